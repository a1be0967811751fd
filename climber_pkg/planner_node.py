"""climber_planner: the kinematics control algorithm of the climbing parallel robot (ROS adapter).

Thin adapter around :class:`climber_pkg.gait.ClimbingGait` (section IV of Almonacid et al.
2003: correction eq. (5), prediction eqs. (6)-(8), inverse kinematics eqs. (2)-(3), forward
kinematics from the encoders after every move, clamp alternation with the safety invariant).
It knows the robot (parameter file), its encoders, clamp confirmations and ultrasonic sensors:
never the structure file nor the ground truth.

Subscribes: ``/climber/joint_states`` (sensor_msgs/JointState, encoder lengths),
``/climber/ring{1,2}/clamp_closed`` (std_msgs/Bool), ``/climber/ring{1,2}/ultrasonic``
(sensor_msgs/Range, frames ``ring<N>_us<k>``).
Publishes: ``/climber/leg_command`` (trajectory_msgs/JointTrajectory, one point),
``/climber/ring{1,2}/clamp_command`` (std_msgs/Bool), ``/climber/planned_pose``
(geometry_msgs/PoseStamped of the moving ring, frame ``odom`` = ring 1's initial frame),
``/climber/planned_path`` (nav_msgs/Path, latched), ``/climber/markers``
(visualization_msgs/MarkerArray: estimated rings and measured structure sections, latched),
``/climber/status`` (diagnostic_msgs/DiagnosticStatus, latched: state, cycle, refusal reason).

A managed (lifecycle) node, as Nav2's planners and controllers are: it must not command the
legs or the clamps before it knows the encoders, both clamps and both ultrasonic rings.

* *unconfigured* -> **configure**: reads the robot file, builds the gait, subscribes to the
  inputs and creates the (lifecycle) command publishers, still silent.
* *inactive* -> **activate**: refused (the transition fails, the node stays inactive and says
  which inputs are missing, in the log and in ``/climber/status``) until every input has
  arrived at least once; then planning starts on the next ``1/rate`` tick.
* **deactivate** stops planning and commanding (the gait keeps its state; activate resumes);
  **cleanup** drops the gait and the subscriptions.

With ``autostart: true`` (default) the node does this itself: configures when created and
activates as soon as its inputs are there, so ``ros2 run``, ``paramotion launch`` and the
one-process Graph runner need no lifecycle manager. With ``autostart: false`` a manager
(``ros2 lifecycle set``, Nav2's lifecycle_manager) drives the transitions through the standard
``~/change_state`` services.
"""
import math

import numpy as np
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from rclpy.lifecycle import LifecycleNodeMixin, LifecyclePublisher, TransitionCallbackReturn
from sensor_msgs.msg import JointState, Range
from std_msgs.msg import Bool
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from climber_pkg.gait import (
    APPROACHES,
    ClampCommand,
    ClimbingGait,
    GaitParams,
    LegCommand,
    PlannedPose,
    StatusUpdate,
    parse_without,
)
from climber_pkg.robot import load_robot_config
from paramotion import gough_stewart as gs
from paramotion.errors import UserError
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import LATCHED_QOS, SENSOR_QOS, STATE_QOS
from paramotion.rotations import quat_from_matrix

LEG_NAMES = tuple(f'leg{i}' for i in range(1, 7))


def pose_msg(position, rotation):
    msg = PoseStamped()
    msg.header.frame_id = 'odom'
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in position)
    x, y, z, w = quat_from_matrix(rotation)
    msg.pose.orientation.x, msg.pose.orientation.y = float(x), float(y)
    msg.pose.orientation.z, msg.pose.orientation.w = float(z), float(w)
    return msg


INPUTS = ('/climber/joint_states', '/climber/ring1/clamp_closed', '/climber/ring2/clamp_closed',
          '/climber/ring1/ultrasonic', '/climber/ring2/ultrasonic')


