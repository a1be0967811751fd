"""fast_isolation_controller: fine loop -- Gough-Stewart isolation of the feed.

Runs :class:`cable_robot_pkg.fast.isolation.IsolationController` at ``rate`` Hz (above the
cable loop's rate), clocked by the leg encoder stream (``/fast/legs/state``) like a drive's
servo cycle, in one of three modes: ``lu`` (PID on direct terminal feedback, Lu et al.),
``cheng`` (base position prediction + the legs' PD, Cheng et al.) or ``predictive`` (the
project's own: fused, latency-scheduled base prediction + slow trim on the tracked feed error).
``without`` (comma-separated) removes constructs: ``tracker_feedback`` (legs open loop from
the trajectory), ``isolation`` (legs held nominal), ``prediction`` (no extrapolation).

Inputs: ``/fast/feed_target``, ``/fast/tracker/{upper_platform,trolley,feed}``,
``/fast/legs/state`` and ``/fast/orienting/state`` (encoders, for fusing the trolley and feed
measurements into base measurements). Output: ``/fast/legs/command`` (JointState: position =
leg length m, velocity = m/s). With ``enabled: false`` the legs are held at their nominal
lengths (isolation off, the comparison case).

Dropout: when no valid base measurement has arrived for the config's
``isolation.dropout_timeout``, the legs hold their last command, a warning is logged and a WARN
diagnostic published; when measurements return the controller re-initialises its predictor
and resumes (logged once).
"""
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState

from cable_robot_pkg.fast.configuration import ABLATIONS, ISOLATION_MODES, parse_without
from cable_robot_pkg.fast.isolation import IsolationController
from cable_robot_pkg.fast.ros_messages import (
    HINGE_NAMES,
    LEG_NAMES,
    TOPICS,
    check_config_param,
    config_from_param,
    joint_state_msg,
    joint_vector,
    log_compile_time,
    pose_from_msg,
    stamp_seconds,
)
from paramotion.errors import UserError
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import SENSOR_QOS, STATE_QOS


