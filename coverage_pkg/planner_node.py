"""coverage_planner: coverage with an extended-range detector as a ROS 2 node.

A thin adapter (all the math is in the planners): ``planner:=paper`` (the default) runs
Algorithm 1 of Acar, Choset and Lee driven by sensed events alone
(:class:`coverage_pkg.algorithm1.PaperPlanner`, ablations with ``without``, modes with
``modes``, e.g. ``rules=paper``, ``handover=false`` or ``ours=on``);
``planner:=grid`` the frontier-driven evidence-grid planner (ours, not the paper's,
:class:`coverage_pkg.planner.CoveragePlanner`).
Inputs, and nothing else (never the world file, never ground truth):

* ``sonar/scan`` (sensor_msgs/LaserScan: one sweep of the sonar ring, REP 117 values; the
  beam width is the ``beam_width`` parameter since LaserScan has no field of view);
* ``odom`` (nav_msgs/Odometry).

(The per-transducer ``sonar/ranges`` stream carries the same readings as sensor_msgs/Range; the
planner reads the scan because one message per sweep can't be split across executor steps.)

Outputs:

* ``cmd_vel`` (geometry_msgs/Twist, body frame) after every sweep; zero when stopping;
* ``/coverage/status`` (diagnostic_msgs/DiagnosticArray, latched): state (``warmup``,
  ``covering_vast``, ``covering_narrow``, ``waiting_for_sonar``, ``stuck``, ``done``...), the
  current node, uncovered nodes, the last event;
* ``/coverage/graph`` (std_msgs/String, latched): the hierarchical decomposition graph as JSON,
  published at every new event; the paper planner's also carries every event so far
  (``events``: [sim time, kind, x, y (odom), detail]) and the path's segments with the
  primitive that drove each (``path_segments``: [primitive, length m]);
* ``/coverage/markers`` (visualization_msgs/MarkerArray, frame ``odom``): vast and narrow cells,
  GVD, Morse cell boundaries, critical, cusp and meet points, the graph, the path so far and
  the planned path.
"""
import json
import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan
from std_msgs.msg import ColorRGBA, String
from visualization_msgs.msg import Marker, MarkerArray

from coverage_pkg.algorithm1 import PaperConfig, PaperPlanner, parse_modes, parse_without
from coverage_pkg.baseline import robot_size_config
from coverage_pkg.morse import cell_boundaries
from coverage_pkg.planner import PlannerConfig, PlannerDriver, graph_dict
from coverage_pkg.sonar import yaw_of
from paramotion.errors import UserError
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import LATCHED_QOS, SENSOR_QOS, STATE_QOS

LEVEL = {'done': DiagnosticStatus.OK, 'stuck': DiagnosticStatus.ERROR,
         'incomplete': DiagnosticStatus.ERROR,
         'waiting_for_sonar': DiagnosticStatus.WARN, 'error': DiagnosticStatus.ERROR}


