"""Write rosbag2 bags (metadata.yaml + one .mcap file, version 9, cdr, ros2msg schemas).

The heavy lifting (MCAP records, ``metadata.yaml``) is done by ``rosbags``; this module adds
what a recorder needs on top of it: QoS profiles converted from rclpy publishers, and chunks
flushed to disk at least every ``flush_period`` seconds of wall time, so a recorder killed with
SIGKILL leaves a file whose complete chunks still read back (see :mod:`paramotion.bag.reader`).
"""
import os
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from paramotion.errors import UserError

_TYPESTORE = None


def typestore() -> Typestore:
    """The Jazzy type store (message definitions and hashes of the standard messages)."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


def _duration(d):
    """rclpy Duration -> rosbags QosTime (rosbag2 writes 'infinite' as the max values)."""
    ns = d.nanoseconds
    if ns == 0 or ns >= 2 ** 63 - 1:
        return QosTime(sec=0x7FFFFFFF, nsec=0xFFFFFFFF) if ns else QosTime(sec=0, nsec=0)
    return QosTime(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def qos_from_rclpy(profile: Any) -> Qos:
    """Convert an rclpy ``QoSProfile`` into the rosbags ``Qos`` stored in offered_qos_profiles.

    ``profile`` is read by attribute, so this module needs no rclpy import.
    """
    return Qos(
        history=QosHistory(int(profile.history)),
        depth=int(profile.depth),
        reliability=QosReliability(int(profile.reliability)),
        durability=QosDurability(int(profile.durability)),
        deadline=_duration(profile.deadline),
        lifespan=_duration(profile.lifespan),
        liveliness=QosLiveliness(int(profile.liveliness)),
        liveliness_lease_duration=_duration(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


class BagWriter:
    """A rosbag2 MCAP bag being written; flushes complete chunks periodically.

    Use as a context manager or call :meth:`close`. ``path`` must not exist yet (rosbag2 never
    overwrites a bag); its parent directory is created.
    """

    def __init__(self, path: str | os.PathLike[str], flush_period: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        path = Path(path)
        if path.exists():
            raise UserError(f'bag {path}: already exists, not overwriting')
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.flush_period = float(flush_period)
        self._clock = clock
        self._writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections = {}
        self._last_flush = clock()
        self._dirty = False
        self.message_count = 0

    def add_topic(self, topic: str, msgtype: str, offered_qos: Iterable[Any] = ()) -> None:
        """Register ``topic`` of ``msgtype`` ('pkg/msg/Type') with the publishers' QoS profiles."""
        if topic in self._connections:
            return
        qos = [q if isinstance(q, Qos) else qos_from_rclpy(q) for q in offered_qos]
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=typestore(), offered_qos_profiles=qos)
        self._dirty = True

    def has_topic(self, topic: str) -> bool:
        """True once ``topic`` is registered."""
        return topic in self._connections

    def write(self, topic: str, timestamp_ns: int, data: bytes) -> None:
        """Append one CDR-serialised message received at ``timestamp_ns`` (recorder clock)."""
        self._writer.write(self._connections[topic], int(timestamp_ns), bytes(data))
        self.message_count += 1
        self._dirty = True
        self.maybe_flush()

    def maybe_flush(self) -> None:
        """Close and flush the pending chunk if ``flush_period`` has passed since the last one."""
        now = self._clock()
        if self._dirty and now - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        """Write the pending chunk (with its message index) and push it to the OS."""
        storage = self._writer.storage
        if storage is not None and storage.chunk.bio.tell():
            storage.close_chunk()
            storage.bio.flush()
        self._last_flush = self._clock()
        self._dirty = False

    def close(self) -> None:
        """Finish the MCAP summary and write metadata.yaml (ros_distro: jazzy, as rosbag2
        would; the rosbags library writes its own name there)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
            meta = self.path / 'metadata.yaml'
            text = meta.read_text()
            meta.write_text(text.replace('  ros_distro: rosbags\n', '  ros_distro: jazzy\n', 1))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
