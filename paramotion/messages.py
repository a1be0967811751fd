"""Builders for the standard messages several nodes publish, so that every sensor fills them
the same way (REP 117 ranges, stamped poses)."""
from collections.abc import Sequence

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Range


def range_msg(stamp: Time, frame_id: str, reading: float, min_range: float, max_range: float,
              field_of_view: float, radiation_type: int = Range.ULTRASOUND) -> Range:
    """sensor_msgs/Range with every field filled; ``reading`` already REP 117 encoded."""
    msg = Range()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.radiation_type = radiation_type
    msg.field_of_view = float(field_of_view)
    msg.min_range = float(min_range)
    msg.max_range = float(max_range)
    msg.range = float(reading)
    return msg


def pose_stamped(stamp: Time, frame_id: str, position: Sequence[float],
                 quaternion_xyzw: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> PoseStamped:
    """geometry_msgs/PoseStamped from a position (x, y, z) and a quaternion (x, y, z, w)."""
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    p, q = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z = (float(v) for v in position)
    q.x, q.y, q.z, q.w = (float(v) for v in quaternion_xyzw)
    return msg
