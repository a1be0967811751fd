"""fast_cable_controller: coarse loop -- cable inverse kinematics plus a PID per winch.

Inputs: ``/fast/feed_target`` (PoseStamped), the tracked trolley pose ``/fast/tracker/trolley``
(direct terminal feedback, Lu, Zhu, Ren) and ``/fast/cables/state`` (tensions for the floor).
Every ``1/rate`` s it

1. derives the trolley target and the orienting-mechanism angles from the feed target
   (:class:`cable_robot_pkg.fast.focal_surface.FeedSupportChain`);
2. solves the cable inverse kinematics at the target (tension distribution within the limits,
   unstretched lengths) -- the feedforward;
3. runs one PID per winch on ``L_i(target) - L_i(tracked pose)``
   (:class:`cable_robot_pkg.fast.pid.WinchController`: anti-windup, winch speed limit,
   tension floor);

and publishes ``/fast/cables/command`` (JointState: position = unstretched length, velocity =
winch speed), ``/fast/orienting/command`` (hinge angles) and ``/fast/trolley_target``.
Without a fresh trolley measurement (``dropout_timeout``) it holds the winches and warns.
With ``without: tracker_feedback`` the winches follow the cable inverse kinematics alone
(open loop, no PID correction, trolley frames ignored).
"""
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState

from cable_robot_pkg.fast.configuration import parse_without
from cable_robot_pkg.fast.pid import CoarseController
from cable_robot_pkg.fast.ros_messages import (
    HINGE_NAMES,
    TOPICS,
    check_config_param,
    config_from_param,
    joint_state_msg,
    joint_vector,
    pose_from_msg,
    pose_msg,
)
from paramotion.errors import UserError
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import SENSOR_QOS, STATE_QOS


class CablePidNode(ParamotionNode):
    """Per-winch PID with terminal feedback from the trolley tracker."""

    PARAMS = (
        Param('config', '', 'FAST config YAML (empty: the packaged fast.yaml).',
              read_only=True),
        Param('rate', 50.0, 'Control rate (Hz, sim time).', min=1.0, max=1000.0,
              read_only=True),
        Param('kp', -1.0, 'Proportional gain per winch (m/m); < 0: config value.', min=-1.0,
              max=100.0, read_only=True),
        Param('ki', -1.0, 'Integral gain per winch (1/s); < 0: config value.', min=-1.0,
              max=100.0, read_only=True),
        Param('kd', -1.0, 'Derivative gain per winch (s); < 0: config value.', min=-1.0,
              max=10.0, read_only=True),
        Param('without', '', 'Comma-separated constructs switched off (tracker_feedback: '
              'open-loop cable IK; the others concern the isolation controller).',
              read_only=True),
        Param('dropout_timeout', 0.2, 'Hold the winches when the trolley measurement is older '
              'than this (s).', min=0.01, max=10.0),
    )

    def __init__(self, node_name='fast_cable_controller', **kwargs):
        super().__init__(node_name, **kwargs)
        self.cfg = config_from_param(self.params.config)
        cc = self.cfg.raw['cable_controller']
        for name in ('kp', 'ki', 'kd'):
            if getattr(self.params, name) >= 0:
                cc[name] = getattr(self.params, name)
        self.dt = 1.0 / self.params.rate
        open_loop = 'tracker_feedback' in parse_without(self.params.without, "parameter 'without'")
        self.ctl = CoarseController(self.cfg, self.dt, open_loop)
        self.winches = self.ctl.winches
        self.names = list(self.cfg.cables.names)
        self.target = None
        self.trolley = None
        self.trolley_arrival = None
        self.tensions = None
        self.update_times = []
        self.holding = False
        self._last_warn = -10.0
        self.create_subscription(PoseStamped, TOPICS['feed_target'], self._on_target, STATE_QOS)
        self.create_subscription(PoseStamped, TOPICS['tracker_trolley'], self._on_trolley,
                                 SENSOR_QOS)
        self.create_subscription(JointState, TOPICS['cables_state'], self._on_cables, STATE_QOS)
        self.cmd_pub = self.create_publisher(JointState, TOPICS['cables_command'], STATE_QOS)
        self.hinge_pub = self.create_publisher(JointState, TOPICS['orienting_command'],
                                               STATE_QOS)
        self.target_pub = self.create_publisher(PoseStamped, TOPICS['trolley_target'],
                                                STATE_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, TOPICS['diagnostics'], STATE_QOS)
        self.create_timer(self.dt, self._tick)

    def check_params(self, values):
        try:
            parse_without(values['without'], "parameter 'without'")
        except UserError as exc:
            return str(exc)
        return check_config_param(values['config'])

    def _now(self):
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_target(self, msg):
        p, R = pose_from_msg(msg)
        if np.isfinite(p).all() and np.isfinite(R).all():
            self.target = (p, R)

    def _on_trolley(self, msg):
        p, R = pose_from_msg(msg)
        if np.isfinite(p).all() and np.isfinite(R).all():
            self.trolley = (p, R)
            self.trolley_arrival = self._now()

    def _on_cables(self, msg):
        t = joint_vector(msg, self.names, 'effort')
        if t is not None:
            self.tensions = t

    def _warn(self, now, text):
        if now - self._last_warn >= 1.0:
            self._last_warn = now
            self.get_logger().warning(text)
            arr = DiagnosticArray()
            arr.header.stamp = self.get_clock().now().to_msg()
            arr.status = [DiagnosticStatus(level=DiagnosticStatus.WARN,
                                           name='fast_cable_controller', message=text)]
            self.diag_pub.publish(arr)

    def _tick(self):
        if self.target is None:
            return
        start = time.perf_counter()
        now = self._now()
        feed_p, feed_R = self.target
        trolley_p, (alpha, beta) = self.ctl.targets(feed_p, feed_R)
        stamp = self.get_clock().now().to_msg()
        self.target_pub.publish(pose_msg(stamp, 'map', trolley_p, np.eye(3)))
        self.hinge_pub.publish(joint_state_msg(stamp, HINGE_NAMES, [alpha, beta]))
        stale = self.trolley is None or now - self.trolley_arrival > self.params.dropout_timeout
        if stale and not self.ctl.open_loop and self.ctl.winches.command is not None:
            self.holding = True
            self._warn(now, 'no trolley tracker measurement for '
                       f'{self.params.dropout_timeout:g} s: holding the winches')
        elif not stale and self.holding:
            self.holding = False
            self.get_logger().info('trolley tracker measurements back: winch control resumed')
            arr = DiagnosticArray()
            arr.header.stamp = stamp
            arr.status = [DiagnosticStatus(level=DiagnosticStatus.OK,
                                           name='fast_cable_controller',
                                           message='trolley measurements back: resumed')]
            self.diag_pub.publish(arr)
        out = self.ctl.update(feed_p, feed_R, None if stale else self.trolley, self.tensions)
        for note in self.ctl.notes:
            self._warn(now, note)
        if out is None:
            return
        self.cmd_pub.publish(joint_state_msg(stamp, self.names, *out))
        self.update_times.append(time.perf_counter() - start)


def main(args=None):
    run_node(CablePidNode, args)


if __name__ == '__main__':
    main()
