"""Recover an MCAP file that was never closed (recorder SIGKILLed, disk full), as ``mcap recover``.

A recorder killed mid-run leaves its complete chunks on disk, but no summary, no footer and no
``metadata.yaml``; rosbags and Foxglove's reader refuse such a file (they need the footer). This
module copies every record that can still be read into a new, complete MCAP file:

- the data section is walked record by record (opcode, length, body); every complete record
  is parsed with the ``mcap`` library, a complete chunk yields all its schemas, channels and
  messages (CRC checked);
- the last, cut-off record, if it is an uncompressed chunk, still yields each of its inner
  records that lies wholly before the cut (the messages the recorder had flushed of it);
- the copy keeps the header's profile, the schemas, the channels with their metadata
  (``offered_qos_profiles``) and every message with its log and publish times and sequence
  number, in file order; it is written with chunks, message indexes, statistics and a summary
  by ``mcap.writer.Writer``, plus the ``rosbag2`` metadata record that rosbag2 writes.
"""
import io
import os
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Header, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from paramotion.bag.reader import TopicInfo

MAGIC = b'\x89MCAP0\r\n'
_OP_CHUNK = 0x06
_OP_DATA_END = 0x0F
_OP_FOOTER = 0x02


@dataclass
class Recovered:
    """What :func:`recover` found and wrote."""

    messages: int = 0
    chunks: int = 0                   # complete chunks read
    partial_messages: int = 0         # messages taken from the cut-off chunk
    lost_bytes: int = 0               # bytes of the source after its last whole record
    closed: bool = False              # the source already had its data end / footer
    start_ns: int = 0                 # first and last log time copied
    end_ns: int = 0
    topics: dict[str, TopicInfo] = field(default_factory=dict)   # type, count, QoS per topic


def _parse(record_bytes):
    """All records in ``record_bytes`` (one or more whole records; chunks are opened)."""
    out = []
    reader = StreamReader(io.BytesIO(record_bytes), skip_magic=True, validate_crcs=True)
    try:
        for record in reader.records:
            out.append(record)
    except (McapError, EOFError, ValueError, struct.error):
        pass    # end of the given bytes (or a damaged tail): keep what was parsed
    return out


def _profile(path):
    """The profile named by MCAP file ``path``'s header record ('ros2' for rosbag2 bags)."""
    with open(path, 'rb') as f:
        head = f.read(4096)
    if head[:len(MAGIC)] != MAGIC:
        raise ValueError(f'{path}: not an MCAP file (bad magic)')
    records = _whole_records(head[len(MAGIC):])
    parsed = _parse(records[0]) if records else []
    return parsed[0].profile if parsed and isinstance(parsed[0], Header) else 'ros2'


def _chunk_inner_prefix(body):
    """The inner records' bytes of a cut-off *uncompressed* chunk body, or b'' if unusable."""
    head = 8 + 8 + 8 + 4
    if len(body) < head + 4:
        return b''
    (n,) = struct.unpack_from('<I', body, head)
    pos = head + 4 + n
    compression = body[head + 4:pos]
    if compression != b'' or len(body) < pos + 8:
        return b''
    return body[pos + 8:]


def _whole_records(data):
    """Split ``data`` into its complete records (opcode, length, body); drop the cut-off rest."""
    pos, out = 0, []
    while pos + 9 <= len(data):
        (length,) = struct.unpack_from('<Q', data, pos + 1)
        end = pos + 9 + length
        if end > len(data):
            break
        out.append(data[pos:end])
        pos = end
    return out