class CoveragePlannerNode(ParamotionNode):
    """Online coverage with an extended-range detector (or the robot-size baseline)."""

    PARAMS = (
        Param('delta', 2.0, 'Detector range delta (m); must exceed radius.', min=0.01,
              max=100.0, read_only=True),
        Param('radius', 0.25, 'Robot radius r (m).', min=0.01, max=10.0, read_only=True),
        Param('detector', 'extended', "'extended': hierarchical decomposition with range "
              "delta; 'robot': robot-size detector, plain boustrophedon (Section II, grid "
              "planner only).", choices=('extended', 'robot'), read_only=True),
        Param('planner', 'paper', "'paper' (default): Algorithm 1 driven by sensed events "
              "alone (coverage_pkg/algorithm1.py); 'grid': the frontier-driven evidence-grid "
              "planner (ours, coverage_pkg/planner.py).", choices=('paper', 'grid'),
              read_only=True),
        Param('without', '', 'Comma-separated events whose sensing is switched off in the '
              'paper planner: cusp, critical, meet (ablations).', read_only=True),
        Param('modes', '', "Comma-separated NAME=VALUE modes of the paper planner "
              "(coverage_pkg/algorithm1.py: MODE_FIELDS), later ones overriding earlier ones: "
              "'rules=paper' sets every sensing rule of ours to the paper's reading, "
              "'handover=false' is Algorithm 1's pseudocode order, e.g. "
              "'rules=paper,handover=false'; 'ours=on' turns on seven of the modes of ours "
              "that are off in the default (algorithm1.py: OUR_MODES).", read_only=True),
        Param('beam_width', 0.2, 'Cone angle of one transducer (rad); the same as the sonar '
              "ring's field_of_view (LaserScan does not carry it).", min=0.01, max=1.5,
              read_only=True),
        Param('resolution', 0.1, 'Evidence grid cell (m); at most radius. Extended detector '
              'only: the robot-size baseline uses radius / 5.', min=0.01, max=1.0,
              read_only=True),
        Param('max_speed', 1.0, 'Speed limit (m/s).', min=0.05, max=5.0, read_only=True),
        Param('spin_rate', 0.6, 'Turret spin (rad/s) sweeping the ring over its gaps.',
              min=0.0, max=3.0, read_only=True),
        Param('replan_period', 1.5, 'Decomposition rebuild period (s, sim time).', min=0.1,
              max=30.0, read_only=True),
        Param('sonar_timeout', 0.5, 'Stop when no sweep for this long (s, sim time).',
              min=0.05, max=10.0, read_only=True),
        Param('clearance_margin', 0.1, 'Extra clearance beyond radius for paths (m); '
              'extended detector only (the baseline uses radius / 10).',
              min=0.0, max=2.0, read_only=True),
        Param('min_unseen_area', 0.2, 'Pockets of known free space the detector has not seen, '
              'smaller than this (m^2) and away from the frontier, are sensing speckles, not '
              'work; extended detector only (the baseline keeps every pocket).', min=0.0,
              max=10.0, read_only=True),
        Param('unseen_budget', 0.005, 'Speckles are dropped smallest first while their total '
              'stays within this share of the known free area; extended detector only.',
              min=0.0, max=0.1, read_only=True),
        Param('piece_order', 'tour', "Order of a narrow cell's pieces once no uncovered vast "
              "cell borders it: 'tour' (shortest open tour ending at the frontier) or "
              "'nearest'; extended detector only.", choices=('tour', 'nearest'),
              read_only=True),
        Param('view_margin', 0.2, 'A GVD path ends where every unseen cell it was going to '
              'show is within delta - view_margin (m); extended detector only.', min=0.0,
              max=2.0, read_only=True),
        Param('leave_far', 4.0, 'A narrow cell whose nearest work left is at least this far '
              '(m, travel) first covers an uncovered vast neighbour within leave_near, '
              'instead of leaving it behind; 0 turns this off. Extended detector only.',
              min=0.0, max=100.0, read_only=True),
        Param('leave_near', 2.0, 'See leave_far (m, travel).', min=0.0, max=100.0,
              read_only=True),
        Param('marker_period', 5.0, 'Marker publication period (s, sim time).', min=0.1,
              max=600.0),
        Param('marker_stride', 0.4, 'Spacing of the cell markers (m).', min=0.05, max=5.0),
    )

    def __init__(self, node_name='coverage_planner', **kwargs):
        super().__init__(node_name, **kwargs)
        p = self.params
        common = dict(max_speed=p.max_speed, spin_rate=p.spin_rate,
                      sonar_timeout=p.sonar_timeout)
        if p.planner == 'grid':
            common['replan_period'] = p.replan_period
        if p.planner == 'paper':
            self.config = PaperConfig(
                delta=p.delta, radius=p.radius, without=parse_without(p.without),
                **parse_modes(p.modes), **common)
        elif p.detector == 'robot':
            self.config = robot_size_config(p.radius, **common)
        else:
            self.config = PlannerConfig(
                delta=p.delta, radius=p.radius, detector=p.detector, resolution=p.resolution,
                clearance_margin=p.clearance_margin, min_unseen_area=p.min_unseen_area,
                unseen_budget=p.unseen_budget, piece_order=p.piece_order,
                view_margin=p.view_margin, leave_far=p.leave_far, leave_near=p.leave_near,
                **common)
        self.driver = PlannerDriver(self.config, p.beam_width)
        if p.planner == 'paper':
            modes = parse_modes(p.modes)
            self.get_logger().info(
                'coverage planner: paper (Algorithm 1)'
                + (f", without {','.join(self.config.without)}" if self.config.without else '')
                + (', modes ' + ','.join(f'{k}={v}' for k, v in modes.items()) if modes
                   else ''))
        else:
            self.get_logger().info(f'coverage planner: {p.planner} (ours, frontier-driven)')
        self.cmd_pub = self.create_publisher(Twist, 'cmd_vel', STATE_QOS)
        self.status_pub = self.create_publisher(DiagnosticArray, '/coverage/status',
                                                LATCHED_QOS)
        self.graph_pub = self.create_publisher(String, '/coverage/graph', LATCHED_QOS)
        self.marker_pub = self.create_publisher(MarkerArray, '/coverage/markers', LATCHED_QOS)
        self.create_subscription(Odometry, 'odom', self._on_odom, SENSOR_QOS)
        self.create_subscription(LaserScan, 'sonar/scan', self._on_scan, SENSOR_QOS)
        self.create_timer(0.1, self._on_timer)
        self.state = None
        self.error = None
        self.path = []
        self._last_plan = None
        self._last_markers = -math.inf
        self.update_times = []          # wall seconds per processed sweep (benchmark)

    def check_params(self, values):
        for name, parse in (('without', parse_without), ('modes', parse_modes)):
            try:
                chosen = parse(values[name])
            except UserError as exc:
                return f"parameter '{name}': {exc}"
            if chosen and values['planner'] != 'paper':
                return f"parameter '{name}' applies to planner 'paper' only"
        if values['planner'] == 'paper' and values['detector'] != 'extended':
            return "parameter 'detector' = 'robot' needs planner 'grid'"
        if values['detector'] == 'extended' and not values['delta'] > values['radius']:
            return (f"parameter 'delta' = {values['delta']} must be greater than "
                    f"'radius' = {values['radius']}")
        if values['detector'] == 'extended' and not values['view_margin'] < values['delta']:
            return (f"parameter 'view_margin' = {values['view_margin']} must be less than "
                    f"'delta' = {values['delta']}")
        if values['resolution'] > values['radius']:
            return (f"parameter 'resolution' = {values['resolution']} must not exceed "
                    f"'radius' = {values['radius']}")
        return None

    @property
    def planner(self):
        return self.driver.planner

    def _on_odom(self, msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        x, y = msg.pose.pose.position.x, msg.pose.pose.position.y
        self.driver.on_odometry(t, x, y, yaw_of(msg.pose.pose.orientation))
        if not self.path or math.hypot(x - self.path[-1][0], y - self.path[-1][1]) > 0.2:
            self.path.append((x, y))

    def _on_scan(self, msg):
        if self.error:
            return
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        n = len(msg.ranges)
        angles = msg.angle_min + msg.angle_increment * np.arange(n)
        start = time.perf_counter()
        try:
            cmd = self.driver.on_scan(t, np.asarray(msg.ranges, dtype=float), angles,
                                      msg.range_min, msg.range_max)
        except UserError as exc:
            self.error = str(exc)
            self.get_logger().error(self.error)
            self.cmd_pub.publish(Twist())
            self._status('error', self.error)
            return
        if cmd is not None:
            self.update_times.append(time.perf_counter() - start)
            self._publish(cmd)

    def _on_timer(self):
        cmd = self.driver.on_timer(self.get_clock().now().nanoseconds * 1e-9)
        if cmd is not None:
            self._publish(cmd)

    def _publish(self, cmd):
        twist = Twist()
        twist.linear.x, twist.linear.y, twist.angular.z = cmd.vx, cmd.vy, cmd.wz
        self.cmd_pub.publish(twist)
        p = self.planner
        event = p.events[-1] if p.events else None
        # the graph before the status: a watcher that stops the graph on an end state has
        # the final graph and events recorded by then
        stamp = len(p.events) if isinstance(p, PaperPlanner) else p.t_plan
        if stamp != self._last_plan:
            self._last_plan = stamp
            self.graph_pub.publish(String(data=json.dumps(self.graph_message(p))))
            now = p.t_plan
            if now - self._last_markers >= self.params.marker_period or cmd.state == 'done':
                self._last_markers = now
                self.marker_pub.publish(self.markers())
        if cmd.state != self.state:
            self._status(cmd.state, event[4] if event else cmd.state)
            if cmd.state in ('done', 'stuck', 'incomplete', 'waiting_for_sonar'):
                self.get_logger().info(f'coverage planner: {cmd.state}: '
                                       f'{event[4] if event else ""}')

    @staticmethod
    def graph_message(p):
        """The ``/coverage/graph`` JSON dict: the graph, and with the paper planner its events
        and path segments, so that a bag alone gives what result.json reports."""
        data = graph_dict(p)
        if isinstance(p, PaperPlanner):
            data['events'] = [[float(e[0]), e[1], float(e[2]), float(e[3]), e[4]]
                              for e in p.events]
            data['path_segments'] = [[k, round(float(v), 3)] for k, v in p.segments]
        return data

    def _status(self, state, message):
        self.state = state
        p = self.planner
        st = p.status() if p is not None else {'state': state}
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status.append(DiagnosticStatus(
            level=LEVEL.get(state, DiagnosticStatus.OK), name='coverage_planner',
            message=str(message), hardware_id='coverage_robot',
            values=[KeyValue(key=k, value=json.dumps(v)) for k, v in st.items()]
            + [KeyValue(key='state_now', value=state)]))
        self.status_pub.publish(arr)

    # ------------------------------------------------------------------ visualisation

    def markers(self):
        """MarkerArray of the last decomposition (frame odom)."""
        p = self.planner
        arr = MarkerArray()
        stamp = self.get_clock().now().to_msg()
        clear = Marker()
        clear.action = Marker.DELETEALL
        arr.markers.append(clear)

        def marker(ns, mtype, color, scale, mid=0):
            m = Marker()
            m.header.frame_id = 'odom'
            m.header.stamp = stamp
            m.ns, m.id, m.type, m.action = ns, mid, mtype, Marker.ADD
            m.pose.orientation.w = 1.0
            m.scale.x = m.scale.y = m.scale.z = scale
            m.color = ColorRGBA(r=color[0], g=color[1], b=color[2], a=color[3])
            arr.markers.append(m)
            return m

        d = p.last if p is not None else {}
        if isinstance(p, PaperPlanner):
            paper_markers(p, marker)
        elif d:
            k = max(1, int(round(self.params.marker_stride / p.grid.res)))
            for ns, key, color in (('vast_cells', 'vast', (0.6, 0.6, 0.6, 0.5)),
                                   ('narrow_cells', 'narrow', (0.7, 0.85, 1.0, 0.5))):
                m = marker(ns, Marker.CUBE_LIST, color, k * p.grid.res)
                m.scale.z = 0.02
                sub = np.zeros_like(d[key])
                sub[::k, ::k] = d[key][::k, ::k]
                rr, cc = np.nonzero(sub)
                m.points = [Point(x=float(x), y=float(y)) for x, y in d['to_world'](rr, cc)]
            m = marker('gvd', Marker.POINTS, (0.1, 0.3, 1.0, 1.0), p.grid.res)
            rr, cc = np.nonzero(d['gvd'])
            m.points = [Point(x=float(x), y=float(y), z=0.05) for x, y in d['to_world'](rr, cc)]
            m = marker('morse_boundaries', Marker.POINTS, (0.3, 0.0, 0.5, 1.0), p.grid.res)
            rr, cc = np.nonzero(cell_boundaries(d['reeb']))
            m.points = [Point(x=float(x), y=float(y), z=0.05) for x, y in d['to_world'](rr, cc)]
            nodes = [n for n in p.graph.alive()]
            m = marker('critical_points', Marker.SPHERE_LIST, (0.0, 0.0, 0.0, 1.0), 0.25)
            m.points = [Point(x=q[0], y=q[1], z=0.1) for n in nodes for q in n.reeb_points]
            m = marker('meet_points', Marker.SPHERE_LIST, (0.5, 0.5, 0.5, 1.0), 0.3)
            m.points = [Point(x=q[0], y=q[1], z=0.1) for n in nodes for q in n.meet_points]
            cusps = [c for (v, n) in p.graph.edges
                     if p.graph.nodes[v].alive and p.graph.nodes[n].alive
                     for c in p.graph.cusp_points(v, n)]
            m = marker('cusp_points', Marker.SPHERE_LIST, (1.0, 1.0, 1.0, 1.0), 0.3)
            m.points = [Point(x=c[0], y=c[1], z=0.1) for c in cusps]
            m = marker('graph_edges', Marker.LINE_LIST, (0.6, 0.0, 0.6, 1.0), 0.05)
            for (v, n) in p.graph.edges:
                a, b = p.graph.nodes[v], p.graph.nodes[n]
                cs = p.graph.cusp_points(v, n)
                if a.alive and b.alive:
                    for c in cs:
                        for u, w in ((a.label_point, c), (c, b.label_point)):
                            m.points += [Point(x=u[0], y=u[1], z=0.2),
                                         Point(x=w[0], y=w[1], z=0.2)]
            for i, n in enumerate(nodes):
                t = marker('graph_nodes', Marker.TEXT_VIEW_FACING,
                           (0.3, 0.3, 0.3, 1.0) if n.kind == 'vast' else (0.2, 0.4, 1.0, 1.0),
                           0.5, mid=i)
                t.pose.position.x, t.pose.position.y, t.pose.position.z = (
                    n.label_point[0], n.label_point[1], 0.5)   # a point of the cell
                t.text = f"{'V' if n.kind == 'vast' else 'N'}{n.id}" + (
                    '' if n.covered else '*')
        m = marker('path', Marker.LINE_STRIP, (0.0, 0.7, 0.0, 1.0), 0.05)
        m.points = [Point(x=x, y=y) for x, y in self.path]
        if p is not None and getattr(p, 'path', None):
            m = marker('plan', Marker.LINE_STRIP, (1.0, 0.5, 0.0, 1.0), 0.05)
            m.points = [Point(x=float(x), y=float(y), z=0.02) for x, y in p.path]
        return arr


def paper_markers(p, marker):
    """Markers of the paper planner's graph: sensed events and nodes (no decomposed map)."""
    for kind, color, size in (('critical', (0.0, 0.0, 0.0, 1.0), 0.25),
                              ('meet', (0.5, 0.5, 0.5, 1.0), 0.3),
                              ('cusp', (1.0, 1.0, 1.0, 1.0), 0.3)):
        m = marker(f'{kind}_points', Marker.SPHERE_LIST, color, size)
        m.points = [Point(x=float(e[2]), y=float(e[3]), z=0.1) for e in p.events
                    if e[1] == kind]
    m = marker('graph_edges', Marker.LINE_LIST, (0.6, 0.0, 0.6, 1.0), 0.05)
    for v, w, c in p.edges:
        for a in (p.nodes[v].anchor, p.nodes[w].anchor):
            m.points += [Point(x=float(a[0]), y=float(a[1]), z=0.2),
                         Point(x=float(c[0]), y=float(c[1]), z=0.2)]
    for i, n in enumerate(p.nodes):
        t = marker('graph_nodes', Marker.TEXT_VIEW_FACING,
                   (0.3, 0.3, 0.3, 1.0) if n.kind == 'vast' else (0.2, 0.4, 1.0, 1.0), 0.5,
                   mid=i)
        t.pose.position.x, t.pose.position.y, t.pose.position.z = n.anchor[0], n.anchor[1], 0.5
        t.text = f"{'V' if n.kind == 'vast' else 'N'}{n.id}" + ('' if n.covered else '*')


def main(args=None):
    run_node(CoveragePlannerNode, args)


if __name__ == '__main__':
    main()
