"""QoS profiles used across the graph, named for what the data is.

- ``SENSOR_QOS``: sensor streams, ``qos_profile_sensor_data`` (best effort, keep last 5).
- ``STATE_QOS``: commands and estimated state (reliable, keep last 10, volatile).
- ``LATCHED_QOS``: latched data such as maps, graphs and results (reliable, transient local,
  depth 1): a late subscriber still receives the last value.
- ``CLOCK_QOS``: ``/clock`` as rclpy's TimeSource subscribes to it (reliable would stall a
  free-running simulator on a slow subscriber, so best effort like ``rosgraph_msgs`` users expect).
"""
from rclpy.qos import (
                       DurabilityPolicy,
                       HistoryPolicy,
                       QoSProfile,
                       ReliabilityPolicy,
                       qos_profile_sensor_data,
)

SENSOR_QOS = qos_profile_sensor_data

STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)

LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)
