"""climber_ultrasonic: the three ultrasonic sensors of one ring (sensor_msgs/Range, REP 117).

A simulated sensor, so ground truth is its input: it reads the ring's true pose from
``/climber/ground_truth`` (geometry_msgs/PoseArray [ring 1, ring 2]) and casts the three beams
(120 deg apart in the ring plane, pointing at the ring axis, positions from the robot parameter
file) against the structure of ``trunk_file``: each sensor answers with the nearest echo inside
its cone (``field_of_view`` of the robot file, :meth:`Trunk.cone_distance`, computed by
:func:`climber_pkg.cone_cast.cone_distances`, one batch of rays). At ``rate`` Hz of
sim time it publishes one Range per sensor on ``/climber/ring<N>/ultrasonic`` (frame
``ring<N>_us<k>``, k = 0, 1, 2):
Gaussian noise, ``+inf`` with no echo (past the top of the structure or beyond max range),
``-inf`` below min range, NaN with probability ``fault_probability``, and no message at all
with probability ``dropout_probability``.
"""

import sys

import numpy as np
from geometry_msgs.msg import PoseArray
from sensor_msgs.msg import Range

from climber_pkg.cone_cast import cone_distances
from climber_pkg.robot import load_robot_config
from climber_pkg.trunk import Trunk
from paramotion.errors import ParameterError
from paramotion.messages import range_msg
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import SENSOR_QOS
from paramotion.range_sensing import rep117_reading
from paramotion.rotations import matrix_from_quat


class ClimberUltrasonicNode(ParamotionNode):
    """Three ultrasonic range sensors on one ring."""

    PARAMS = (
        Param('ring', 2, 'Which ring carries these sensors (1 = bottom, 2 = top).', min=1,
              max=2, read_only=True),
        Param('trunk_file', '', 'Structure JSON (shared/trunks format) the beams hit.',
              read_only=True),
        Param('robot_config', '', 'Robot geometry YAML; empty = climber_pkg/config/climber.yaml.',
              read_only=True),
        Param('rate', 20.0, 'Measurement rate (Hz, sim time).', min=0.1, max=1000.0,
              read_only=True),
        Param('noise_std', 0.001, 'Standard deviation of range noise (m).', min=0.0, max=0.1),
        Param('fault_probability', 0.0, 'Probability that a reading is NaN (invalid).',
              min=0.0, max=1.0),
        Param('dropout_probability', 0.0, 'Probability that a reading is not published.',
              min=0.0, max=1.0),
        Param('seed', 1, 'Seed of the noise generator (reproducible runs).', min=0,
              max=2 ** 31 - 1, read_only=True),
    )

    def __init__(self, node_name=None, **kwargs):
        super().__init__(node_name or 'climber_ultrasonic', **kwargs)
        p = self.params
        if not p.trunk_file:
            raise ParameterError(f"{self.get_name()}: parameter 'trunk_file' is required")
        self.trunk = Trunk.from_file(p.trunk_file)
        self.robot = load_robot_config(p.robot_config or None)
        self.index = p.ring - 1
        self.rng = np.random.default_rng(p.seed + 1000 * p.ring)
        self.origins, self.dirs = self.robot.sensor_rays()
        self.pose = None
        self._cache = (None, None)
        self._warm_up()
        self.create_subscription(PoseArray, '/climber/ground_truth', self._on_truth, SENSOR_QOS)
        self.pub = self.create_publisher(Range, f'/climber/ring{p.ring}/ultrasonic', SENSOR_QOS)
        self.create_timer(1.0 / p.rate, self._measure)

    def _on_truth(self, msg):
        if len(msg.poses) < 2:
            return
        pose = msg.poses[self.index]
        q = pose.orientation
        self.pose = (np.array([pose.position.x, pose.position.y, pose.position.z]),
                     matrix_from_quat([q.x, q.y, q.z, q.w]))

    def _warm_up(self):
        """Cast the beams once from the structure's base, before the node spins: the first
        cast compiles the ray-casting kernels (or loads them from numba's disk cache). Inside a
        callback that compile takes seconds on a loaded machine, and a Ctrl-C then waits for
        the callback to end, long enough for launch to escalate to SIGTERM and SIGKILL; here a
        Ctrl-C stops it, or, landing in one of LLVM's callbacks into Python (which drop the
        exception), is taken up by the node's spin, which ends at once. Such a dropped
        KeyboardInterrupt is not printed as an error."""
        previous = sys.unraisablehook

        def quiet(unraisable):
            if not isinstance(unraisable.exc_value, KeyboardInterrupt):
                previous(unraisable)
        sys.unraisablehook = quiet
        try:
            base = np.asarray(self.trunk.points[0], dtype=float)
            cone_distances(self.trunk, base + self.origins, self.dirs, self.robot.sensor_fov,
                           self.robot.sensor_max_range)
        finally:
            sys.unraisablehook = previous

    def true_distances(self):
        """Noise-free nearest echo in each sensor's cone for the current ring pose (m or inf)."""
        pos, rot = self.pose
        key = (pos.round(6).tobytes(), rot.round(7).tobytes())
        if self._cache[0] != key:
            self._cache = (key, cone_distances(
                self.trunk, pos + self.origins @ rot.T, self.dirs @ rot.T,
                self.robot.sensor_fov, self.robot.sensor_max_range))
        return self._cache[1]

    def _measure(self):
        if self.pose is None:
            return
        p, rb = self.params, self.robot
        stamp = self.get_clock().now().to_msg()
        for k, distance in enumerate(self.true_distances()):
            fault = self.rng.random() < p.fault_probability
            drop = self.rng.random() < p.dropout_probability
            reading = rep117_reading(float(distance), rb.sensor_min_range, rb.sensor_max_range,
                                     p.noise_std, self.rng, fault=fault)
            if drop:
                continue
            self.pub.publish(range_msg(stamp, f'ring{p.ring}_us{k}', reading,
                                       rb.sensor_min_range, rb.sensor_max_range, rb.sensor_fov))


def main(args=None):
    run_node(ClimberUltrasonicNode, args)


if __name__ == '__main__':
    main()
