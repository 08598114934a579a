"""
What bag_play plays: topic selection, remapping, the playback window and the schedule.

Nothing here touches ROS or reads messages: Playback checks bag_play's options against a
BagReader's topics and time span and turns them into the topics to play, their published
names, the log-time window [ns] and the number of passes; wall_offset schedules each message.
Problems raise BagError with a one-line reason.
"""

import re

from dual_arm_control.bags import BagError
from dual_arm_control.bags.schema import first_field_type, HEADER_TYPE

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


class Playback:
    """
    What to play and how, checked against the bag before any ROS entity exists.

    topics: bag topics to publish (--wait-for topics excluded); outputs: {bag topic: published
    name}; window: log-time [first, stop) [ns]; passes: None = until interrupted.
    """

    def __init__(self, reader, options):
        if reader.start_ns is None:
            raise BagError(f'{reader.path}: the bag holds no messages')
        self.wait_for = list(dict.fromkeys(options.wait_for))
        for topic in self.wait_for:
            if topic not in reader.topics:
                raise BagError(f'--wait-for {topic}: not in the bag (it has '
                               f'{sorted(reader.topics)})')
            if first_field_type(reader.topics[topic].type_name) != HEADER_TYPE:
                raise BagError(f'--wait-for {topic}: its type {reader.topics[topic].type_name} '
                               f'has no header stamp')
        selected = select_topics(reader.topics, options.topics, options.regex, options.exclude)
        self.topics = [t for t in selected if t not in self.wait_for]
        if not self.topics:
            raise BagError('no topic left to play after --topics/--regex/--exclude/--wait-for')
        remaps = parse_remaps(options.remap)
        unused = sorted(set(remaps) - set(reader.topics))
        if unused:
            raise BagError(f'--remap: {unused} not in the bag')
        self.outputs = {topic: remaps.get(topic, topic) for topic in self.topics}
        self.wait_names = {topic: remaps.get(topic, topic) for topic in self.wait_for}
        names = list(self.outputs.values()) + list(self.wait_names.values())
        clashes = sorted({name for name in names if names.count(name) > 1})
        if clashes:
            raise BagError(f'--remap: several topics would be published as {clashes}')
        self.window = playback_window(reader.start_ns, reader.end_ns, options.start_offset,
                                      options.duration)
        self.passes = options.loops if options.loops is not None else (
            None if options.loop else 1)
