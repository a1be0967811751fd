"""voronoi_planner: serves nav_msgs/srv/GetPlan for the planar platform of Vaca, Aranda &
Thomas (section 6) with the simplified Voronoi diagram planner.

A thin adapter around :class:`voronoi_pkg.planner.VoronoiPlanner`:

* service ``/voronoi/get_plan`` (nav_msgs/srv/GetPlan): start and goal poses give the
  platform configuration ``(x, y, yaw)`` = (P3, direction of P3P4); the response's
  ``plan`` is the densely sampled path (every <= 0.05 units / 0.01 rad, verified free), or an
  empty path when there is none or the request is refused (the reason goes to
  ``/voronoi/status``);
* ``/voronoi/path`` (nav_msgs/Path, latched): the last plan found;
* ``/voronoi/diagram`` (visualization_msgs/MarkerArray, latched): the scene (base, boundary,
  obstacles), the simplified Voronoi diagram slice at ``marker_slice_yaw``, the last path and
  the diagram edges it used (namespace ``diagram_used``);
* ``/voronoi/status`` (diagnostic_msgs/DiagnosticArray, latched): outcome of the last request.

Scene units are metres in the messages; frames follow REP 105 (``frame_id``, default map).
"""
import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from visualization_msgs.msg import Marker, MarkerArray

from paramotion.errors import ParameterError, UserError
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import LATCHED_QOS
from paramotion.rotations import quat_from_yaw, yaw_from_quat
from voronoi_pkg.diagram import grid_axes, tie_segments
from voronoi_pkg.planar import check_without, load_scene, paper_model
from voronoi_pkg.planner import VoronoiPlanner, diagram_segments


