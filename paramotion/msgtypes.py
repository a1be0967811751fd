"""Resolve ROS 2 message types by name ('sensor_msgs/msg/Range') without rosidl_runtime_py."""
import importlib
from typing import Any

from paramotion.errors import UserError


def message_class(msgtype: str) -> type[Any]:
    """Return the Python class of ``msgtype`` ('pkg/msg/Type' or 'pkg/Type')."""
    parts = msgtype.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts):
        raise UserError(f'message type {msgtype!r}: expected pkg/msg/Type')
    try:
        module = importlib.import_module(f'{parts[0]}.{parts[1]}')
        return getattr(module, parts[2])
    except (ImportError, AttributeError):
        raise UserError(f'message type {msgtype!r}: not installed') from None


def type_name(msg_or_cls: object) -> str:
    """'pkg/msg/Type' of an rclpy message instance or class."""
    cls = msg_or_cls if isinstance(msg_or_cls, type) else type(msg_or_cls)
    module = cls.__module__.split('.')
    return f'{module[0]}/{module[1]}/{cls.__name__}'