class ClimberPlannerNode(LifecycleNodeMixin, ParamotionNode):
    """Sensor-based predictive climbing of an unknown structure (a managed node)."""

    PARAMS = (
        Param('robot_config', '', 'Robot geometry YAML; empty = climber_pkg/config/climber.yaml.',
              read_only=True),
        Param('mode', 'climb', 'climb (up), descend (down) or turn (around the structure).',
              choices=('climb', 'descend', 'turn'), read_only=True),
        Param('delta', 0.10, 'Displacement per step along the ring axis, Delta (m).', min=0.01,
              max=0.5, read_only=True),
        Param('delta_min', 0.05, 'Smallest Delta when adapting to the sensed curvature (m).',
              min=0.01, max=0.5, read_only=True),
        Param('adaptive_delta', True, 'Shrink Delta where the structure bends.', read_only=True),
        Param('n_cycles', 0, 'Cycles to perform; 0 = until the end of the structure.', min=0,
              max=100000, read_only=True),
        Param('turn_angle_deg', 0.0, 'Rotation around the structure for mode turn (deg).',
              min=-360.0, max=360.0, read_only=True),
        Param('approach', 'centres', "Approach vector of eq. (7): 'centres' (ours: secant of "
              "measured structure centres) or 'paper' (eq. (7) verbatim).",
              choices=APPROACHES, read_only=True),
        Param('without', '', 'Comma-separated constructs switched off: correction (eq. (5)), '
              'prediction (eqs. (6)-(8): step along the ring axis); empty: none.',
              read_only=True),
        Param('max_condition', 30.0, 'Jacobian condition number ending a semicycle '
              '(near-singular configuration).', min=2.0, max=gs.DEFAULT_MAX_CONDITION,
              read_only=True),
        Param('min_clearance', 0.015, 'Stop when a sensor sees the structure closer (m).',
              min=0.0, max=0.3, read_only=True),
        Param('leg_speed', 0.10, 'Actuator speed used to time the moves (m/s).', min=0.001,
              max=2.0, read_only=True),
        Param('length_tolerance', 0.002, 'Encoder-to-command agreement ending a move (m).',
              min=1e-5, max=0.05, read_only=True),
        Param('sensor_timeout', 2.0, 'Longest wait for a valid ultrasonic triplet (s).',
              min=0.1, max=60.0, read_only=True),
        Param('rate', 20.0, 'Planning rate (Hz, sim time).', min=1.0, max=1000.0,
              read_only=True),
        Param('autostart', True, 'Configure when created and activate as soon as every input '
              'has arrived; false: wait for a lifecycle manager.', read_only=True),
    )

    def __init__(self, node_name='climber_planner', **kwargs):
        ParamotionNode.__init__(self, node_name, **kwargs)
        LifecycleNodeMixin.__init__(self, enable_communication_interface=True)
        self.gait = None
        self.seen = set()               # inputs received at least once
        self.configure_error = None
        self._timer = None
        self._entities = []
        self.status_pub = self.create_publisher(DiagnosticStatus, '/climber/status',
                                                LATCHED_QOS)
        self.last_status = None
        self._waiting_said = None
        if self.params.autostart:
            self.trigger_configure()
            if self.configure_error is not None:
                raise self.configure_error   # bad robot file: one line, exit 2 (run_node)

    @property
    def lifecycle_state(self):
        """Current lifecycle state label: unconfigured, inactive, active, finalized..."""
        return self._state_machine.current_state[1]

    def missing_inputs(self):
        return [t for t in INPUTS if t not in self.seen]

    def _seen(self, topic):
        self.seen.add(topic)

    # ------------------------------------------------------------------ lifecycle
    def on_configure(self, state):
        try:
            self._configure()
        except UserError as exc:
            self.configure_error = exc
            self.get_logger().error(f'configure failed: {exc}')
            return TransitionCallbackReturn.FAILURE
        self.configure_error = None
        self._say_waiting()
        return super().on_configure(state)

    def on_activate(self, state):
        missing = self.missing_inputs()
        if missing:
            self._say_waiting()
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info('every input is there: planning')
        return super().on_activate(state)

    def on_deactivate(self, state):
        self.get_logger().info('deactivated: planning stopped')
        return super().on_deactivate(state)

    def on_cleanup(self, state):
        for entity in self._entities:
            if isinstance(entity, LifecyclePublisher):
                self.destroy_lifecycle_publisher(entity)
            else:
                self.destroy_subscription(entity)
        self._entities = []
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        self.gait = None
        self.seen.clear()
        self._waiting_said = None
        return super().on_cleanup(state)

    def on_shutdown(self, state):
        return TransitionCallbackReturn.SUCCESS

    def _say_waiting(self):
        missing = self.missing_inputs()
        if not missing or missing == self._waiting_said:
            return
        self._waiting_said = missing
        text = 'inactive: waiting for ' + ', '.join(missing)
        self.get_logger().info(text)
        st = DiagnosticStatus(level=DiagnosticStatus.WARN, name='climber_planner',
                              message=text, hardware_id='climber')
        st.values = [KeyValue(key='state', value='inactive')]
        self.last_status = st
        self.status_pub.publish(st)

    def _configure(self):
        p = self.params
        self.robot = load_robot_config(p.robot_config or None)
        rb = self.robot
        params = GaitParams(
            delta=p.delta, delta_min=p.delta_min, adaptive_delta=p.adaptive_delta,
            n_cycles=p.n_cycles, mode=p.mode, turn_angle=math.radians(p.turn_angle_deg),
            approach=p.approach, without=parse_without(p.without, "parameter 'without'"),
            max_condition=p.max_condition, min_clearance=p.min_clearance,
            leg_speed=p.leg_speed, length_tolerance=p.length_tolerance,
            sensor_timeout=p.sensor_timeout,
            stall_gap=max(0.5, 5.0 / p.rate))     # five ticks missed: the process stalled
        self.gait = ClimbingGait(rb.geometry, rb.sensor_mount_radius, rb.sensor_angles,
                                 rb.sensor_min_range, rb.sensor_max_range,
                                 rb.ring_inner_radius, params)
        sub, pub = self.create_subscription, self.create_lifecycle_publisher
        subs = [sub(JointState, INPUTS[0], self._on_joints, SENSOR_QOS)]
        for ring in (0, 1):
            subs.append(sub(Bool, INPUTS[1 + ring], lambda m, r=ring: self._on_clamp(r, m),
                            STATE_QOS))
            subs.append(sub(Range, INPUTS[3 + ring], lambda m, r=ring: self._on_range(r, m),
                            SENSOR_QOS))
        # Commands and plans only go out while active (lifecycle publishers).
        self.leg_pub = pub(JointTrajectory, '/climber/leg_command', STATE_QOS)
        self.clamp_pubs = [pub(Bool, f'/climber/ring{r}/clamp_command', STATE_QOS)
                           for r in (1, 2)]
        self.pose_pub = pub(PoseStamped, '/climber/planned_pose', STATE_QOS)
        self.path_pub = pub(Path, '/climber/planned_path', LATCHED_QOS)
        self.marker_pub = pub(MarkerArray, '/climber/markers', LATCHED_QOS)
        self._entities = subs + [self.leg_pub, *self.clamp_pubs, self.pose_pub, self.path_pub,
                                 self.marker_pub]
        self.path = Path()
        self.path.header.frame_id = 'odom'
        self._timer = self.create_timer(1.0 / p.rate, self._tick)

    def check_params(self, values):
        if values['delta_min'] > values['delta']:
            return (f"parameter 'delta_min' = {values['delta_min']} must not exceed "
                    f"'delta' = {values['delta']}")
        if values['mode'] == 'turn' and values['turn_angle_deg'] == 0.0:
            return "parameter 'turn_angle_deg' must be non-zero in mode 'turn'"
        try:
            parse_without(values['without'], "parameter 'without'")
        except UserError as exc:
            return str(exc)
        return None

    def _now(self):
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_joints(self, msg):
        try:
            idx = [list(msg.name).index(n) for n in LEG_NAMES]
        except ValueError:
            self.get_logger().error(f'joint_states must name {LEG_NAMES}')
            return
        self._seen(INPUTS[0])
        self.gait.update_encoders(self._now(), [msg.position[k] for k in idx])

    def _on_clamp(self, ring, msg):
        self._seen(INPUTS[1 + ring])
        self.gait.update_clamp(self._now(), ring, msg.data)

    def _on_range(self, ring, msg):
        frame = msg.header.frame_id
        prefix = f'ring{ring + 1}_us'
        if not frame.startswith(prefix) or frame[len(prefix):] not in ('0', '1', '2'):
            self.get_logger().error(f'unexpected ultrasonic frame {frame!r}')
            return
        self._seen(INPUTS[3 + ring])
        self.gait.update_range(self._now(), ring, int(frame[len(prefix):]), msg.range)

    def _tick(self):
        """One planning step; while inactive with autostart, activate once the inputs are
        there (in this same tick, so planning keeps the timer's phase)."""
        state = self.lifecycle_state
        if state == 'inactive' and self.params.autostart and not self.missing_inputs():
            self.trigger_activate()
            state = self.lifecycle_state
        if state != 'active':
            self._say_waiting()
            return
        now = self._now()
        for action in self.gait.tick(now):
            self._execute(action, now)

    def _execute(self, action, now):
        stamp = self.get_clock().now().to_msg()
        if isinstance(action, LegCommand):
            msg = JointTrajectory()
            msg.header.stamp = stamp
            msg.joint_names = list(LEG_NAMES)
            point = JointTrajectoryPoint()
            point.positions = [float(v) for v in action.lengths]
            sec = int(action.duration)
            point.time_from_start = Duration(sec=sec, nanosec=int((action.duration - sec) * 1e9))
            msg.points = [point]
            self.leg_pub.publish(msg)
        elif isinstance(action, ClampCommand):
            self.clamp_pubs[action.ring].publish(Bool(data=action.close))
        elif isinstance(action, PlannedPose):
            pose = pose_msg(action.position, action.rotation)
            pose.header.stamp = stamp
            self.pose_pub.publish(pose)
            self.path.header.stamp = stamp
            self.path.poses.append(pose)
            self.path_pub.publish(self.path)
            self._publish_markers(stamp)
        elif isinstance(action, StatusUpdate):
            level = DiagnosticStatus.OK if action.ok else DiagnosticStatus.ERROR
            st = DiagnosticStatus(level=level, name='climber_planner', message=action.message,
                                  hardware_id='climber')
            st.values = [KeyValue(key='state', value=action.state)] + [
                KeyValue(key=k, value=str(v)) for k, v in action.values.items()]
            self.last_status = st
            self.status_pub.publish(st)
            v = action.values
            text = (f"{action.state}: cycle {v.get('cycle')} semicycle {v.get('semicycle')}, "
                    f"moving {v.get('moving')}, {v.get('steps')} steps"
                    + (f': {action.message}' if action.message else ''))
            # rclpy requires one severity per logging call site.
            if action.ok:
                self.get_logger().info(text)
            else:
                self.get_logger().error(text)

    def _publish_markers(self, stamp):
        arr = MarkerArray()
        rb = self.robot
        for ring, est in enumerate(self.gait.pose):
            if est is None:
                continue
            pos, rot = est
            m = Marker()
            m.header.frame_id = 'odom'
            m.header.stamp = stamp
            m.ns = 'rings'
            m.id = ring
            m.type = Marker.LINE_STRIP
            m.scale.x = 0.01
            m.color.a = 1.0
            m.color.r, m.color.g, m.color.b = (0.1, 0.4, 1.0) if ring == 0 else (1.0, 0.4, 0.1)
            for a in np.linspace(0, 2 * math.pi, 37):
                p = pos + rot @ np.array([rb.ring_inner_radius * math.cos(a),
                                          rb.ring_inner_radius * math.sin(a), 0.0])
                m.points.append(Point(x=float(p[0]), y=float(p[1]), z=float(p[2])))
            arr.markers.append(m)
        centres = Marker()
        centres.header.frame_id = 'odom'
        centres.header.stamp = stamp
        centres.ns = 'structure_centres'
        centres.type = Marker.SPHERE_LIST
        centres.scale.x = centres.scale.y = centres.scale.z = 0.02
        centres.color.a, centres.color.g = 1.0, 0.8
        for c in self.gait.centre_log:
            centres.points.append(Point(x=float(c[0]), y=float(c[1]), z=float(c[2])))
        arr.markers.append(centres)
        self.marker_pub.publish(arr)


def main(args=None):
    run_node(ClimberPlannerNode, args)


if __name__ == '__main__':
    main()
