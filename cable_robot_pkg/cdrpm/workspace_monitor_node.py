"""workspace_monitor: checks commanded platform poses of a cable robot against its workspace.

A thin adapter around :mod:`cable_robot_pkg.cdrpm` (Aref & Taghirad's collision tests):

- subscribes ``/cdrpm/pose_cmd`` (geometry_msgs/PoseStamped): commanded pose of the platform
  centroid G in the fixed frame A (origin O at the frame centroid);
- publishes ``/cdrpm/cable_lengths`` (sensor_msgs/JointState): ``cable_1..cable_n`` lengths
  L_i (eq. (2), m) for every pose inside the frame; nothing for a pose outside the frame or an
  invalid pose (lengths of an unreachable pose must not reach the winches);
- publishes ``/cdrpm/workspace_status`` (diagnostic_msgs/DiagnosticArray, latched): OK when the
  pose is collision-free, WARN when the smallest cable-cable gap is below
  ``clearance_warning``, ERROR naming the colliding cable pair(s), the cables entering the
  platform body or the workpiece, or "outside frame" / "invalid pose";
- publishes ``/cdrpm/cable_markers`` (visualization_msgs/MarkerArray): cables as a line list
  coloured by clearance (green clear, yellow below ``clearance_warning``, red colliding) and
  the platform box.

Parameters: ``robot_description`` (YAML path, empty = the shipped Neuron, an arrangement
fitted to Table II and the TOW box), ``frame_id``, ``clearance_warning``, ``without``
(comma-separated constructs switched off: cable_cable, cable_body, cable_workpiece,
workpiece_sides).
"""
import math

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from cable_robot_pkg.cdrpm.collisions import CONSTRUCTS, check_pose, check_without
from cable_robot_pkg.cdrpm.description import load_description
from cable_robot_pkg.cdrpm.kinematics import quaternion_to_matrix
from paramotion.errors import ParameterError, UserError
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import LATCHED_QOS, STATE_QOS

GREEN = ColorRGBA(r=0.2, g=0.8, b=0.2, a=1.0)
YELLOW = ColorRGBA(r=1.0, g=0.8, b=0.0, a=1.0)
RED = ColorRGBA(r=0.9, g=0.1, b=0.1, a=1.0)


