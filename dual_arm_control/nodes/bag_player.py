"""
BagPlayer: the ROS node of bag_play, publishing a bag's messages timed or in lockstep.

Timed: each message goes out at its recorded log time after the start of the pass, scaled by
--rate; with --clock the player publishes /clock from the log time on its way. Lockstep:
messages go out in recorded order, grouped by stamp; after a group stamped t that the node
under test answered in the recording, the player waits for the node's outputs stamped t on the
--wait-for topics. Messages are published as recorded (serialized CDR), each topic with the QoS
its publishers offered; PlaybackStats counts what was played and waited.
"""

from collections import deque
import sys
import time

from dual_arm_control import contract
from dual_arm_control.bags import BagError
from dual_arm_control.bags.playback import wall_offset
from dual_arm_control.bags.schema import first_field_type, HEADER_TYPE
from dual_arm_control.bags.writer import header_stamp_ns
from dual_arm_control.nodes.bag_record import message_class
from dual_arm_control.nodes.messages import time_msg
import rclpy
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

# Wall time the publishers get to deliver their last messages before the process exits [s].
FINAL_ACK_TIMEOUT = 1.0
# Lockstep without waits: handle signals (and other events) every this many messages.
SPIN_EVERY = 100
STAMP_TYPE = 'builtin_interfaces/msg/Time'
# Lockstep: recorded messages searched for late ones of a group before its wait.
LOOKAHEAD = 32
# Lockstep: give up after this many barriers in a row timed out (the node stopped answering).
MAX_CONSECUTIVE_TIMEOUTS = 3
# A --wait-for subscription keeps this many unprocessed outputs.
WAIT_FOR_DEPTH = 1000


def stamped_type(type_name):
    """Return True if a message type starts with a stamp (std_msgs/Header, or a Time: Clock)."""
    try:
        return first_field_type(type_name) in (HEADER_TYPE, STAMP_TYPE)
    except BagError:
        return False


class BagClock:
    """
    The /clock of a timed pass (--clock): bag log time at a wall-clock tick rate.

    Ticks fall every 1 / hz wall seconds from the start of the pass; a tick carries the bag time
    the pass has reached then (window start + wall time x rate), at most last_ns. Ticks missed
    while the player was busy are dropped, not sent in a burst.
    """

    def __init__(self, start, first_ns, last_ns, rate, hz):
        self._start = start
        self._first_ns = first_ns
        self._last_ns = last_ns
        self._rate = rate
        self._period = 1.0 / hz
        self.next_tick = start

    def take(self, now):
        """Return the bag time [ns] of the last tick due at wall time now; schedule the next."""
        tick = self.next_tick + max(int((now - self.next_tick) / self._period), 0) * self._period
        self.next_tick = tick + self._period
        return min(self._first_ns + int(round((tick - self._start) * self._rate * 1e9)),
                   self._last_ns)


class PlaybackStats:
    """Counts of one run: messages per published topic, passes, barriers, waits, timeouts."""

    def __init__(self):
        self.counts = {}
        self.passes = 0
        self.barriers = 0
        self.waits = 0
        self.timeouts = []
        self.started = None
        self.finished = None
        self.interrupted = False
        self.node_lost = False
        self.consecutive_timeouts = 0

    def line(self):
        """Return the one-line summary printed at the end."""
        wall = (self.finished - self.started) if self.started is not None else 0.0
        counts = ', '.join(f'{topic}: {count}' for topic, count in sorted(self.counts.items()))
        text = (f'bag_play: {"interrupted after " if self.interrupted else ""}{self.passes} '
                f'pass{"es" if self.passes != 1 else ""}, {sum(self.counts.values())} messages '
                f'in {wall:.2f} s wall ({counts or "none"})')
        if self.barriers:
            text += (f'; lockstep: {self.barriers} barriers, {self.waits} waits, '
                     f'{len(self.timeouts)} timeouts')
            if self.timeouts:
                text += f' (first at stamp {self.timeouts[0] * 1e-9:.9f} s)'
        if self.node_lost:
            text += '; the node under test went away or stopped answering'
        return text


