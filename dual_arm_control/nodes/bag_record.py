"""
bag_record: record topics of the graph, as published (serialized CDR), into an MCAP bag.

By default every topic of the contract plus /parameter_events and /rosout; topics given on the
command line or matching --regex instead. Contract topics are subscribed at once with their
contract QoS (so the subscriptions exist before the graph starts: a bridge started with
wait_for_recorder waits for them); other topics as their publishers appear (the graph
is polled every 0.5 s), with a QoS compatible with every publisher: reliable and transient
local only if each publisher offers it. SIGINT/SIGTERM first take what was already delivered,
then close the bag with its summary. Log times are the receive time on the node's clock: sim
time with use_sim_time (--use-sim-time or the ROS parameter), as rosbag2 records, else wall
time. An existing bag is replaced only with --overwrite.
"""

import argparse
import importlib
import re
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.bags import BagError
from dual_arm_control.bags.writer import (available_compressions, BagWriter, DEFAULT_CHUNK_SIZE,
                                          existing_bag_files)
from dual_arm_control.nodes.process import run_node
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.utilities import remove_ros_args

DISCOVERY_PERIOD = 0.5
# Wall time between checks of the matched publishers (published on a change).
STATUS_PERIOD = 0.1
DEFAULT_EXTRA_TOPICS = ('/parameter_events', '/rosout')
# On stop: take delivered messages until none came for DRAIN_IDLE, at most DRAIN_LIMIT [s].
DRAIN_IDLE = 0.5
DRAIN_LIMIT = 10.0
EXIT_CODES = ('exit codes: 0 the bag was closed with its summary; 1 recording failed (the '
              'traceback names the error); 2 bad input: an unknown option or topic expression, '
              'a bag already at --output without --overwrite, a bag file that cannot be '
              'created')


def contract_topics():
    """Return {absolute topic name: contract Topic} of every contract topic (both arms)."""
    topics = {}
    for topic in contract.ALL_TOPICS:
        for arm in (contract.ARMS if topic.per_arm else (None,)):
            topics[topic.resolved(arm)] = topic
    return topics


def message_class(type_name):
    """Return the Python class of 'package/msg/Type'; raise BagError if it cannot be imported."""
    parts = type_name.split('/')
    if len(parts) != 3:
        raise BagError(f'cannot interpret message type {type_name!r}')
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError) as error:
        raise BagError(f'message type {type_name} is not installed: {error}') from error


# The recorder's own queue per topic: it may fall behind the lockstep graph by this many
# messages of a topic without losing one (the publishers keep as many).
RECORDER_DEPTH = contract.PUBLISHER_HISTORY_DEPTH


def compatible_qos(publishers):
    """
    Return a subscription QoS matching every publisher of a topic.

    Reliable only if all publishers are reliable, transient local only if all are (so the
    recorder gets what they sent before it matched), keep-last RECORDER_DEPTH.
    """
    reliable = all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers)
    latched = bool(publishers) and all(
        p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=RECORDER_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                    else DurabilityPolicy.VOLATILE))


class TopicSelection:
    """Which topics to record: explicit names, a regular expression, or the default set."""

    def __init__(self, names=(), regex=None):
        self.names = frozenset(names)
        self.regex = re.compile(regex) if regex else None
        if not self.names and self.regex is None:
            self.names = frozenset(contract_topics()) | frozenset(DEFAULT_EXTRA_TOPICS)

    def wants(self, topic):
        """Return True if the topic is to be recorded."""
        return topic in self.names or bool(self.regex and self.regex.search(topic))


