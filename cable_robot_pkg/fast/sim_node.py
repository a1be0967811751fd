"""fast_sim: PyBullet FAST feed support (hardware stand-in, owns /clock).

The model (:class:`cable_robot_pkg.fast.plant.FeedSupportPlant`): a trolley on ten
tension-only elastic cables over the field model's towers, a 2-DOF orienting mechanism and a
Gough-Stewart platform as a dynamic closed chain (P2P-constrained legs) under it, wind on the
trolley. Subscribes to winch, hinge and leg commands; publishes every ``publish_period``:

- ``/fast/ground_truth/{trolley,upper_platform,feed}`` (geometry_msgs/PoseStamped, ``map``)
- ``/fast/cables/state`` (sensor_msgs/JointState: position = stretched length m, velocity =
  dL/dt m/s, effort = tension N) and ``/fast/winches/state`` (position = unstretched length)
- ``/fast/legs/state`` (position = leg length m, velocity m/s, effort = actuator force N)
- ``/fast/orienting/state`` (hinge angles rad)
- ``/fast/wind`` (geometry_msgs/WrenchStamped on the trolley, ``map`` axes)
- ``/diagnostics``: WARN while a cable is slack, above its tension limit, or a leg is at a
  stroke end (once per second at most), naming the cables/legs.
"""
import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, WrenchStamped
from sensor_msgs.msg import JointState

from cable_robot_pkg.fast.plant import FeedSupportPlant
from cable_robot_pkg.fast.ros_messages import (
    HINGE_NAMES,
    LEG_NAMES,
    TOPICS,
    check_config_param,
    config_from_param,
    joint_state_msg,
    joint_vector,
    log_compile_time,
    pose_msg,
    stamp_seconds,
)
from cable_robot_pkg.fast.wind import WindModel
from paramotion.node import Param, run_node
from paramotion.qos import STATE_QOS
from paramotion.sim import NS, SimulationNode


