"""Translate between rosbag2 ``offered_qos_profiles`` YAML and rclpy QoS profiles."""
import yaml
from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from paramotion import yamlfile


def _policy(enum, value, default):
    if isinstance(value, int):
        try:
            return enum(value)
        except ValueError:
            return default
    if isinstance(value, str):
        try:
            return enum[value.upper()]
        except KeyError:
            return default
    return default


def _time(value):
    if not isinstance(value, dict):
        return Duration()
    sec, nsec = int(value.get('sec', 0)), int(value.get('nsec', 0))
    if sec >= 0x7FFFFFFF:
        return Duration()  # rosbag2 writes "infinite" as max sec/nsec; rclpy's default is 0
    return Duration(seconds=sec, nanoseconds=nsec)


def profiles_from_yaml(text: str | None) -> list[QoSProfile]:
    """Parse an ``offered_qos_profiles`` string into rclpy ``QoSProfile`` objects."""
    try:
        items = yamlfile.safe_load(text) if text else []
    except yaml.YAMLError:
        return []
    profiles = []
    for item in items or []:
        if not isinstance(item, dict):
            continue
        history = _policy(HistoryPolicy, item.get('history'), HistoryPolicy.KEEP_LAST)
        if history not in (HistoryPolicy.KEEP_LAST, HistoryPolicy.KEEP_ALL):
            history = HistoryPolicy.KEEP_LAST  # graph introspection reports 'unknown'
        profiles.append(QoSProfile(
            history=history,
            depth=max(1, int(item.get('depth', 10) or 10)),
            reliability=_policy(ReliabilityPolicy, item.get('reliability'),
                                ReliabilityPolicy.RELIABLE),
            durability=_policy(DurabilityPolicy, item.get('durability'),
                               DurabilityPolicy.VOLATILE),
            deadline=_time(item.get('deadline')),
            lifespan=_time(item.get('lifespan')),
            liveliness=_policy(LivelinessPolicy, item.get('liveliness'),
                               LivelinessPolicy.AUTOMATIC),
            liveliness_lease_duration=_time(item.get('liveliness_lease_duration')),
        ))
    return profiles


def adapted_subscription_qos(profiles: list[QoSProfile], depth: int = 1000) -> QoSProfile:
    """The QoS a recorder or player should use to match all ``profiles`` (as rosbag2 does).

    Reliable only if every publisher offers reliable; transient-local only if every publisher
    offers it; otherwise the weaker policy, which matches everyone.
    """
    reliable = bool(profiles) and all(
        p.reliability == ReliabilityPolicy.RELIABLE for p in profiles)
    latched = bool(profiles) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                    else DurabilityPolicy.VOLATILE))
