"""
bag_play: publish the topics of an MCAP bag again, with their recorded timing or in lockstep.

Timed (default): each message goes out at its recorded log time after the start, scaled by
--rate; the bag's /clock (recorded from the sim bridge) is republished with the rest, so nodes
with use_sim_time follow the recorded sim time. Lockstep (--lockstep): the messages go out in
recorded order as fast as the node under test allows. Each --wait-for topic is an output of
that node recorded in the bag (header-stamped, not published); its recorded stamps are the
input stamps the node answers. Messages are grouped by stamp (header stamp, /clock's time):
where a group stamped t ends and the node answered t in the recording, bag_play first sends
the messages stamped t among the next few recorded ones (the recorder may log one of a cycle's
inputs late), then waits until the node has published a message stamped t on every --wait-for
topic (or --wait-timeout passed: counted and reported). Messages are published as recorded
(serialized CDR), never deserialized, each topic with the QoS its publishers offered when
recorded (reliable, volatile, keep-last 100 if unknown). Input: an .mcap file (with its split
files <stem>_N.mcap) or a rosbag2 folder.
"""

import argparse
from collections import deque
import sys
import time

from dual_arm_control.bags import BagError
from dual_arm_control.bags.playback import (parse_remaps, playback_window, select_topics,
                                            wall_offset)
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.bags.schema import first_field_type, HEADER_TYPE
from dual_arm_control.bags.writer import header_stamp_ns
from dual_arm_control.nodes.bag_record import message_class
from dual_arm_control.nodes.process import StopRequest
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions

EXAMPLES = """\
examples:
  # replay a recorded run at its recorded pace (/clock included)
  bag_play runs/latest/bag.mcap
  # twice as fast, only the arm states, from 0.5 s into the bag for 1 s
  bag_play bag.mcap --rate 2 --regex 'joint_states$' --start-offset 0.5 --duration 1
  # everything but ground truth, the left arm's state under another name, 3 passes
  bag_play bag.mcap --exclude '^/.*ground_truth' --remap /left/joint_states:=/test/js \\
      --loops 3
  # exact reproduction: feed the motion generator's recorded inputs to a fresh
  # ds_motion_generator (same parameters as the recorded run, lockstep:=true) tick by
  # tick; the phase is latched, so the bag has all of it even if the recorder started late
  bag_play bag.mcap --lockstep --topics /clock /object/state /left/joint_states \\
      /right/joint_states /left/ft_wrench /right/ft_wrench --wait-for /dual_arm/phase

exit codes: 0 played; 1 a lockstep wait timed out or the node under test went away;
2 bad input (file, damaged bag without --recover, unknown topic, bad option value).
"""
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


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are BagErrors (one line, exit 2), not usage dumps."""

    def error(self, message):
        raise BagError(message)


def parse_arguments(argv):
    """Parse bag_play's own arguments (see split_arguments); raise BagError if invalid."""
    parser = _Parser(prog='bag_play', description=__doc__.split('\n')[1],
                     epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', help='.mcap file (split files <stem>_N.mcap follow) or rosbag2 '
                        'folder with metadata.yaml')
    parser.add_argument('--topics', nargs='+', default=[], metavar='TOPIC',
                        help='play these topics (default: all, or those matching --regex)')
    parser.add_argument('-e', '--regex', help='play the topics matching this expression')
    parser.add_argument('-x', '--exclude', metavar='REGEX',
                        help='do not play the topics matching this expression')
    parser.add_argument('--remap', action='append', default=[], metavar='/OLD:=/NEW',
                        help='publish bag topic /OLD as /NEW (repeatable)')
    parser.add_argument('-r', '--rate', type=float, default=1.0,
                        help='timed mode: playback speed factor (2 = twice as fast)')
    parser.add_argument('--start-offset', type=float, default=0.0, metavar='SECONDS',
                        help='start this far after the first message of the bag [s]')
    parser.add_argument('--duration', type=float, metavar='SECONDS',
                        help='play this much of the bag (log time) per pass [s]')
    parser.add_argument('-l', '--loop', action='store_true',
                        help='play the window again and again until interrupted')
    parser.add_argument('--loops', type=int, metavar='N',
                        help='play the window N times (implies --loop)')
    parser.add_argument('--lockstep', action='store_true',
                        help='recorded order, as fast as the node under test allows')
    parser.add_argument('--wait-for', action='append', default=[], metavar='TOPIC',
                        help='lockstep: header-stamped output topic of the node under test, '
                             'recorded in the bag: after the inputs stamped t, wait for its '
                             'answer stamped t if it answered t in the recording (repeatable)')
    parser.add_argument('--wait-timeout', type=float, default=10.0, metavar='SECONDS',
                        help='lockstep: wall time to wait at one barrier [s]')
    parser.add_argument('--wait-for-subscribers', action='store_true',
                        help='first wait until every topic has a subscriber (always in '
                             'lockstep)')
    parser.add_argument('--startup-timeout', type=float, default=30.0, metavar='SECONDS',
                        help='wall time to wait for subscribers and --wait-for publishers [s]')
    parser.add_argument('--settle', type=float, default=1.0, metavar='SECONDS',
                        help='wall time between matching and the first message, so both '
                             'sides of every match know each other [s]')
    parser.add_argument('--recover', action='store_true',
                        help='play the recoverable messages of a torn, truncated or corrupt '
                             'bag (refused without this flag)')
    options = parser.parse_args(argv)
    for name in ('rate', 'wait_timeout', 'startup_timeout'):
        if not getattr(options, name) > 0.0:
            raise BagError(f'--{name.replace("_", "-")} must be > 0, got '
                           f'{getattr(options, name)}')
    if options.settle < 0.0:
        raise BagError(f'--settle must be >= 0, got {options.settle}')
    if options.loops is not None and options.loops < 1:
        raise BagError(f'--loops must be >= 1, got {options.loops}')
    if options.wait_for and not options.lockstep:
        raise BagError('--wait-for needs --lockstep')
    return options


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
        self._stamped = {topic: stamped_type(reader.topics[topic].type_name)
                         for topic in playback.topics + playback.wait_for}
        for topic in playback.topics:
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
        self._outputs[message.topic].publish(message.data)
        output = self._playback.outputs[message.topic]
        self.stats.counts[output] = self.stats.counts.get(output, 0) + 1

    def _play_timed(self):
        """Publish each message at its recorded time after the start of the pass (/ rate)."""
        first, stop = self._playback.window
        start = time.monotonic()
        for message in self._reader.messages(list(self._outputs), first, stop):
            due = start + wall_offset(message.log_time, first, self._options.rate)
            self.spin_until(due)
            if not self.running():
                return
            self._publish(message)

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


