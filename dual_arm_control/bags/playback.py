"""
The pure helpers of bag_play: topic selection, remapping, the playback window and schedule.

Nothing here touches ROS or the files of a bag: the options are checked and turned into the
topics to play, their published names, the log-time window [ns] and each message's wall-clock
offset, raising BagError with a one-line reason for a bad option.
"""

import re

from dual_arm_control.bags import BagError

NANOSECONDS_PER_SECOND = 1_000_000_000


def select_topics(available, names=(), regex=None, exclude=None):
    """
    Return the topics to play, sorted: all, or those named or matching regex, minus exclude.

    regex and exclude are regular expressions matched anywhere in the name (re.search), like
    bag_record's --regex. A name that is not in the bag raises BagError.
    """
    available = set(available)
    missing = sorted(set(names) - available)
    if missing:
        raise BagError(f'topic(s) {missing} not in the bag (it has {sorted(available)})')
    include = _compile(regex, '--regex')
    skip = _compile(exclude, '--exclude')
    if not names and include is None:
        chosen = available
    else:
        chosen = set(names) | {t for t in available if include and include.search(t)}
    return sorted(t for t in chosen if not (skip and skip.search(t)))


def _compile(pattern, option):
    """Compile an optional regular expression; raise BagError naming the option if invalid."""
    if pattern is None:
        return None
    try:
        return re.compile(pattern)
    except re.error as error:
        raise BagError(f'invalid {option} {pattern!r}: {error}') from error


def parse_remaps(rules):
    """Return {old topic: new topic} of '/old:=/new' rules; raise BagError for a bad rule."""
    remaps = {}
    for rule in rules:
        old, separator, new = rule.partition(':=')
        if not separator or not old.startswith('/') or not new.startswith('/') or \
                ':=' in new or any(c.isspace() for c in rule):
            raise BagError(f'invalid --remap {rule!r}: expected /old/topic:=/new/topic')
        if old in remaps:
            raise BagError(f'--remap: {old} is remapped twice')
        remaps[old] = new
    return remaps


def playback_window(start_ns, end_ns, start_offset=0.0, duration=None):
    """
    Return the log-time window [first, stop) [ns] to play of a bag spanning start_ns..end_ns.

    first = start_ns + start_offset; stop = first + duration, or just past end_ns without a
    duration. start_offset [s] must lie within the bag; duration [s] must be positive.
    """
    if start_offset < 0.0:
        raise BagError(f'--start-offset must be >= 0 s, got {start_offset}')
    if duration is not None and duration <= 0.0:
        raise BagError(f'--duration must be > 0 s, got {duration}')
    first = start_ns + int(round(start_offset * NANOSECONDS_PER_SECOND))
    if first > end_ns:
        raise BagError(f'--start-offset {start_offset} s is beyond the end of the bag '
                       f'({(end_ns - start_ns) / NANOSECONDS_PER_SECOND:.3f} s long)')
    if duration is None:
        return first, end_ns + 1
    return first, first + int(round(duration * NANOSECONDS_PER_SECOND))


def wall_offset(log_time_ns, window_start_ns, rate):
    """Return when [s after the start of playback] a message is due at a rate factor > 0."""
    return (log_time_ns - window_start_ns) / NANOSECONDS_PER_SECOND / rate