class FastSimNode(SimulationNode):
    """The FAST field model in PyBullet."""

    PARAMS = tuple(p for p in SimulationNode.PARAMS if p.name != 'publish_period') + (
        Param('publish_period', 0.005, 'Simulated seconds per step; /clock and state are '
              'published once per step.', min=1e-4, max=1.0, read_only=True),
        Param('config', '', 'FAST config YAML (empty: the packaged fast.yaml).',
              read_only=True),
        Param('wind', 1.0, 'Wind intensity: scales the mean wind speed and the gust rate '
              '(0 = calm).', min=0.0, max=5.0, read_only=True),
        Param('wind_seed', -1, "Seed of the wind generator (-1: the config's wind.seed).",
              min=-1, max=2 ** 31 - 1, read_only=True),
        Param('solver_iterations', 0, "PyBullet solver iterations (0: the config's "
              'sim.solver_iterations).', min=0, max=1000, read_only=True),
    )

    def __init__(self, node_name='fast_sim', **kwargs):
        super().__init__(node_name, **kwargs)
        p = self.params
        self.cfg = config_from_param(p.config)
        seed = None if p.wind_seed < 0 else p.wind_seed
        wind = WindModel.from_config(self.cfg.raw['wind'], self.cfg.raw['trolley'],
                                     intensity=p.wind, seed=seed)
        self.plant = FeedSupportPlant(self.cfg, self.bullet, wind=wind, dt=p.physics_dt,
                                      solver_iterations=p.solver_iterations or None)
        log_compile_time(self, 'the plant step', self.plant.compile_step)
        self.cable_names = list(self.cfg.cables.names)
        self.slack_steps = np.zeros(len(self.cable_names), int)
        self.over_limit_steps = np.zeros(len(self.cable_names), int)
        self.stroke_steps = np.zeros(6, int)
        self.tension_min = np.inf
        self.tension_max = 0.0
        self._last_diag = -1.0
        self.create_subscription(JointState, TOPICS['cables_command'], self._on_winch, STATE_QOS)
        self.create_subscription(JointState, TOPICS['legs_command'], self._on_legs, STATE_QOS)
        self.create_subscription(JointState, TOPICS['orienting_command'], self._on_hinges,
                                 STATE_QOS)
        pub = self.create_publisher
        self.pubs = {k: pub(t, TOPICS[k], STATE_QOS) for k, t in (
            ('truth_trolley', PoseStamped), ('truth_upper', PoseStamped),
            ('truth_feed', PoseStamped), ('cables_state', JointState),
            ('winches_state', JointState), ('legs_state', JointState),
            ('orienting_state', JointState), ('wind', WrenchStamped),
            ('diagnostics', DiagnosticArray))}
        self.msgs = {k: PoseStamped() for k in ('truth_trolley', 'truth_upper', 'truth_feed')}
        self.msgs.update((k, JointState()) for k in ('cables_state', 'winches_state',
                                                     'legs_state', 'orienting_state'))

    def check_params(self, values):
        reason = super().check_params(values)
        return reason or check_config_param(values['config'])

    # ------------------------------------------------------------------ commands
    def _on_winch(self, msg):
        # The cable controller's winch command, the last message of its tick (sync_max_lag).
        self.answered('fast_cable_controller', msg.header.stamp.sec * NS
                      + msg.header.stamp.nanosec)
        pos = joint_vector(msg, self.cable_names)
        vel = joint_vector(msg, self.cable_names, 'velocity')
        if pos is not None and np.all(np.isfinite(pos)) and np.all(pos > 0):
            self.plant.set_winch_command(pos, vel if vel is not None and np.all(
                np.isfinite(vel)) else None, stamp_seconds(msg.header.stamp))

    def _on_legs(self, msg):
        # The isolation controller's leg command answers the state stamped like it
        # (sync_max_lag: the free-running simulator waits for that answer).
        self.answered('fast_isolation_controller', msg.header.stamp.sec * NS
                      + msg.header.stamp.nanosec)
        pos = joint_vector(msg, LEG_NAMES)
        vel = joint_vector(msg, LEG_NAMES, 'velocity')
        if pos is not None and np.all(np.isfinite(pos)):
            # The command is a time-stamped set-point: the drive extrapolates it from its
            # stamp with its velocity (first-order hold), as a servo trajectory interface does.
            self.plant.set_leg_command(pos, vel if vel is not None and np.all(
                np.isfinite(vel)) else None, stamp_seconds(msg.header.stamp))

    def _on_hinges(self, msg):
        pos = joint_vector(msg, HINGE_NAMES)
        if pos is not None and np.all(np.isfinite(pos)):
            self.plant.set_hinge_command(*pos)

    # ------------------------------------------------------------------ physics
    def step_physics(self, dt):
        pl = self.plant
        pl.step()
        # Counters and extremes from the step's own summary (array work only when a cable is
        # slack or over its limit); NaN tensions count as numpy's comparisons count them.
        low, high = pl.tension_range
        if pl.slack_count:
            self.slack_steps += pl.slack
        if not high <= pl.t_max:
            self.over_limit_steps += pl.last_tensions > pl.t_max
        if low < self.tension_min:
            self.tension_min = low
        if high > self.tension_max:
            self.tension_max = high

    def publish_state(self):
        pl = self.plant
        pubs, msgs = self.pubs, self.msgs
        stamp = self.stamp()
        trolley = pl.trolley_pose()
        # One message per topic, refilled (publishing copies it).
        pubs['truth_trolley'].publish(pose_msg(stamp, 'map', *trolley,
                                               msg=msgs['truth_trolley']))
        pubs['truth_upper'].publish(pose_msg(stamp, 'map', *pl.upper_pose(),
                                             msg=msgs['truth_upper']))
        pubs['truth_feed'].publish(pose_msg(stamp, 'map', *pl.feed_pose(),
                                            msg=msgs['truth_feed']))
        dL = self.cfg.cables.length_rates(*trolley, *pl.trolley_velocity())
        pubs['cables_state'].publish(joint_state_msg(
            stamp, self.cable_names, pl.last_lengths, dL, pl.last_tensions,
            msg=msgs['cables_state']))
        if pubs['winches_state'].get_subscription_count():   # no reader, no message
            pubs['winches_state'].publish(joint_state_msg(
                stamp, self.cable_names, pl.unstretched, pl.winch_rates,
                msg=msgs['winches_state']))
        q, v, f = pl.leg_lengths()
        pubs['legs_state'].publish(joint_state_msg(stamp, LEG_NAMES, q, v, f,
                                                   msg=msgs['legs_state']))
        # Stroke ends tested on floats (the same comparisons); arrays only when a leg is there.
        lo, hi = pl.geom.leg_min + 1e-3, pl.geom.leg_max - 1e-3
        at_end = None
        if any(x <= lo or x >= hi for x in q.tolist()):
            at_end = (q <= lo) | (q >= hi)
            self.stroke_steps += at_end
        pubs['orienting_state'].publish(joint_state_msg(stamp, HINGE_NAMES, pl.hinge_angles(),
                                                        msg=msgs['orienting_state']))
        if self.pubs['wind'].get_subscription_count():
            w = WrenchStamped()
            w.header.stamp = stamp
            w.header.frame_id = 'map'
            w.wrench.force.x, w.wrench.force.y, w.wrench.force.z = (
                float(x) for x in pl.wind_force)
            w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z = (
                float(x) for x in pl.wind_torque)
            self.pubs['wind'].publish(w)
        problems = []
        # The step's summary says whether there is anything to name: its slack count, and
        # its largest tension (NaN when one is NaN, which numpy's comparison does not count).
        if pl.slack_count:
            problems.append('slack: ' + ', '.join(n for n, s in zip(self.cable_names, pl.slack)
                                                  if s))
        high = pl.tension_range[1]
        if not high <= pl.t_max:
            over = pl.last_tensions > pl.t_max
            if over.any():
                problems.append('over tension limit: ' + ', '.join(
                    n for n, o in zip(self.cable_names, over) if o))
        if at_end is not None:
            problems.append('at stroke end: ' + ', '.join(
                n for n, e in zip(LEG_NAMES, at_end) if e))
        if problems and self.sim_time - self._last_diag >= 1.0:
            self._last_diag = self.sim_time
            self.get_logger().warning('; '.join(problems))
            self.pubs['diagnostics'].publish(_diag(stamp, DiagnosticStatus.WARN, '; '.join(
                problems), {'tension_min': pl.last_tensions.min(),
                            'tension_max': pl.last_tensions.max()}))


def _diag(stamp, level, message, values):
    arr = DiagnosticArray()
    arr.header.stamp = stamp
    st = DiagnosticStatus(level=level, name='fast_sim: cables and legs', message=message,
                          hardware_id='fast_field_model')
    st.values = [KeyValue(key=k, value=f'{v:.6g}') for k, v in values.items()]
    arr.status = [st]
    return arr


def main(args=None):
    run_node(FastSimNode, args)


if __name__ == '__main__':
    main()