def split_arguments(argv):
    """
    Return (bag_play's arguments, the ROS arguments) of a command line (argv[0] excluded).

    The ROS arguments are those between `--ros-args` and `--` (or the end). rclpy's own
    remove_ros_args is not used: it takes '/old:=/new' for a deprecated ROS remap rule even
    after --remap.
    """
    own, ros, in_ros = [], [], False
    for argument in argv[1:]:
        if argument == '--ros-args':
            in_ros = True
            ros.append(argument)
        elif in_ros and argument == '--':
            in_ros = False
        else:
            (ros if in_ros else own).append(argument)
    return own, ros


def main(argv=None):
    """Play a bag; return the exit code (0 played, 1 lockstep trouble, 2 bad input)."""
    argv = sys.argv if argv is None else argv
    own_arguments, ros_arguments = split_arguments(argv)
    try:
        options = parse_arguments(own_arguments)
        reader = BagReader(options.bag, recover=options.recover)
        playback = Playback(reader, options)
    except SystemExit as exit_request:
        return exit_request.code
    except BagError as error:
        print(f'bag_play: {error}', file=sys.stderr)
        return 2
    for summary in reader.damaged:
        print(f'bag_play: warning: {summary.path} is {summary.status} ({summary.problem}); '
              f'playing its {summary.message_count} recoverable messages', file=sys.stderr)
    # SIGINT/SIGTERM only set a flag, so playback stops between two messages (and still prints
    # its summary) instead of rclpy shutting the context down under a publish call.
    rclpy.init(args=argv[:1] + ros_arguments, signal_handler_options=SignalHandlerOptions.NO)
    player = None
    stop = StopRequest()
    try:
        player = BagPlayer(reader, playback, options, stop)
        if options.lockstep or options.wait_for_subscribers:
            unmatched = player.wait_for_graph() if player.running() else []
            missing = [name for name in unmatched if name in playback.wait_names.values()]
            if missing and player.running():
                print(f'bag_play: no publisher on {missing} after {options.startup_timeout:g} '
                      's: is the node under test running?', file=sys.stderr)
                return 1
            if unmatched and player.running():
                print(f'bag_play: warning: no subscriber on {unmatched}; playing anyway',
                      file=sys.stderr)
        stats = player.play()
    except (KeyboardInterrupt, ExternalShutdownException):
        stats = player.stats if player is not None else PlaybackStats()
        stats.interrupted = True
        stats.finished = time.monotonic()
    except BagError as error:
        print(f'bag_play: {error}', file=sys.stderr)
        return 2
    finally:
        stop.restore()
        if player is not None:
            player.close()
        rclpy.try_shutdown()
    print(stats.line(), flush=True)
    return 1 if stats.timeouts or stats.node_lost else 0


if __name__ == '__main__':
    sys.exit(main())
