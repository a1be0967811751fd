"""Clean Ctrl-C for timer-driven publishers.

When SIGINT arrives while a timer callback is publishing, rclpy shuts the context down under it
and ``publish`` raises ``RCLError: publisher's context is invalid``; without this guard a
node stopped by Ctrl-C (or ``ros2 launch`` shutting down) prints a traceback and exits non-zero.
"""
import functools

from rclpy._rclpy_pybind11 import RCLError


def tolerate_shutdown(method):
    """Decorate a node method: swallow the publish error only if the context is shut down."""
    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except RCLError:
            if self.context.ok():
                raise
            return None
    return wrapper
