"""Read rosbag2 MCAP bags, including ones whose recorder was killed or whose file is damaged.

This reader is deliberately independent of the writer: it parses the MCAP file record by record
with the ``mcap`` library (not ``rosbags``), so a bag that was never closed (no summary, no
``metadata.yaml``) still yields every message of its complete chunks. What could not be read is
described in :attr:`BagInfo.problem` and, for strict readers, raised as :class:`BagReadError`, a
one-line message naming the file and how many messages were recovered.
"""
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Channel, DataEnd, Footer, Message, Schema
from mcap.stream_reader import StreamReader

from paramotion import yamlfile
from paramotion.errors import UserError


class BagReadError(UserError):
    """A bag that cannot be read completely (message names the file and what was recovered)."""


@dataclass
class TopicInfo:
    """One topic of a bag: type, number of messages read and offered QoS profiles (YAML)."""

    name: str
    msgtype: str
    count: int = 0
    offered_qos_profiles: str = ''


@dataclass
class BagMessage:
    """One recorded message: topic, type, receive time on the recorder's clock, CDR bytes."""

    topic: str
    msgtype: str
    log_time_ns: int
    data: bytes


@dataclass
class BagInfo:
    """What a scan of the bag found."""

    path: Path
    mcap_path: Path
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    message_count: int = 0
    start_ns: int = 0
    end_ns: int = 0
    has_metadata: bool = False
    closed: bool = False
    problem: str = ''

    @property
    def duration_s(self) -> float:
        """Time from the first to the last message (s)."""
        return max(0, self.end_ns - self.start_ns) * 1e-9

    @property
    def complete(self) -> bool:
        """Closed, with its ``metadata.yaml`` and nothing lost."""
        return self.closed and self.has_metadata and not self.problem


def find_mcap(path: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Return (bag directory, .mcap file) for a bag directory or an .mcap file path."""
    path = Path(path)
    if path.is_file() and path.suffix == '.mcap':
        return path.parent, path
    if not path.is_dir():
        raise BagReadError(f'bag {path}: no such bag directory')
    meta = path / 'metadata.yaml'
    if meta.is_file():
        try:
            doc = yamlfile.safe_load(meta.read_text())
            files = doc['rosbag2_bagfile_information']['relative_file_paths']
            if files:
                return path, path / files[0]
        except Exception as exc:
            raise BagReadError(f'bag {meta}: unreadable metadata.yaml ({exc})') from None
    files = sorted(path.glob('*.mcap'))
    if not files:
        raise BagReadError(f'bag {path}: no .mcap file in the directory')
    return path, files[0]


def _iter_records(mcap_path, info):
    """Yield MCAP records; on damage record the problem in ``info`` and stop cleanly."""
    size = os.path.getsize(mcap_path)
    with open(mcap_path, 'rb') as stream:
        reader = StreamReader(stream, validate_crcs=True, record_size_limit=size)
        try:
            for record in reader.records:
                yield record
                if isinstance(record, Footer):
                    info.closed = True
        except (McapError, ValueError, EOFError, OSError) as exc:
            kind = type(exc).__name__
            info.problem = (f'{mcap_path}: damaged or truncated at byte {stream.tell()} of {size} '
                            f'({kind}); recovered {info.message_count} messages')


def scan(path: str | os.PathLike[str], topics: set[str] | None = None,
         want_messages: bool = False) -> tuple[BagInfo, list[BagMessage] | None]:
    """Scan a bag; returns ``(info, messages)`` where messages is a list if requested."""
    bag_dir, mcap_path = find_mcap(path)
    info = BagInfo(path=bag_dir, mcap_path=mcap_path,
                   has_metadata=(bag_dir / 'metadata.yaml').is_file())
    schemas, channels = {}, {}
    messages = [] if want_messages else None
    for record in _iter_records(mcap_path, info):
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            if record.id in channels:
                continue
            schema = schemas.get(record.schema_id)
            msgtype = schema.name if schema is not None else '?'
            channels[record.id] = (record.topic, msgtype)
            if record.topic not in info.topics:
                info.topics[record.topic] = TopicInfo(
                    record.topic, msgtype,
                    offered_qos_profiles=record.metadata.get('offered_qos_profiles', ''))
        elif isinstance(record, Message):
            topic, msgtype = channels.get(record.channel_id, (None, None))
            if topic is None:
                continue
            info.topics[topic].count += 1
            info.message_count += 1
            if info.message_count == 1 or record.log_time < info.start_ns:
                info.start_ns = record.log_time
            info.end_ns = max(info.end_ns, record.log_time)
            if messages is not None and (topics is None or topic in topics):
                messages.append(BagMessage(topic, msgtype, record.log_time, record.data))
        elif isinstance(record, DataEnd):
            pass
    if not info.problem and not info.closed:
        info.problem = (f'{mcap_path}: file ends without an MCAP footer (recorder did not close '
                        f'it); recovered {info.message_count} messages')
    return info, messages


def bag_info(path: str | os.PathLike[str]) -> BagInfo:
    """Scan a bag and return its :class:`BagInfo` (never raises for damage; see ``problem``)."""
    return scan(path)[0]


def read_messages(path: str | os.PathLike[str], topics: Iterable[str] | None = None,
                  strict: bool = False) -> list[BagMessage]:
    """Return the list of :class:`BagMessage` of ``topics`` (all if None) in file order.

    With ``strict`` a damaged/unfinished bag raises :class:`BagReadError`; otherwise the messages
    of every complete chunk are returned and the problem is available via :func:`bag_info`.
    """
    info, messages = scan(path, topics=set(topics) if topics else None, want_messages=True)
    if strict and info.problem:
        raise BagReadError(f'bag {info.problem}')
    return messages


def deserialize(message: BagMessage) -> Any:
    """Turn a :class:`BagMessage` into an rclpy message object (imports rclpy lazily)."""
    from rclpy.serialization import deserialize_message

    from paramotion.msgtypes import message_class
    return deserialize_message(message.data, message_class(message.msgtype))
