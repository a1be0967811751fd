"""``paramotion bag record|play|info|reindex``: the bag tools without the ros2 CLI."""
import argparse
import faulthandler
import os
import sys
import time

import yaml

from paramotion import yamlfile
from paramotion.bag.reader import BagInfo, TopicInfo, bag_info
from paramotion.errors import UserError


def _linger(node, seconds):
    """Keep ``node``'s publishers alive ``seconds`` of wall time before they are destroyed.

    A reader that has not yet taken the last samples loses them when the writer disappears
    (the DDS reader drops a gone writer's unread samples), so a player that exits right after
    its last publish can lose its tail on a loaded machine. Reliable publishers wait for their
    acknowledgements; best-effort ones just get the time.
    """
    from rclpy.duration import Duration
    end = time.monotonic() + seconds
    for pub in node.publishers:
        left = end - time.monotonic()
        if left <= 0:
            break
        pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
    time.sleep(max(0.0, end - time.monotonic()))


def _spin_node(node_cls, params, until=None, duration=None, linger=0.0):
    """Run one node in this process until Ctrl-C or SIGTERM, ``until()`` or ``duration`` wall
    seconds.

    When it stops by ``until()``, its publishers linger ``linger`` wall seconds first. Further
    SIGINT/SIGTERM while it stops are absorbed: the recorder's bag is always finished
    (:mod:`paramotion.shutdown`). ``kill -USR1`` prints where every thread is.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from paramotion.node import overrides_from_dict
    from paramotion.shutdown import ShutdownSignals
    signals = ShutdownSignals().install()
    context = rclpy.Context()
    rclpy.init(context=context)
    node = None
    executor = SingleThreadedExecutor(context=context)
    try:
        node = node_cls(context=context, parameter_overrides=overrides_from_dict(params))
        executor.add_node(node)
        signals.spinning()
        end = None if duration is None else time.monotonic() + duration
        while context.ok() and not signals.requested:
            if until is not None and until(node):
                _linger(node, linger)
                break
            if end is not None and time.monotonic() >= end:
                break
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        # A teardown still running after 20 s prints every thread's stack to stderr (it goes
        # on; the bag itself is closed by destroy_node).
        faulthandler.dump_traceback_later(20.0)
        try:
            executor.shutdown()
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown(context=context)
        finally:
            faulthandler.cancel_dump_traceback_later()
            signals.finish()
    return node


def _record(args):
    from paramotion.bag.recorder_node import BagRecorderNode
    params = {'output': args.output, 'topics': args.topics or [''],
              'use_sim_time': args.use_sim_time, 'flush_period': args.flush_period}
    node = _spin_node(BagRecorderNode, params, duration=args.duration)
    print(f'recorded {node.writer.message_count} messages to {args.output}')
    return 0


def _play(args):
    from paramotion.bag.player_node import BagPlayerNode
    if not args.linger >= 0:
        raise UserError(f'--linger: must be >= 0 wall seconds, got {args.linger}')
    params = {'bag': args.bag, 'topics': args.topics or [''], 'remap': args.remap or [''],
              'real_time_factor': args.rate, 'publish_period': args.clock_period,
              'wait_for_clock_subscribers': args.wait_for_subscribers,
              'wait_for_matched': args.wait_for_matched or ['']}
    node = _spin_node(BagPlayerNode, params, until=lambda n: n.finished, linger=args.linger)
    print(f'played {node.published} messages from {args.bag}')
    return 0


def format_info(info: BagInfo) -> str:
    """Text like ``ros2 bag info``."""
    lines = [f'Files:             {info.mcap_path}',
             f'Bag size:          {info.mcap_path.stat().st_size} B',
             'Storage id:        mcap',
             f'Duration:          {info.duration_s:.3f}s',
             f'Start:             {info.start_ns * 1e-9:.3f}s',
             f'End:               {info.end_ns * 1e-9:.3f}s',
             f'Messages:          {info.message_count}',
             'Topic information:']
    for name in sorted(info.topics):
        t = info.topics[name]
        lines.append(f'  Topic: {name} | Type: {t.msgtype} | Count: {t.count} | '
                     'Serialization Format: cdr')
    return '\n'.join(lines)


def _info(args):
    info = bag_info(args.bag)
    print(format_info(info))
    if info.problem:
        print(f'paramotion bag info: error: {info.problem}', file=sys.stderr)
        return 1
    if not info.has_metadata:
        print(f'paramotion bag info: warning: {info.path}/metadata.yaml missing '
              '(run paramotion bag reindex)', file=sys.stderr)
        return 1
    return 0


def metadata_yaml(topics: dict[str, TopicInfo], message_count: int, start_ns: int, end_ns: int,
                  file_name: str) -> str:
    """rosbag2 ``metadata.yaml`` text (version 9, one MCAP file) for ``topics`` (TopicInfo)."""
    from paramotion.bag.writer import typestore
    store = typestore()
    entries = []
    for name in sorted(topics):
        t = topics[name]
        try:
            rihs = store.hash_rihs01(t.msgtype)
        except Exception:
            rihs = ''
        entries.append({'topic_metadata': {
            'name': name, 'type': t.msgtype, 'serialization_format': 'cdr',
            'offered_qos_profiles': yamlfile.safe_load(t.offered_qos_profiles or '[]') or [],
            'type_description_hash': rihs}, 'message_count': t.count})
    duration = max(0, end_ns - start_ns)
    doc = {'rosbag2_bagfile_information': {
        'version': 9, 'storage_identifier': 'mcap',
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start_ns},
        'message_count': message_count, 'topics_with_message_count': entries,
        'compression_format': '', 'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [{'path': file_name,
                   'starting_time': {'nanoseconds_since_epoch': start_ns},
                   'duration': {'nanoseconds': duration},
                   'message_count': message_count}],
        'custom_data': {}, 'ros_distro': 'jazzy'}}
    return yaml.safe_dump(doc, sort_keys=False)


def reindex(bag: str | os.PathLike[str]) -> BagInfo:
    """Make a bag whose recorder was killed complete again (``ros2 bag reindex`` plus ``mcap
    recover``); returns the :class:`~paramotion.bag.reader.BagInfo` of the result.

    An .mcap file without its footer is rewritten with every message that can still be read
    (every complete chunk, and the whole messages of a cut-off uncompressed one) and a full
    summary, so rosbags and Foxglove's readers open it; the original is kept beside it as
    ``<name>.mcap.truncated``. Then ``metadata.yaml`` is written from what the file holds.
    """
    from paramotion.bag.reader import find_mcap
    from paramotion.bag.recover import is_closed, recover
    bag_dir, mcap_path = find_mcap(bag)
    if not is_closed(mcap_path):
        fresh = mcap_path.with_name(mcap_path.name + '.recovering')
        fresh.unlink(missing_ok=True)
        try:
            recover(mcap_path, fresh, metadata=lambda r: metadata_yaml(
                r.topics, r.messages, r.start_ns, r.end_ns, mcap_path.name))
        except BaseException:
            fresh.unlink(missing_ok=True)
            raise
        mcap_path.replace(mcap_path.with_name(mcap_path.name + '.truncated'))
        fresh.replace(mcap_path)
    info = bag_info(mcap_path)
    (bag_dir / 'metadata.yaml').write_text(metadata_yaml(
        info.topics, info.message_count, info.start_ns, info.end_ns, mcap_path.name))
    info.has_metadata = True
    return info


def _reindex(args):
    info = reindex(args.bag)
    print(f'wrote {info.path / "metadata.yaml"}: {info.message_count} messages in '
          f'{len(info.topics)} topics')
    if info.problem:
        print(f'paramotion bag reindex: warning: {info.problem}', file=sys.stderr)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``paramotion bag`` and its subcommands."""
    parser = subparsers.add_parser('bag', help='record, play and inspect rosbag2 MCAP bags',
                                   description='Record, play and inspect rosbag2 MCAP bags.')
    sub = parser.add_subparsers(dest='bag_command', metavar='SUBCOMMAND')
    sub.required = True

    rec = sub.add_parser('record', help='record topics to a new bag',
                         description='Record topics (all if none given) until Ctrl-C.')
    rec.add_argument('topics', nargs='*', help='topics to record (default: all)')
    rec.add_argument('-o', '--output', required=True, help='bag directory to create')
    rec.add_argument('--duration', type=float, default=None, help='stop after S wall seconds')
    rec.add_argument('--use-sim-time', action='store_true',
                     help='stamp messages with /clock time (default: system time)')
    rec.add_argument('--flush-period', type=float, default=1.0,
                     help='wall seconds between chunk flushes (default 1)')
    rec.set_defaults(func=_record)

    play = sub.add_parser('play', help='replay a bag, publishing /clock from it',
                          description='Replay a bag on sim time: /clock follows the bag.')
    play.add_argument('bag', help='bag directory')
    play.add_argument('--topics', nargs='*', help='topics to play (default: all)')
    play.add_argument('--remap', nargs='*', help="topic remappings 'from:=to'")
    play.add_argument('--rate', type=float, default=1.0, help='playback rate (0 = max)')
    play.add_argument('--clock-period', type=float, default=0.01,
                      help='sim seconds per /clock tick (default 0.01)')
    play.add_argument('--wait-for-subscribers', type=int, default=0,
                      help='hold time until this many /clock subscribers are present')
    play.add_argument('--wait-for-matched', nargs='*', metavar='TOPIC:N',
                      help='hold time until these played topics have N matched subscribers')
    play.add_argument('--linger', type=float, default=0.5,
                      help='wall seconds to keep publishers up after the last message, so '
                           'slow subscribers still take it (default 0.5)')
    play.set_defaults(func=_play)

    info = sub.add_parser('info', help='summarise a bag (recovers damaged ones)',
                          description='Print topics, counts and duration of a bag.')
    info.add_argument('bag', help='bag directory or .mcap file')
    info.set_defaults(func=_info)

    rei = sub.add_parser('reindex', help='complete a bag whose recorder was killed',
                         description='Recover every readable message of an unclosed .mcap '
                         'file into a complete one (the original is kept as '
                         '<name>.mcap.truncated) and rebuild metadata.yaml from it.')
    rei.add_argument('bag', help='bag directory')
    rei.set_defaults(func=_reindex)
    return parser
