"""smoke_range_sensor: simulated forward range sensor on the cart (sensor_msgs/Range, REP 117).

Reads the cart's true pose (it is a simulated sensor, so ground truth is its input), and at
``rate`` Hz of sim time publishes ``/smoke/range`` with Gaussian noise, ``+inf`` beyond
``max_range``, ``-inf`` below ``min_range``, NaN with probability ``fault_probability`` and no
message at all with probability ``dropout_probability``.
"""
import math
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Range

from paramotion.messages import range_msg
from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import SENSOR_QOS
from paramotion.range_sensing import rep117_reading


class SmokeRangeSensorNode(ParamotionNode):
    """Ultrasonic-like range sensor at the cart's front face."""

    PARAMS = (
        Param('rate', 20.0, 'Measurement rate (Hz, sim time).', min=0.1, max=1000.0,
              read_only=True),
        Param('wall_x', 5.0, 'x of the wall face (m), same world as the simulator.',
              min=-100.0, max=100.0),
        Param('cart_half_length', 0.2, 'Sensor offset ahead of the cart centre (m).',
              min=0.0, max=5.0),
        Param('min_range', 0.02, 'Minimum measurable range (m).', min=0.0, max=100.0),
        Param('max_range', 4.0, 'Maximum measurable range (m).', min=0.01, max=100.0),
        Param('field_of_view', math.radians(15.0), 'Beam width (rad).', min=0.0, max=math.pi),
        Param('noise_std', 0.005, 'Standard deviation of range noise (m).', min=0.0, max=1.0),
        Param('fault_probability', 0.0, 'Probability that a reading is NaN (invalid).',
              min=0.0, max=1.0),
        Param('dropout_probability', 0.0, 'Probability that a reading is not published.',
              min=0.0, max=1.0),
        Param('seed', 1, 'Seed of the noise generator (reproducible runs).', min=0,
              max=2 ** 31 - 1, read_only=True),
        Param('frame_id', 'range_sensor', 'Frame of the sensor (x forward, REP 103).'),
    )

    def __init__(self, node_name: str = 'smoke_range_sensor', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.rng = np.random.default_rng(self.params.seed)
        self.cart_x = None
        self.create_subscription(PoseStamped, '/smoke/ground_truth', self._on_truth, SENSOR_QOS)
        self.pub = self.create_publisher(Range, '/smoke/range', SENSOR_QOS)
        self.create_timer(1.0 / self.params.rate, self._measure)

    def check_params(self, values: dict[str, Any]) -> str | None:
        """The measurable interval must not be empty."""
        if values['max_range'] <= values['min_range']:
            return (f"parameter 'max_range' = {values['max_range']} must exceed "
                    f"'min_range' = {values['min_range']}")
        return None

    def _on_truth(self, msg):
        self.cart_x = msg.pose.position.x

    def _measure(self):
        if self.cart_x is None:
            return
        p = self.params
        # Draw both random numbers every time so the noise sequence does not depend on faults.
        fault = self.rng.random() < p.fault_probability
        drop = self.rng.random() < p.dropout_probability
        distance = p.wall_x - (self.cart_x + p.cart_half_length)
        reading = rep117_reading(distance, p.min_range, p.max_range, p.noise_std, self.rng,
                                 fault=fault)
        if drop:
            return
        self.pub.publish(range_msg(self.get_clock().now().to_msg(), p.frame_id, reading,
                                   p.min_range, p.max_range, p.field_of_view))


def main(args: list[str] | None = None) -> None:
    """Console script ``smoke_range_sensor``."""
    run_node(SmokeRangeSensorNode, args)


if __name__ == '__main__':
    main()