class BagRecorder(Node):
    """Subscribe to the selected topics with raw=True and write every message to a BagWriter."""

    def __init__(self, options):
        super().__init__('bag_record', parameter_overrides=(
            [Parameter('use_sim_time', Parameter.Type.BOOL, True)] if options.use_sim_time
            else []))
        self._sim_time = self.get_parameter('use_sim_time').value
        self._selection = TopicSelection(options.topics, options.regex)
        self._writer = BagWriter(options.output, compression=options.compression,
                                 chunk_size=options.chunk_size,
                                 split_size=options.max_bag_size,
                                 split_duration=options.max_bag_duration,
                                 metadata=dict(options.metadata), overwrite=options.overwrite)
        self._recorded = {}
        self._contract = contract_topics()
        for name, topic in self._contract.items():
            if self._selection.wants(name):
                self._subscribe(name, topic.msg_type, [topic.publisher_qos], topic.qos)
        self._discover()
        # Wall-clock timers: sim time stands still until the graph runs, which waits for us.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(DISCOVERY_PERIOD, self._discover, clock=steady)
        self._status_pub = self.create_publisher(
            contract.RECORDER_STATUS.msg_type, contract.RECORDER_STATUS.name,
            contract.RECORDER_STATUS.qos)
        self._matched = None
        self.create_timer(STATUS_PERIOD, self._publish_matched, clock=steady)
        self.get_logger().info(f'recording {len(self._recorded)} topics into '
                               f'{options.output} ({options.compression}, '
                               f'{"sim" if self._sim_time else "wall"} time)')

    @property
    def counts(self):
        """Return {topic: messages recorded}."""
        return self._writer.counts

    def _subscribe(self, name, msg_type, offered_qos, qos):
        """Register the topic and its offered QoS in the bag; subscribe to serialized data."""
        self._writer.add_topic(name, msg_type, offered_qos)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=RECORDER_DEPTH,
                         reliability=qos.reliability, durability=qos.durability)
        self._recorded[name] = self.create_subscription(
            msg_type, name, lambda data, topic=name: self._record(topic, data), qos, raw=True)

    def _record(self, topic, data):
        """Write one received message with its receive time (sim time with use_sim_time)."""
        self._writer.write(topic, data, self.get_clock().now().nanoseconds if self._sim_time
                           else time.time_ns())

    def _discover(self):
        """Subscribe to selected topics that appeared in the graph since the last poll."""
        for name, types in self.get_topic_names_and_types():
            if name in self._recorded or not self._selection.wants(name):
                continue
            if len(types) != 1:
                self.get_logger().warning(f'not recording {name}: several types {types}')
                self._selection.names -= {name}
                continue
            publishers = self.get_publishers_info_by_topic(name)
            if not publishers:
                continue
            try:
                self._subscribe(name, message_class(types[0]),
                                [p.qos_profile for p in publishers], compatible_qos(publishers))
            except BagError as error:
                self.get_logger().warning(f'not recording {name}: {error}')
                continue
            self.get_logger().info(f'recording {name} ({types[0]})')

    def _publish_matched(self):
        """Publish the matched publishers per recorded topic when they changed."""
        matched = {name: sub.get_publisher_count() for name, sub in self._recorded.items()}
        if matched == self._matched:
            return
        self._matched = matched
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK, name='bag_record', message='matched publishers',
            values=[KeyValue(key=name, value=str(count))
                    for name, count in sorted(matched.items())])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._status_pub.publish(msg)

    def drain(self, executor):
        """Take the messages already delivered until none came for DRAIN_IDLE (on stop)."""
        deadline = time.monotonic() + DRAIN_LIMIT
        total = sum(self.counts.values())
        idle_since = time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - idle_since < DRAIN_IDLE:
            executor.spin_once(timeout_sec=0.05)
            if sum(self.counts.values()) != total:
                total = sum(self.counts.values())
                idle_since = time.monotonic()

    def destroy_node(self):
        """Close the bag (summary written), print the counts (rosout may be gone), destroy."""
        self._writer.close()
        counts = self._writer.counts
        summary = ', '.join(f'{topic}: {count}' for topic, count in sorted(counts.items()))
        print(f'bag_record: closed {[str(p) for p in self._writer.paths]}: '
              f'{sum(counts.values())} messages ({summary})', flush=True)
        return super().destroy_node()


def _metadata_entry(text):
    """Parse a --metadata KEY=VALUE argument into (key, value)."""
    key, separator, value = text.partition('=')
    if not separator or not key:
        raise argparse.ArgumentTypeError(f'expected KEY=VALUE, got {text!r}')
    return key, value


def parse_arguments(argv):
    """Parse the recorder's command line (ROS arguments removed)."""
    parser = argparse.ArgumentParser(prog='bag_record', description=__doc__.split('\n')[1],
                                     epilog=EXIT_CODES)
    parser.add_argument('topics', nargs='*', help='topics to record (default: the contract '
                        'topics, /parameter_events and /rosout)')
    parser.add_argument('-o', '--output', default='bag.mcap', help='bag file (.mcap)')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace a bag already at --output (with its split files)')
    parser.add_argument('--use-sim-time', action='store_true',
                        help='log times from /clock (sim time), as the ROS parameter '
                             'use_sim_time:=true')
    parser.add_argument('-e', '--regex', help='record every topic matching this expression')
    parser.add_argument('--compression', default='zstd', choices=available_compressions())
    parser.add_argument('--chunk-size', type=int, default=DEFAULT_CHUNK_SIZE,
                        help='uncompressed chunk size [bytes]')
    parser.add_argument('--max-bag-size', type=int,
                        help='start a new file <stem>_<N>.mcap beyond this size [bytes]')
    parser.add_argument('--max-bag-duration', type=float,
                        help='start a new file beyond this recording time [s]')
    parser.add_argument('--metadata', action='append', default=[], type=_metadata_entry,
                        metavar='KEY=VALUE', help='a fact of the run stored in the bag '
                        "(MCAP metadata 'dual_arm_control'), e.g. scenario=PATH; repeatable")
    options = parser.parse_args(argv)
    if options.regex is not None:
        try:
            re.compile(options.regex)
        except re.error as error:
            parser.error(f'invalid --regex {options.regex!r}: {error}')
    return options


def main(argv=None):
    """Run the recorder until SIGINT/SIGTERM; return the process exit code."""
    argv = sys.argv if argv is None else argv
    options = parse_arguments(remove_ros_args(argv)[1:])
    existing = existing_bag_files(options.output)
    if existing and not options.overwrite:
        print(f'bag_record: {options.output} already exists '
              f'({", ".join(str(p) for p in existing)}); pass --overwrite to replace it',
              file=sys.stderr)
        return 2
    return run_node(lambda: BagRecorder(options), 'bag_record', args=argv, drain=True)


if __name__ == '__main__':
    sys.exit(main())
