"""Message helpers shared by the FAST nodes: poses and joint states <-> numpy.

Topic names live here too, so the nodes, the scenario and the tests agree on them.
"""
from __future__ import annotations

import array
import copy
import math
import os
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from numpy.typing import ArrayLike
from sensor_msgs.msg import JointState

from cable_robot_pkg.fast.configuration import DEFAULT_CONFIG, FastConfig, load_config
from paramotion.errors import UserError
from paramotion.rotations import matrix_from_quat, quat_from_matrix

TOPICS = {
    'truth_trolley': '/fast/ground_truth/trolley',
    'truth_upper': '/fast/ground_truth/upper_platform',
    'truth_feed': '/fast/ground_truth/feed',
    'tracker_trolley': '/fast/tracker/trolley',
    'tracker_upper': '/fast/tracker/upper_platform',
    'tracker_feed': '/fast/tracker/feed',
    'feed_target': '/fast/feed_target',
    'trolley_target': '/fast/trolley_target',
    'cables_state': '/fast/cables/state',
    'winches_state': '/fast/winches/state',
    'cables_command': '/fast/cables/command',
    'legs_state': '/fast/legs/state',
    'legs_command': '/fast/legs/command',
    'orienting_state': '/fast/orienting/state',
    'orienting_command': '/fast/orienting/command',
    'wind': '/fast/wind',
    'diagnostics': '/diagnostics',
}

LEG_NAMES = [f'leg{i + 1}' for i in range(6)]
HINGE_NAMES = ['hinge_x', 'hinge_y']


_CONFIG_CACHE = {}


def _file_key(path):
    st = os.stat(path)
    return (os.path.realpath(path), st.st_mtime_ns, st.st_size)


def config_from_param(path: str) -> FastConfig:
    """Validated config from a node's ``config`` parameter ('' = the packaged default).

    Validation (every track target's reachability) takes most of a node's start-up, and a
    one-process graph has five nodes reading the same file, each twice (parameter check and
    construction): the validated config is cached per file contents (path, mtime, size of the
    user file and of the packaged defaults) and each caller gets its own deep copy.
    """
    try:
        key = (_file_key(path) if path else None, _file_key(DEFAULT_CONFIG))
    except OSError:
        return load_config(path or None)     # missing file: load_config names the problem
    if key not in _CONFIG_CACHE:
        _CONFIG_CACHE.clear()
        _CONFIG_CACHE[key] = load_config(path or None)
    return copy.deepcopy(_CONFIG_CACHE[key])


def stamp_seconds(stamp: Time) -> float:
    """builtin_interfaces/Time -> float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def pose_msg(stamp: Time, frame_id: str, position: ArrayLike, rotation: ArrayLike,
             msg: PoseStamped | None = None) -> PoseStamped:
    """PoseStamped from a position (3,) and rotation matrix (3, 3).

    ``msg``: a message to refill instead of a new one (a publisher keeps one per topic; the
    middleware and the in-process delivery copy a message when it is published)."""
    if msg is None:
        msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    pose = msg.pose
    p = pose.position
    p.x, p.y, p.z = float(position[0]), float(position[1]), float(position[2])
    o = pose.orientation
    o.x, o.y, o.z, o.w = quat_from_matrix(rotation)   # x, y, z, w (floats)
    return msg


def pose_from_msg(msg: PoseStamped) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,), rotation (3, 3)) of a PoseStamped; NaN-safe (returns NaN arrays)."""
    pose = msg.pose
    p = pose.position
    o = pose.orientation
    position = np.array([p.x, p.y, p.z], float)
    x, y, z, w = o.x, o.y, o.z, o.w
    isfinite = math.isfinite
    if not (isfinite(x) and isfinite(y) and isfinite(z) and isfinite(w)) \
            or math.sqrt(x * x + y * y + z * z + w * w) < 1e-9:
        return position, np.full((3, 3), np.nan)
    return position, matrix_from_quat((x, y, z, w))


def _doubles(values: ArrayLike) -> array.array:
    """A ``float64[]`` message field (``array('d')``, what the setter stores) of ``values``."""
    return array.array('d', np.asarray(values, float).tobytes())


def joint_state_msg(stamp: Time, names: Sequence[str], position: ArrayLike,
                    velocity: ArrayLike | None = None,
                    effort: ArrayLike | None = None,
                    msg: JointState | None = None) -> JointState:
    """sensor_msgs/JointState (``msg``: a message to refill instead of a new one; a field
    not given is left empty, as in a new message, whatever the refilled one held)."""
    if msg is None:
        msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(names)
    msg.position = _doubles(position)
    msg.velocity = _doubles(velocity) if velocity is not None else []
    msg.effort = _doubles(effort) if effort is not None else []
    return msg


def joint_vector(msg: JointState, names: Sequence[str],
                 field: str = 'position') -> np.ndarray | None:
    """Values of ``field`` in ``names`` order, or None if the message does not match."""
    values = getattr(msg, field)
    if len(values) != len(msg.name):
        return None
    if list(msg.name) == list(names):      # the usual case: the publisher's order
        return np.array(values, float)
    index = {n: i for i, n in enumerate(msg.name)}
    if any(n not in index for n in names):
        return None
    return np.array([values[index[n]] for n in names], float)


def check_config_param(path: str) -> str | None:
    """One-line reason if the ``config`` parameter does not load, else None."""
    try:
        config_from_param(path)
    except UserError as exc:
        return f"parameter 'config': {exc}"
    return None


def log_compile_time(node: Any, what: str, compile_now: Callable[[], object]) -> None:
    """Run ``compile_now`` (a node's numba kernels, compiled or loaded from numba's disk
    cache) while the node starts, and say so when it took long: the first start after an
    install compiles them, seconds in which the node would seem stuck without the line."""
    start = time.monotonic()
    compile_now()
    took = time.monotonic() - start
    if took > 1.0:
        node.get_logger().info(f'compiled {what} in {took:.1f} s (numba keeps it in its disk '
                               'cache: later starts load it)')
