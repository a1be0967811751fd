"""coverage_sonar: simulated ring of ultrasonic transducers (sensor_msgs/Range, REP 117).

A simulated sensor: its inputs are the world file and the true pose
(``/coverage/ground_truth``). Every ``1/rate`` s of sim time it ray-casts each transducer's cone
(:func:`coverage_pkg.sonar.simulate_ring`, by a :class:`coverage_pkg.sonar.RingCaster` built
once per ring geometry) and publishes

* ``sonar/ranges``: one sensor_msgs/Range per transducer, all with the sweep's stamp, frame
  ``sonar_<k>`` (transducer k points at ``2 pi k / count`` rad from the robot's +x axis),
  ``radiation_type = ULTRASOUND``, ``field_of_view = beam_width``, REP 117 values
  (+inf no echo, -inf too close, NaN invalid);
* ``sonar/scan``: the same sweep as one sensor_msgs/LaserScan in ``base_link``.

Faults for testing the planner: ``fault_probability`` makes single readings NaN,
``dropout_probability`` drops whole sweeps, ``silence_start``/``silence_duration`` stop the ring
for a sim-time window.
"""
import math

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import LaserScan, Range

from coverage_pkg.sonar import RingCaster, SonarRing, yaw_of
from coverage_pkg.world import load_world_param
from paramotion.messages import range_msg
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import SENSOR_QOS

# Sensor-data QoS (best effort) deep enough for whole sweeps: all ``count`` Range messages of a
# sweep are published at once, and the default depth of 5 would drop most of them.
SONAR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=128,
                       reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)


class CoverageSonarNode(ParamotionNode):
    """Sonar ring simulator."""

    PARAMS = (
        Param('world', '', 'World JSON file (same as the simulator).', read_only=True),
        Param('count', 16, 'Number of transducers, evenly spaced.', min=3, max=360,
              read_only=True),
        Param('beam_width', 0.2, 'Full cone angle of a transducer (rad), REP 117 '
              'field_of_view.', min=0.01, max=1.5),
        Param('min_range', 0.05, 'Minimum range (m); closer gives -inf.', min=0.0, max=10.0),
        Param('max_range', 5.0, 'Maximum range (m); no echo gives +inf. Must exceed the '
              'detector range delta.', min=0.1, max=100.0),
        Param('noise_std', 0.01, 'Range noise standard deviation (m).', min=0.0, max=1.0),
        Param('rays_per_beam', 7, 'Rays cast per cone.', min=1, max=101),
        Param('rate', 10.0, 'Sweeps per second of sim time.', min=0.1, max=100.0,
              read_only=True),
        Param('seed', 1, 'Noise seed (reproducible runs).', min=0, max=2 ** 31 - 1,
              read_only=True),
        Param('fault_probability', 0.0, 'Probability that one reading is NaN.', min=0.0,
              max=1.0),
        Param('dropout_probability', 0.0, 'Probability that a whole sweep is not published.',
              min=0.0, max=1.0),
        Param('silence_start', -1.0, 'Sim time (s) at which the ring falls silent (<0: never).',
              min=-1.0, max=1e6),
        Param('silence_duration', 0.0, 'Length of that silence (s).', min=0.0, max=1e6),
    )

    def __init__(self, node_name='coverage_sonar', **kwargs):
        super().__init__(node_name, **kwargs)
        self.world = load_world_param(self, self.params.world)
        self.rng = np.random.default_rng(self.params.seed)
        self.pose = None
        self.sweeps = 0
        self._caster = None
        self._scan = None
        self.create_subscription(Odometry, '/coverage/ground_truth', self._on_truth, SENSOR_QOS)
        self.range_pub = self.create_publisher(Range, 'sonar/ranges', SONAR_QOS)
        self.scan_pub = self.create_publisher(LaserScan, 'sonar/scan', SENSOR_QOS)
        self.create_timer(1.0 / self.params.rate, self._sweep)

    def check_params(self, values):
        if values['max_range'] <= values['min_range']:
            return (f"parameter 'max_range' = {values['max_range']} must exceed "
                    f"'min_range' = {values['min_range']}")
        return None

    def ring(self):
        p = self.params
        return SonarRing(count=p.count, beam_width=p.beam_width, min_range=p.min_range,
                         max_range=p.max_range, noise_std=p.noise_std,
                         rays_per_beam=p.rays_per_beam)

    def caster(self):
        """The ray caster of the current ring parameters (rebuilt when one of them changed)."""
        ring = self.ring()
        if self._caster is None or self._caster.ring != ring:
            self._caster = RingCaster(self.world, ring)
        return self._caster

    def _on_truth(self, msg):
        q = msg.pose.pose.orientation
        self.pose = (msg.pose.pose.position.x, msg.pose.pose.position.y, yaw_of(q))
        self.pose_stamp = msg.header.stamp

    def _sweep(self):
        if self.pose is None:
            return
        p = self.params
        now = self.get_clock().now()
        t = now.nanoseconds * 1e-9
        ranges = self.caster()(self.pose, self.rng)
        faults = self.rng.random(len(ranges)) < p.fault_probability
        drop = self.rng.random() < p.dropout_probability
        ranges[faults] = math.nan
        if drop or (p.silence_start >= 0.0
                    and p.silence_start <= t < p.silence_start + p.silence_duration):
            return
        # The sweep is stamped with the time of the pose it was taken from, so that the planner
        # pairs it with the odometry of that same instant.
        stamp = self.pose_stamp
        # The per-transducer stream is only built when someone listens (16 messages a sweep).
        per_transducer = self.range_pub.get_subscription_count() > 0
        for k, value in enumerate(ranges if per_transducer else []):
            self.range_pub.publish(range_msg(stamp, f'sonar_{k}', value, p.min_range,
                                             p.max_range, p.beam_width))
        scan = self._scan
        if scan is None:          # one message, refilled every sweep (publishing serialises it)
            scan = self._scan = LaserScan()
            scan.header.frame_id = 'base_link'
            scan.angle_min = 0.0
            scan.angle_increment = 2.0 * math.pi / p.count
            scan.angle_max = scan.angle_increment * (p.count - 1)
            scan.scan_time = 1.0 / p.rate
        scan.header.stamp = stamp
        scan.range_min = float(p.min_range)
        scan.range_max = float(p.max_range)
        scan.ranges = ranges.tolist()
        self.scan_pub.publish(scan)
        self.sweeps += 1


def main(args=None):
    run_node(CoverageSonarNode, args)


if __name__ == '__main__':
    main()
