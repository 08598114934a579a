"""
When a lockstep run may start: every node of the graph (and the recorder) is there and matched.

A lockstep bridge publishes its first state only once the awaited nodes exist with their
publishers, every topic it publishes has a subscriber (if asked) and bag_record has matched
every publisher it records (if asked), so every node, and a recording, sees the run from its
first cycle.
"""

from dual_arm_control import contract
from dual_arm_control.nodes.recorder_status import (recorder_has_matched,
                                                    recorder_matched_counts)
from rclpy.node import NodeNameNonExistentError


class GraphReadiness:
    """Checks the graph a lockstep bridge waits for; ready() says whether it is complete."""

    def __init__(self, node, streams, awaited_nodes, wait_for_subscribers, wait_for_recorder):
        self._node = node
        self._streams = streams
        self._awaited_nodes = [name for name in awaited_nodes if name]
        self._wait_for_subscribers = wait_for_subscribers
        self._wait_for_recorder = wait_for_recorder
        self._recorder_matched = None
        if wait_for_recorder:
            node.create_subscription(contract.RECORDER_STATUS.msg_type,
                                     contract.RECORDER_STATUS.name, self._on_recorder_status,
                                     contract.RECORDER_STATUS.qos)

    @property
    def waits(self):
        """Return True if anything must be awaited before the first state."""
        return bool(self._wait_for_subscribers or self._awaited_nodes or self._wait_for_recorder)

    def _on_recorder_status(self, msg):
        self._recorder_matched = recorder_matched_counts(msg)

    def ready(self):
        """Return True once the awaited subscribers, recorder and nodes are all there."""
        if self._wait_for_subscribers and not all(
                stream.publisher.get_subscription_count() > 0 for stream in self._streams()):
            return False
        if self._wait_for_recorder and not recorder_has_matched(self._node,
                                                                self._recorder_matched):
            return False
        present = {f'{namespace.rstrip("/")}/{name}'
                   for name, namespace in self._node.get_node_names_and_namespaces()}
        for full_name in self._awaited_nodes:
            if full_name not in present:
                return False
            namespace, _, name = full_name.rpartition('/')
            try:
                if not self._node.get_publisher_names_and_types_by_node(name, namespace or '/'):
                    return False
            except NodeNameNonExistentError:
                return False
        return True