class WorkspaceMonitorNode(ParamotionNode):
    """Per-pose inverse kinematics and collision diagnosis for a cable-driven robot."""

    PARAMS = (
        Param('robot_description', '', 'Robot description YAML file (empty: the shipped KNTU '
              'Neuron, cable_robot_pkg/cdrpm/config/kntu_neuron.yaml, fitted to Table II and '
              'the TOW box).', read_only=True),
        Param('frame_id', 'map', 'Frame of the fixed frame A for the markers and lengths.'),
        Param('clearance_warning', 0.02, 'Warn when two cables come closer than this surface '
              'gap (m).', min=0.0, max=1.0),
        Param('without', '', 'Comma-separated constructs switched off (ablation): '
              + ', '.join(CONSTRUCTS) + '.', read_only=True),
    )

    def __init__(self, node_name='workspace_monitor', **kwargs):
        super().__init__(node_name, **kwargs)
        try:
            self.desc = load_description(self.params.robot_description or None)
        except UserError as exc:
            raise ParameterError(f"{node_name}: parameter 'robot_description': {exc}") from None
        try:
            self.without = check_without(
                [w.strip() for w in self.params.without.split(',') if w.strip()])
        except ValueError as exc:
            raise ParameterError(f"{node_name}: parameter 'without': {exc}") from None
        self.names = [f'cable_{i + 1}' for i in range(self.desc.n_cables)]
        self.lengths_pub = self.create_publisher(JointState, '/cdrpm/cable_lengths', STATE_QOS)
        self.status_pub = self.create_publisher(DiagnosticArray, '/cdrpm/workspace_status',
                                                LATCHED_QOS)
        self.marker_pub = self.create_publisher(MarkerArray, '/cdrpm/cable_markers', STATE_QOS)
        self.create_subscription(PoseStamped, '/cdrpm/pose_cmd', self._on_pose, STATE_QOS)
        self.poses = 0
        self.get_logger().info(f'monitoring {self.desc.name} ({self.desc.n_cables} cables, '
                               f'{self.desc.source})')

    def _on_pose(self, msg):
        self.poses += 1
        p, q = msg.pose.position, msg.pose.orientation
        position = np.array([p.x, p.y, p.z])
        try:
            if not np.all(np.isfinite(position)):
                raise ValueError('position is not finite')
            rotation = quaternion_to_matrix([q.x, q.y, q.z, q.w])
        except ValueError as exc:
            self._publish_status(msg, DiagnosticStatus.ERROR, f'invalid pose: {exc}',
                                 {'state': 'invalid_pose'})
            return
        report = check_pose(self.desc, position, rotation, self.without)
        if not report.inside_frame:
            self._publish_status(msg, DiagnosticStatus.ERROR,
                                 'outside frame: the platform does not fit inside the fixed '
                                 'frame at this pose', {'state': 'outside_frame'})
            self._publish_markers(msg, position, rotation, report)
            return
        lengths = JointState()
        lengths.header.stamp = msg.header.stamp
        lengths.header.frame_id = self.params.frame_id
        lengths.name = list(self.names)
        lengths.position = [float(v) for v in report.lengths]
        self.lengths_pub.publish(lengths)
        self._publish_markers(msg, position, rotation, report)
        level, message, state = self._diagnose(report)
        min_gap = float(np.min(report.clearance)) if report.clearance.size else math.inf
        self._publish_status(msg, level, message, {
            'state': state,
            'min_cable_gap_m': f'{min_gap:.6f}',
            'colliding_pairs': ' '.join(f'{i + 1}-{j + 1}' for i, j, _ in
                                        report.colliding_pairs),
            'body_cables': ' '.join(str(k + 1) for k in report.body_cables),
            'workpiece_cables': ' '.join(str(k + 1) for k in report.workpiece_cables),
            'platform_workpiece': str(report.platform_workpiece).lower(),
        })

    def _diagnose(self, report):
        """Level, one-line message and state name of an in-frame pose report."""
        parts = []
        two_eps = 2 * self.desc.cable_radius
        for i, j, dist in report.colliding_pairs:
            parts.append(f'cable-cable collision: cables {i + 1} and {j + 1} '
                         f'({dist * 1e3:.1f} mm apart < 2 eps = {two_eps * 1e3:.1f} mm)')
        if report.body_cables:
            parts.append('cable-body collision: cable(s) '
                         + ', '.join(str(k + 1) for k in report.body_cables))
        if report.workpiece_cables:
            parts.append('cable-workpiece collision: cable(s) '
                         + ', '.join(str(k + 1) for k in report.workpiece_cables))
        if report.platform_workpiece:
            parts.append('platform-workpiece collision')
        if parts:
            return DiagnosticStatus.ERROR, '; '.join(parts), 'collision'
        min_gap = float(np.min(report.clearance)) if report.clearance.size else math.inf
        if min_gap < self.params.clearance_warning:
            return (DiagnosticStatus.WARN,
                    f'collision-free, but cables only {min_gap * 1e3:.1f} mm apart', 'close')
        return DiagnosticStatus.OK, 'collision-free', 'collision_free'

    def _publish_status(self, msg, level, message, values):
        arr = DiagnosticArray()
        arr.header.stamp = msg.header.stamp
        arr.header.frame_id = self.params.frame_id
        arr.status.append(DiagnosticStatus(
            level=level, name='workspace_monitor', message=message,
            hardware_id=self.desc.name,
            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()]))
        self.status_pub.publish(arr)

    def _publish_markers(self, msg, position, rotation, report):
        out = MarkerArray()
        cables = Marker()
        cables.header.stamp = msg.header.stamp
        cables.header.frame_id = self.params.frame_id
        cables.ns = 'cables'
        cables.id = 0
        cables.type = Marker.LINE_LIST
        cables.action = Marker.ADD
        cables.pose.orientation.w = 1.0
        cables.scale.x = max(2 * self.desc.cable_radius, 0.004)
        attach = position + self.desc.platform_points @ rotation.T
        bad = {k for k in report.body_cables} | {k for k in report.workpiece_cables}
        for i, j, _ in report.colliding_pairs:
            bad.update((i, j))
        for k in range(self.desc.n_cables):
            gap = report.clearance[k]
            colour = RED if (k in bad or gap < 0) else (
                YELLOW if gap < self.params.clearance_warning else GREEN)
            for point in (self.desc.frame_points[k], attach[k]):
                cables.points.append(Point(x=float(point[0]), y=float(point[1]),
                                           z=float(point[2])))
                cables.colors.append(colour)
        out.markers.append(cables)
        body = Marker()
        body.header = cables.header
        body.ns = 'platform'
        body.id = 1
        body.type = Marker.CUBE
        body.action = Marker.ADD
        body.pose = msg.pose
        size = 2 * self.desc.platform_half_size
        body.scale.x, body.scale.y, body.scale.z = (float(v) for v in size)
        base = GREEN if report.collision_free else RED
        body.color = ColorRGBA(r=base.r, g=base.g, b=base.b, a=0.6)
        out.markers.append(body)
        self.marker_pub.publish(out)


def main(args=None):
    run_node(WorkspaceMonitorNode, args)


if __name__ == '__main__':
    main()
