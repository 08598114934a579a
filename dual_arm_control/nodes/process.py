"""
The process around a node: publishers that count, a clean shutdown, the Jazzy lifetime.

run_node() builds a node, spins it with the EventsExecutor until Ctrl-C, SIGTERM or the node
finishes, and on the way out waits until its subscribers acknowledged its last messages and
prints how many messages it published per topic (the bag tests compare them with the bag).
"""

import json
import os
import signal
import time

from dual_arm_control.core.exceptions import DualArmControlError
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions

# Wall time a stopping node waits for its subscribers to acknowledge its last messages [s].
FLUSH_TIMEOUT = 2.0
# The line a stopping node prints with {topic: messages published} (read by the bag tests).
PUBLISHED_COUNTS_PREFIX = 'published counts: '
# Environment variable with the SCHED_FIFO priority (1-99) a node's process runs at; the
# launcher sets it per node in realtime mode (the robot side and the controllers highest).
REALTIME_PRIORITY_VARIABLE = 'DUAL_ARM_REALTIME_PRIORITY'


class CountingPublisher(Publisher):
    """A publisher that counts its messages, so a recording can be checked against it."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.published = 0

    def publish(self, msg):
        """Publish msg and count it."""
        super().publish(msg)
        self.published += 1


def create_topic_publisher(node, topic, arm=None):
    """
    Return a counting publisher of a contract topic with the contract's publisher QoS.

    arm resolves a per-arm topic to /<arm>/...; without it a per-arm topic stays relative to
    the node's namespace.
    """
    name = topic.name if arm is None else topic.resolved(arm)
    return node.create_publisher(topic.msg_type, name, topic.publisher_qos,
                                 publisher_class=CountingPublisher)


def published_counts(node):
    """Return {topic: messages published} over the node's counting publishers."""
    counts = {}
    for publisher in node.publishers:
        if isinstance(publisher, CountingPublisher):
            counts[publisher.topic_name] = counts.get(publisher.topic_name, 0) + \
                publisher.published
    return counts


def flush_publishers(node, timeout=FLUSH_TIMEOUT):
    """Wait until every reliable subscriber acknowledged the node's messages; return success."""
    deadline = time.monotonic() + timeout
    acknowledged = True
    for publisher in node.publishers:
        remaining = max(deadline - time.monotonic(), 0.0)
        try:
            acknowledged &= publisher.wait_for_all_acked(Duration(seconds=remaining))
        except RuntimeError:
            acknowledged = False  # rclpy's InvalidHandle/RCLError: the context is already gone
    return acknowledged


class StopRequest:
    """
    SIGINT/SIGTERM set a flag (with rclpy's own handlers off), until restore().

    So a stopping process can still finish its work with rclpy up: flush, drain, print.
    """

    def __init__(self):
        self.requested = False
        self._previous = {signum: signal.getsignal(signum)
                          for signum in (signal.SIGINT, signal.SIGTERM)}
        for signum in self._previous:
            signal.signal(signum, self.request)

    def request(self, signum=None, frame=None):
        """Ask the process to stop (the signal handler)."""
        self.requested = True

    def restore(self):
        """Put back the signal handlers that were there before."""
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)


def use_realtime_priority(priority):
    """
    Run this process at SCHED_FIFO `priority` (a string 1-99, or None: leave it); return a note.

    Called before rclpy starts its threads, which inherit the policy. Where the OS refuses (no
    CAP_SYS_NICE) the process keeps its normal priority and the note says so.
    """
    if not priority:
        return ''
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
    except (ValueError, OSError) as error:
        return f'real-time priority {priority} refused ({error}); running at normal priority'
    return f'running at real-time priority {priority} (SCHED_FIFO)'


def run_node(node_factory, name, args=None, drain=False, on_exit=None):
    """
    Run one node until Ctrl-C or SIGTERM, the Jazzy way; return the process exit code.

    The node is built before the spin loop so a constructor error (bad parameters, bad files)
    is reported once and exits 2. EventsExecutor.spin() ignores signals, so signals only set a
    flag and the loop spins once at a time. On the way out, with drain, node.drain(executor)
    still spins (a recorder takes the messages already delivered to it); then the node waits
    (FLUSH_TIMEOUT) until its subscribers acknowledged its last messages, prints its published
    counts and is destroyed. on_exit(node), if given, runs before that and returns the exit
    code (0 otherwise).
    """
    priority_note = use_realtime_priority(os.environ.get(REALTIME_PRIORITY_VARIABLE))
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    if priority_note:
        rclpy.logging.get_logger(name).info(priority_note)
    stop = StopRequest()
    try:
        node = node_factory()
    except (DualArmControlError, rclpy.exceptions.ParameterException) as error:
        rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
        rclpy.try_shutdown()
        stop.restore()
        return 2
    executor = EventsExecutor()
    executor.add_node(node)
    status = 0
    try:
        while rclpy.ok() and not stop.requested and not getattr(node, 'finished', False):
            executor.spin_once(timeout_sec=0.1)
        if drain:
            node.drain(executor)
        flush_publishers(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if on_exit is not None:
            status = on_exit(node)
        counts = published_counts(node)
        if counts:
            print(PUBLISHED_COUNTS_PREFIX + json.dumps(counts, sort_keys=True), flush=True)
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
        stop.restore()
    return status