class VoronoiPlannerNode(ParamotionNode):
    """GetPlan server for the planar platform on the simplified Voronoi diagram."""

    PARAMS = (
        Param('scene_file', '', 'Planar scene JSON (empty: the paper scene of section 6).',
              read_only=True),
        Param('grid_spacing', 1.0, 'Grid spacing of the diagram in x and y (m).', min=0.1,
              max=10.0),
        Param('slice_step_deg', 2.5, 'Spacing of orientation slices (deg).', min=0.5,
              max=45.0),
        Param('frame_id', 'map', 'Frame of the scene, requests and the published path.'),
        Param('marker_slice_yaw', math.pi / 4, 'Yaw of the diagram slice published as '
              'markers (rad).', min=-math.pi, max=math.pi),
        Param('without', '', 'Comma-separated constructs switched off (ablation): '
              'singularity (the factors of P1), collision (the predicates of P2).',
              read_only=True),
    )

    def __init__(self, node_name='voronoi_planner', **kwargs):
        super().__init__(node_name, **kwargs)
        try:
            without = check_without(w.strip() for w in self.params.without.split(','))
        except UserError as exc:
            raise ParameterError(f"{node_name}: parameter 'without': {exc}") from None
        try:
            scene = self.params.scene_file
            self.model = load_scene(scene, without) if scene else paper_model(without=without)
        except UserError as exc:
            raise ParameterError(f"{node_name}: parameter 'scene_file': {exc}") from None
        reason = self.check_params(vars(self.params))
        if reason:
            raise ParameterError(f'{node_name}: {reason}')
        self.planner = None
        self.last_path = None
        self.last_used = None
        self.requests = 0
        self.path_pub = self.create_publisher(Path, '/voronoi/path', LATCHED_QOS)
        self.marker_pub = self.create_publisher(MarkerArray, '/voronoi/diagram', LATCHED_QOS)
        self.status_pub = self.create_publisher(DiagnosticArray, '/voronoi/status',
                                                LATCHED_QOS)
        self.create_service(GetPlan, '/voronoi/get_plan', self._on_get_plan)
        self._rebuild()
        self._publish_markers()
        self._status(DiagnosticStatus.OK, 'ready', {})

    def check_params(self, values):
        if getattr(self, 'model', None) is None:
            return None      # checked again in __init__ once the scene is loaded
        try:
            VoronoiPlanner(self.model, h=values['grid_spacing'],
                           dphi_deg=values['slice_step_deg'])
        except UserError as exc:
            return f"parameters 'grid_spacing', 'slice_step_deg': {exc}"
        return None

    def on_params_changed(self, changed):
        if {'grid_spacing', 'slice_step_deg'} & set(changed):
            self._rebuild()
        self._publish_markers()

    def _rebuild(self):
        self.planner = VoronoiPlanner(self.model, h=self.params.grid_spacing,
                                      dphi_deg=self.params.slice_step_deg)
        self.planner.prepare()   # build the diagram slices now, not in the first request

    # -- service ---------------------------------------------------------------------------
    def _on_get_plan(self, request, response):
        self.requests += 1
        t0 = time.perf_counter()
        response.plan = Path()
        response.plan.header.frame_id = self.params.frame_id
        response.plan.header.stamp = self.get_clock().now().to_msg()
        try:
            start = self._configuration(request.start, 'start')
            goal = self._configuration(request.goal, 'goal')
            result = self.planner.plan(start, goal)
        except UserError as exc:
            self._status(DiagnosticStatus.ERROR, f'request refused: {exc}',
                         {'planning_time_s': time.perf_counter() - t0})
            self.get_logger().warning(f'GetPlan refused: {exc}')
            return response
        info = {'planning_time_s': result.planning_time, **result.stats}
        if not result.found:
            self._status(DiagnosticStatus.WARN, f'no path: {result.reason}', info)
            self.get_logger().info(f'GetPlan: no path: {result.reason}')
            return response
        info['min_rho'] = result.min_rho
        info['poses'] = len(result.path)
        for x, y, yaw in result.path:
            pose = PoseStamped()
            pose.header = response.plan.header
            pose.pose.position.x = float(x)
            pose.pose.position.y = float(y)
            o = pose.pose.orientation
            o.x, o.y, o.z, o.w = quat_from_yaw(float(yaw))
            response.plan.poses.append(pose)
        self.last_path = result.path
        self.last_used = diagram_segments(result)
        info['on_diagram_fraction'] = result.on_diagram_fraction
        self.path_pub.publish(response.plan)
        self._publish_markers()
        self._status(DiagnosticStatus.OK, 'path found', info)
        return response

    def _configuration(self, pose_stamped, name):
        frame = pose_stamped.header.frame_id
        if frame and frame != self.params.frame_id:
            raise UserError(f"{name} is in frame '{frame}', expected "
                            f"'{self.params.frame_id}'")
        p, o = pose_stamped.pose.position, pose_stamped.pose.orientation
        try:
            yaw = yaw_from_quat((o.x, o.y, o.z, o.w))
        except ValueError as exc:
            raise UserError(f'{name}: orientation {exc}') from None
        return np.array([p.x, p.y, yaw])

    # -- outputs ---------------------------------------------------------------------------
    def _status(self, level, message, values):
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status.append(DiagnosticStatus(
            level=level, name='voronoi_planner', message=message, hardware_id='planar_platform',
            values=[KeyValue(key=str(k), value=f'{v:.6g}' if isinstance(v, float) else str(v))
                    for k, v in values.items()]))
        self.status_pub.publish(arr)

    def _line_marker(self, ns, mid, kind, points, rgb, width):
        m = Marker()
        m.header.frame_id = self.params.frame_id
        m.header.stamp = self.get_clock().now().to_msg()
        m.ns, m.id, m.type, m.action = ns, mid, kind, Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = width
        m.color.r, m.color.g, m.color.b = rgb
        m.color.a = 1.0
        m.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in points]
        return m

    def _publish_markers(self):
        arr = MarkerArray()
        scene = []
        for a, b in self.model.segments.values():
            if a in self.model.fixed and b in self.model.fixed:
                scene += [self.model.fixed[a], self.model.fixed[b]]
        arr.markers.append(self._line_marker('scene', 0, Marker.LINE_LIST, scene,
                                             (0.1, 0.1, 0.1), 0.5))
        xs, ys = grid_axes(self.model.domain, min(self.params.grid_spacing, 0.5))
        segs = tie_segments(self.model, self.params.marker_slice_yaw, xs, ys)
        arr.markers.append(self._line_marker('diagram', 0, Marker.LINE_LIST,
                                             segs.reshape(-1, 2), (0.1, 0.4, 0.9), 0.2))
        if self.last_path is not None and len(self.last_path) > 1:
            arr.markers.append(self._line_marker('path', 0, Marker.LINE_STRIP,
                                                 self.last_path[:, :2], (0.9, 0.1, 0.1), 0.3))
        if self.last_used is not None and len(self.last_used):
            # The diagram edges the last path ran along (x, y of both ends, any slice).
            arr.markers.append(self._line_marker('diagram_used', 0, Marker.LINE_LIST,
                                                 self.last_used[:, :, :2].reshape(-1, 2),
                                                 (0.1, 0.8, 0.2), 0.4))
        self.marker_pub.publish(arr)


def main(args=None):
    run_node(VoronoiPlannerNode, args)


if __name__ == '__main__':
    main()
