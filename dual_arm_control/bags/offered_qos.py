"""
Replay QoS of bag topics: the rosbag2 'offered_qos_profiles' channel metadata read back.

parse_offered_qos_profiles reads the recorded publishers' profiles (policy names or the rmw
integers of older rosbag2, infinite durations in either encoding); qos_from_offered_profiles
picks the one publisher QoS that keeps every original subscriber compatible.
"""

from rclpy.duration import Duration
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)
import yaml

# Publisher QoS of a topic without (readable) offered_qos_profiles metadata.
DEFAULT_DEPTH = 100
DEFAULT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=DEFAULT_DEPTH,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
# rosbag2 writes an infinite QoS duration as INT64_MAX ns (recent) or as {2^31 - 1 s, 2^32 - 1
# ns} (older): any duration from 2^31 - 1 s on means 'infinite' (= rclpy's unspecified 0).
_INFINITE_SECONDS = 2**31 - 1
_POLICIES = {'history': HistoryPolicy, 'reliability': ReliabilityPolicy,
             'durability': DurabilityPolicy, 'liveliness': LivelinessPolicy}
_UNSET_POLICY_NAMES = ('SYSTEM_DEFAULT', 'UNKNOWN', 'BEST_AVAILABLE')


def _policy(kind, value):
    """Return the rclpy policy for a rosbag2 value (name or rmw integer); None if unset."""
    enum = _POLICIES[kind]
    try:
        policy = enum(value if isinstance(value, int)
                      else enum.get_from_short_key(str(value).strip().lower()))
    except (ValueError, KeyError, TypeError):
        return None
    return None if policy.name in _UNSET_POLICY_NAMES else policy


def _duration(value):
    """Return a rosbag2 '{sec, nsec}' mapping as a Duration; None for unset or infinite."""
    if not isinstance(value, dict):
        return None
    try:
        seconds, nanoseconds = int(value.get('sec', 0)), int(value.get('nsec', 0))
    except (TypeError, ValueError):
        return None
    if seconds >= _INFINITE_SECONDS or seconds < 0 or (seconds == 0 and nanoseconds == 0):
        return None
    return Duration(seconds=seconds, nanoseconds=nanoseconds)


def parse_offered_qos_profiles(text):
    """
    Return the QoSProfiles of rosbag2 'offered_qos_profiles' YAML (one per recorded publisher).

    Policies may be names ('reliable') or rmw integers (older rosbag2); unset, unknown and
    'best_available' policies take DEFAULT_QOS's value, infinite durations stay unspecified.
    Return [] for empty, unreadable or malformed text.
    """
    try:
        entries = yaml.safe_load(text) if text else None
    except yaml.YAMLError:
        return []
    if not isinstance(entries, list):
        return []
    profiles = []
    for entry in entries:
        if not isinstance(entry, dict):
            return []
        history = _policy('history', entry.get('history')) or DEFAULT_QOS.history
        try:
            depth = int(entry.get('depth', 0))
        except (TypeError, ValueError):
            depth = 0
        if history == HistoryPolicy.KEEP_LAST and depth <= 0:
            depth = DEFAULT_DEPTH
        profile = QoSProfile(
            history=history, depth=max(depth, 0),
            reliability=_policy('reliability', entry.get('reliability'))
            or DEFAULT_QOS.reliability,
            durability=_policy('durability', entry.get('durability'))
            or DEFAULT_QOS.durability,
            avoid_ros_namespace_conventions=bool(
                entry.get('avoid_ros_namespace_conventions', False)))
        liveliness = _policy('liveliness', entry.get('liveliness'))
        if liveliness is not None:
            profile.liveliness = liveliness
        for name in ('deadline', 'lifespan', 'liveliness_lease_duration'):
            duration = _duration(entry.get(name))
            if duration is not None:
                setattr(profile, name, duration)
        profiles.append(profile)
    return profiles


def qos_from_offered_profiles(text):
    """
    Return the one publisher QoS that replays a topic recorded with these offered profiles.

    One profile: that profile. Several publishers: reliable only if all were, transient local
    only if all were, keep-all if any was, else keep-last with the largest depth (rosbag2's
    rule: every original subscriber stays compatible). No readable profile: DEFAULT_QOS
    (reliable, volatile, keep-last 100).
    """
    profiles = parse_offered_qos_profiles(text)
    if not profiles:
        return QoSProfile(history=DEFAULT_QOS.history, depth=DEFAULT_QOS.depth,
                          reliability=DEFAULT_QOS.reliability,
                          durability=DEFAULT_QOS.durability)
    if len(profiles) == 1:
        return profiles[0]
    keep_all = any(p.history == HistoryPolicy.KEEP_ALL for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=max(p.depth for p in profiles) or DEFAULT_DEPTH,
        reliability=(ReliabilityPolicy.RELIABLE
                     if all(p.reliability == ReliabilityPolicy.RELIABLE for p in profiles)
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL
                    if all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles)
                    else DurabilityPolicy.VOLATILE))
