"""smoke_controller: drives the cart to ``target`` metres from the wall from range data only.

Subscribes ``/smoke/range`` (sensor_msgs/Range) and publishes ``/smoke/cmd_vel``
(geometry_msgs/Twist) on every reading, using :func:`paramotion.smoke.control.approach_velocity`.
A watchdog on sim time stops the cart when no reading arrived for ``timeout`` seconds and says
so on ``/smoke/status`` (diagnostic_msgs/DiagnosticArray, latched); it resumes when readings
return.
"""
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist
from sensor_msgs.msg import Range

from paramotion.node import Param, ParamotionNode, run_node
from paramotion.qos import LATCHED_QOS, SENSOR_QOS, STATE_QOS
from paramotion.smoke.control import approach_velocity


class SmokeControllerNode(ParamotionNode):
    """Range-only approach controller with a sensor watchdog."""

    PARAMS = (
        Param('target', 1.0, 'Distance to keep from the wall (m).', min=0.0, max=100.0),
        Param('gain', 1.5, 'Proportional gain (1/s).', min=0.0, max=100.0),
        Param('max_speed', 1.0, 'Speed limit (m/s).', min=0.0, max=10.0),
        Param('timeout', 0.5, 'Stop when no reading for this long (s, sim time).', min=0.01,
              max=60.0),
    )

    def __init__(self, node_name: str = 'smoke_controller', **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.cmd_pub = self.create_publisher(Twist, '/smoke/cmd_vel', STATE_QOS)
        self.status_pub = self.create_publisher(DiagnosticArray, '/smoke/status', LATCHED_QOS)
        self.create_subscription(Range, '/smoke/range', self._on_range, SENSOR_QOS)
        self.last_reading_time = None
        self.state = None
        self.readings = 0
        self.create_timer(0.1, self._watchdog)
        self._set_state('waiting', 'no range reading yet')

    def _on_range(self, msg):
        self.readings += 1
        self.last_reading_time = self.get_clock().now()
        p = self.params
        speed = approach_velocity(msg.range, p.target, p.gain, p.max_speed)
        cmd = Twist()
        cmd.linear.x = float(speed)
        self.cmd_pub.publish(cmd)
        self._set_state('tracking', 'range readings arriving')

    def _watchdog(self):
        now = self.get_clock().now()
        if self.last_reading_time is None:
            return
        if (now - self.last_reading_time).nanoseconds * 1e-9 > self.params.timeout:
            if self.state != 'sensor_timeout':
                self.cmd_pub.publish(Twist())
            self._set_state('sensor_timeout', 'no range reading: cart stopped')

    def _set_state(self, state, message):
        if state == self.state:
            return
        self.state = state
        level = DiagnosticStatus.WARN if state == 'sensor_timeout' else DiagnosticStatus.OK
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status.append(DiagnosticStatus(
            level=level, name='smoke_controller', message=message, hardware_id='smoke_cart',
            values=[KeyValue(key='state', value=state)]))
        self.status_pub.publish(arr)
        if state == 'sensor_timeout':
            self.get_logger().warning(message)


def main(args: list[str] | None = None) -> None:
    """Console script ``smoke_controller``."""
    run_node(SmokeControllerNode, args)


if __name__ == '__main__':
    main()