def _read_source(path, sink):
    """Walk ``path``'s data section, calling ``sink(record)``; returns a :class:`Recovered`."""
    result = Recovered()
    size = Path(path).stat().st_size
    with open(path, 'rb') as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise ValueError(f'{path}: not an MCAP file (bad magic)')
        pos = len(MAGIC)
        while True:
            prefix = f.read(9)
            if len(prefix) < 9:
                break
            opcode = prefix[0]
            (length,) = struct.unpack('<Q', prefix[1:])
            body = f.read(min(length, size - pos - 9))    # a cut-off record ends at EOF
            if len(body) < length:
                if opcode == _OP_CHUNK:
                    for record_bytes in _whole_records(_chunk_inner_prefix(body)):
                        for record in _parse(record_bytes):
                            if isinstance(record, Message):
                                result.partial_messages += 1
                            sink(record)
                break
            if opcode in (_OP_DATA_END, _OP_FOOTER):
                result.closed = True
                pos = size
                break
            records = _parse(prefix + body)
            if opcode == _OP_CHUNK:
                if not records:
                    break   # a complete chunk that does not parse (CRC): stop here
                result.chunks += 1
            for record in records:
                sink(record)
            pos += 9 + length
        result.lost_bytes = 0 if result.closed else size - pos
    return result


def recover(src: str | os.PathLike[str], dst: str | os.PathLike[str],
            metadata: Callable[[Recovered], str] | None = None) -> Recovered:
    """Copy every readable record of MCAP file ``src`` into a new complete file ``dst``.

    ``metadata(result) -> str``, if given, returns the rosbag2 ``metadata.yaml`` text stored in
    the file's ``rosbag2`` metadata record (written after the messages, as rosbag2 does).
    Returns a :class:`Recovered`.
    """
    schemas, channels, new_schema, new_channel = {}, {}, {}, {}
    topics, span = {}, []
    with open(dst, 'xb') as out:
        writer = Writer(out, compression=CompressionType.NONE)
        writer.start(profile=_profile(src), library='paramotion bag reindex')

        def channel_id(channel):
            """The output id of source ``channel`` (registered with its schema on first use)."""
            if channel.id not in new_channel:
                schema, schema_id = schemas.get(channel.schema_id), 0
                if schema is not None:
                    if schema.id not in new_schema:
                        new_schema[schema.id] = writer.register_schema(
                            schema.name, schema.encoding, schema.data)
                    schema_id = new_schema[schema.id]
                new_channel[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schema_id, dict(channel.metadata))
                if channel.topic not in topics:
                    topics[channel.topic] = TopicInfo(
                        channel.topic, schema.name if schema is not None else '?',
                        offered_qos_profiles=channel.metadata.get('offered_qos_profiles', ''))
            return new_channel[channel.id]

        def sink(record):
            if isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                channels.setdefault(record.id, record)
            elif isinstance(record, Message) and record.channel_id in channels:
                channel = channels[record.channel_id]
                writer.add_message(channel_id(channel), record.log_time, record.data,
                                   record.publish_time, record.sequence)
                topics[channel.topic].count += 1
                t = record.log_time
                span[:] = [min(span[0], t), max(span[1], t)] if span else [t, t]
            # a message whose channel record was lost cannot be interpreted: dropped

        result = _read_source(src, sink)
        # A channel that carried no message is kept too (a topic subscribed but silent is
        # still part of the recording).
        for channel in channels.values():
            channel_id(channel)
        result.topics = topics
        result.messages = sum(t.count for t in topics.values())
        if span:
            result.start_ns, result.end_ns = span
        if metadata is not None:
            writer.add_metadata('rosbag2', {'serialized_metadata': metadata(result)})
        writer.finish()
    return result


def is_closed(path: str | os.PathLike[str]) -> bool:
    """True if MCAP file ``path`` ends with a footer and the closing magic."""
    size = Path(path).stat().st_size
    if size < 2 * len(MAGIC) + 29:
        return False
    with open(path, 'rb') as f:
        f.seek(size - len(MAGIC) - 29)
        tail = f.read()
    return tail[-len(MAGIC):] == MAGIC and tail[0] == _OP_FOOTER


__all__ = ['Recovered', 'is_closed', 'recover']