class IsolationNode(ParamotionNode):
    """Leg commands that keep the feed still while the trolley vibrates."""

    PARAMS = (
        Param('config', '', 'FAST config YAML (empty: the packaged fast.yaml).',
              read_only=True),
        Param('rate', 200.0, 'Control rate (Hz, sim time); must exceed the cable loop rate.',
              min=1.0, max=2000.0, read_only=True),
        Param('enabled', True, 'false: hold the legs at nominal length (isolation off).'),
        Param('mode', 'config', 'lu (Lu et al.: PID on terminal feedback), cheng (Cheng et '
              "al.: base prediction + leg PD), predictive (ours), or config (the config's "
              'isolation.mode).', choices=('config',) + ISOLATION_MODES, read_only=True),
        Param('without', '', 'Comma-separated constructs switched off: ' + ', '.join(ABLATIONS)
              + ' (empty: none).', read_only=True),
    )

    def __init__(self, node_name='fast_isolation_controller', **kwargs):
        super().__init__(node_name, **kwargs)
        self.cfg = config_from_param(self.params.config)
        mode = None if self.params.mode == 'config' else self.params.mode
        self.without = parse_without(self.params.without, "parameter 'without'")
        self.enabled = self.params.enabled and 'isolation' not in self.without
        self.ctl = IsolationController.from_config(self.cfg, mode=mode, without=self.without)
        log_compile_time(self, 'the forward kinematics', self.ctl.compile_kernels)
        self.update_times = []
        self.hold_events = 0
        self.recoveries = 0
        self._holding = False
        self._last_warn = -10.0
        sub = self.create_subscription
        sub(PoseStamped, TOPICS['feed_target'], self._on_target, STATE_QOS)
        sub(PoseStamped, TOPICS['tracker_upper'], self._on_upper, SENSOR_QOS)
        sub(PoseStamped, TOPICS['tracker_trolley'], self._on_trolley, SENSOR_QOS)
        sub(PoseStamped, TOPICS['tracker_feed'], self._on_feed, SENSOR_QOS)
        sub(JointState, TOPICS['legs_state'], self._on_legs, STATE_QOS)
        sub(JointState, TOPICS['orienting_state'], self._on_hinges, STATE_QOS)
        self.pub = self.create_publisher(JointState, TOPICS['legs_command'], STATE_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, TOPICS['diagnostics'], STATE_QOS)
        self.next_update = 0.0
        self.cmd_msg = JointState()      # the leg command, refilled (publishing copies it)

    def check_params(self, values):
        reason = check_config_param(values['config'])
        if reason:
            return reason
        try:
            parse_without(values['without'], "parameter 'without'")
        except UserError as exc:
            return str(exc)
        cable_rate = config_from_param(values['config']).raw['cable_controller']['rate']
        if values['rate'] <= cable_rate:
            return (f"parameter 'rate' = {values['rate']} must exceed the cable loop rate "
                    f'{cable_rate} Hz')
        return None

    def _now(self):
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_target(self, msg):
        p, R = pose_from_msg(msg)
        if np.isfinite(p).all() and np.isfinite(R).all():
            self.ctl.set_target(stamp_seconds(msg.header.stamp), p, R)

    def _on_upper(self, msg):
        self.ctl.add_base(self._now(), stamp_seconds(msg.header.stamp), *pose_from_msg(msg))

    def _on_trolley(self, msg):
        p, R = pose_from_msg(msg)
        if np.isfinite(p).all() and np.isfinite(R).all():
            self.ctl.add_trolley(self._now(), stamp_seconds(msg.header.stamp), p, R)

    def _on_feed(self, msg):
        self.ctl.add_feed(self._now(), stamp_seconds(msg.header.stamp), *pose_from_msg(msg))

    def _on_legs(self, msg):
        """Leg encoders; they also clock the controller, like a drive's servo cycle: an update
        runs on the first encoder sample at or after each ``1/rate`` tick (sim time)."""
        t = stamp_seconds(msg.header.stamp)
        q = joint_vector(msg, LEG_NAMES)
        if q is not None:
            self.ctl.add_leg_state(t, q)
        if t + 1e-9 >= self.next_update:
            self.next_update = t + 1.0 / self.params.rate - 1e-9
            self._tick(t, msg.header.stamp)

    def _on_hinges(self, msg):
        q = joint_vector(msg, HINGE_NAMES)
        if q is not None:
            self.ctl.add_hinge_state(stamp_seconds(msg.header.stamp), q)

    def _diagnose(self, level, text):
        self.get_logger().warning(text) if level else self.get_logger().info(text)
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [DiagnosticStatus(level=level, name='fast_isolation_controller',
                                       message=text)]
        self.diag_pub.publish(arr)

    def _tick(self, now, stamp):
        if not self.enabled:
            self.pub.publish(joint_state_msg(stamp, LEG_NAMES, self.ctl.nominal_lengths,
                                             np.zeros(6)))
            return
        start = time.perf_counter()
        cmd = self.ctl.update(now)
        if cmd.holding and self.ctl.last_base_arrival is not None:
            if not self._holding:
                self.hold_events += 1
            self._holding = True
            if now - self._last_warn >= 1.0:
                self._last_warn = now
                self._diagnose(DiagnosticStatus.WARN, 'no upper platform measurement for '
                               f'{now - self.ctl.last_base_arrival:.3f} s: holding the legs')
        elif not cmd.holding and self._holding:
            self._holding = False
            self.recoveries += 1
            self._diagnose(DiagnosticStatus.OK, 'tracker measurements back: isolation resumed')
        if self.ctl.last_base_arrival is None and not self.ctl.open_loop:
            return   # nothing measured yet: the simulator keeps the legs at nominal length
        self.pub.publish(joint_state_msg(stamp, LEG_NAMES, cmd.lengths, cmd.rates,
                                         msg=self.cmd_msg))
        self.update_times.append(time.perf_counter() - start)


def main(args=None):
    run_node(IsolationNode, args)


if __name__ == '__main__':
    main()