class BagPlayer(Node):
    """Publishers for the played topics and, in lockstep, subscriptions to the waited outputs."""

    def __init__(self, reader, playback, options, stop):
        super().__init__('bag_play')
        self._stop = stop
        self._reader = reader
        self._playback = playback
        self._options = options
        self._outputs = {}
        self._clock_pub = None
        if options.clock is not None:
            self._clock_pub = self.create_publisher(contract.CLOCK.msg_type, contract.CLOCK.name,
                                                    contract.CLOCK.publisher_qos)
        self._stamped = {topic: stamped_type(reader.topics[topic].type_name)
                         for topic in playback.topics + playback.wait_for}
        for topic in playback.topics:
            if self._clock_pub is not None and playback.outputs[topic] == contract.CLOCK.name:
                continue
            info = reader.topics[topic]
            try:
                msg_type = message_class(info.type_name)
            except BagError as error:
                print(f'bag_play: not playing {topic}: {error}', file=sys.stderr)
                continue
            self._outputs[topic] = self.create_publisher(
                msg_type, playback.outputs[topic], info.qos)
        self._received = {topic: set() for topic in playback.wait_for}
        self._answered = None
        self._waited = {}
        for topic in playback.wait_for:
            info = reader.topics[topic]
            qos = info.qos
            self._waited[topic] = self.create_subscription(
                message_class(info.type_name), playback.wait_names[topic],
                lambda data, topic=topic: self._on_output(topic, data),
                QoSProfile(depth=WAIT_FOR_DEPTH, reliability=qos.reliability,
                           durability=qos.durability), raw=True)
        self._executor = EventsExecutor(context=self.context)
        self._executor.add_node(self)
        self.stats = PlaybackStats()

    def running(self):
        """Return True while playback may go on (no stop request, rclpy up)."""
        return not self._stop.requested and rclpy.ok(context=self.context)

    def close(self):
        """Leave the executor and destroy the node."""
        self._executor.remove_node(self)
        self.destroy_node()

    def _on_output(self, topic, data):
        """Note the stamp of a serialized output of the node under test on a --wait-for topic."""
        stamp = header_stamp_ns(data)
        if stamp is not None:
            self._received[topic].add(stamp)

    def spin_until(self, deadline, condition=lambda: False):
        """Handle events until condition() or the monotonic deadline; return condition()."""
        while self.running() and not condition():
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                break
            self._executor.spin_once(timeout_sec=min(remaining, 0.1))
        return condition()

    def wait_for_graph(self):
        """
        Wait until every publisher has a subscriber and every waited output a publisher.

        Then let --settle pass. Return the topics still unmatched after --startup-timeout.
        """
        def unmatched():
            topics = [self._playback.outputs[t] for t, p in self._outputs.items()
                      if p.get_subscription_count() == 0]
            if self._clock_pub is not None and self._clock_pub.get_subscription_count() == 0:
                topics.append(contract.CLOCK.name)
            return topics + [self._playback.wait_names[t] for t, s in self._waited.items()
                             if s.get_publisher_count() == 0]

        deadline = time.monotonic() + self._options.startup_timeout
        self.spin_until(deadline, lambda: not unmatched())
        self.spin_until(time.monotonic() + self._options.settle)
        return unmatched()

    def play(self):
        """Play the window once per pass; return the stats."""
        stats = self.stats
        stats.started = time.monotonic()
        while (self._playback.passes is None or stats.passes < self._playback.passes) and \
                self.running() and not stats.node_lost:
            for received in self._received.values():
                received.clear()
            if self._options.lockstep:
                self._play_lockstep()
            else:
                self._play_timed()
            if not self.running() or stats.node_lost:
                break
            stats.passes += 1
        stats.finished = time.monotonic()
        stats.interrupted = not self.running()
        if stats.interrupted:
            return stats
        deadline = time.monotonic() + FINAL_ACK_TIMEOUT
        for publisher in self._outputs.values():
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                break
            publisher.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9)))
        return stats

    def _publish(self, message):
        """Publish one BagMessage's CDR bytes on its output topic and count it."""
        self._outputs[message.topic].publish(message.data)
        output = self._playback.outputs[message.topic]
        self.stats.counts[output] = self.stats.counts.get(output, 0) + 1

    def _play_timed(self):
        """Publish each message at its recorded time after the start of the pass (/ rate)."""
        first, stop = self._playback.window
        start = time.monotonic()
        clock = None if self._clock_pub is None else BagClock(
            start, first, min(stop - 1, self._reader.end_ns), self._options.rate,
            self._options.clock)
        for message in self._reader.messages(list(self._outputs), first, stop):
            due = start + wall_offset(message.log_time, first, self._options.rate)
            while clock is not None and clock.next_tick < due and self.running():
                self.spin_until(clock.next_tick)
                self._publish_clock(clock.take(time.monotonic()))
            self.spin_until(due)
            if not self.running():
                return
            self._publish(message)

    def _publish_clock(self, stamp_ns):
        """Publish /clock at a bag time [ns] and count it."""
        if not self.running():
            return
        self._clock_pub.publish(contract.CLOCK.msg_type(clock=time_msg(stamp_ns)))
        self.stats.counts[contract.CLOCK.name] = self.stats.counts.get(contract.CLOCK.name, 0) + 1

    def _play_lockstep(self):
        """
        Publish in recorded order, group by group of equal stamps; await the node at the end.

        A group stamped t ends where the next stamped message has another stamp. If the node
        answered t in the recording, the messages stamped t among the next LOOKAHEAD recorded
        ones go out first (the recorder may log one of a cycle's inputs after the node's answer
        or the next cycle's first message), then bag_play waits for the node's answers to t.
        """
        first, stop = self._playback.window
        if self._answered is None:
            self._answered = {topic: {header_stamp_ns(m.data) for m in self._reader.messages(
                [topic], first, stop)} for topic in self._playback.wait_for}
            self._warn_late_answers()
        source = self._reader.messages(list(self._outputs), first, stop)
        lookahead = deque()
        passed = set()
        group = None
        count = 0
        while self.running() and not self.stats.node_lost:
            message = lookahead.popleft() if lookahead else next(source, None)
            if message is None:
                break
            stamp = self._stamp(message)
            if stamp is not None and stamp != group:
                self._end_group(group, lookahead, source, passed)
                group = stamp
            count += 1
            if count % SPIN_EVERY == 0:
                self._executor.spin_once(timeout_sec=0.0)
            if self.running() and not self.stats.node_lost:
                self._publish(message)
        self._end_group(group, lookahead, source, passed)

    def _warn_late_answers(self):
        """Warn if a --wait-for topic was recorded only after the first played stamp."""
        first, stop = self._playback.window
        stamps = (self._stamp(m) for m in self._reader.messages(list(self._outputs), first, stop))
        first_input = next((stamp for stamp in stamps if stamp is not None), None)
        for topic, answered in self._answered.items():
            if first_input is not None and (not answered or min(answered) > first_input):
                since = f'from {min(answered) * 1e-9:.3f} s on' if answered else 'not at all'
                print(f'bag_play: warning: the bag has {topic} {since}: the inputs before are '
                      'played without waiting for the node (a latched output such as '
                      '/dual_arm/phase is recorded completely)', file=sys.stderr, flush=True)

    def _stamp(self, message):
        """Return a message's stamp [ns] (header or /clock time), None for unstamped types."""
        return header_stamp_ns(message.data) if self._stamped[message.topic] else None

    def _end_group(self, stamp, lookahead, source, passed):
        """Publish late messages stamped `stamp`, then await the node's answers to it."""
        topics = [topic for topic, stamps in self._answered.items() if stamp in stamps]
        if stamp is None or stamp in passed or not topics or not self.running():
            return
        passed.add(stamp)
        while len(lookahead) < LOOKAHEAD:
            message = next(source, None)
            if message is None:
                break
            lookahead.append(message)
        for message in [m for m in lookahead if self._stamp(m) == stamp]:
            lookahead.remove(message)
            self._publish(message)
        for topic in topics:
            self.stats.barriers += 1
            received = self._received[topic]
            if stamp in received:
                self.stats.consecutive_timeouts = 0
                continue
            self.stats.waits += 1
            deadline = time.monotonic() + self._options.wait_timeout
            if self.spin_until(deadline, lambda: stamp in received) or not self.running():
                self.stats.consecutive_timeouts = 0
                continue
            self.stats.timeouts.append(stamp)
            self.stats.consecutive_timeouts += 1
            if (self._waited[topic].get_publisher_count() == 0
                    or self.stats.consecutive_timeouts >= MAX_CONSECUTIVE_TIMEOUTS):
                self.stats.node_lost = True
                return
            print(f'bag_play: no {self._playback.wait_names[topic]} stamped '
                  f'{stamp * 1e-9:.9f} s within {self._options.wait_timeout:g} s; going on',
                  file=sys.stderr, flush=True)
