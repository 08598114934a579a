"""
object_tracker: the object's pose and twist from motion capture (runtime TrackerStep).

Every accepted /mocap/object_pose sample is answered by one /object/state (nav_msgs/Odometry,
frame world, child 'object') with the sample's stamp; every /clock cycle by one more, stamped
with the cycle: the estimate then, or the news that there is no track yet. The lockstep bridge
waits for the first kind, the lockstep DS and wrench QP for the second (only with `lockstep`;
in realtime they use the newest estimate). In lockstep a refused sample is answered too, with
the estimate at its stamp (none for a stamp older than the last sample): the bridge waits for
an answer to each sample it sent, and a stray sample with a newer stamp would otherwise stall
the graph; the cycle's own answer follows and is the one the DS and QP use. What is refused, and
when a new TrackerConfig applies, is the runtime step's business (runtime/tracker_step.py).
With track_container the node tracks a conveyor's container as well: each
/mocap/container_pose sample is answered on /container/state (stamped with it), and in lockstep
each /clock too, right after the object's answer (the lockstep bridge and DS wait for these).
Parameters: the TrackerConfig fields (live), lockstep, track_container and diagnostics_period.
"""

import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.core.tracker import TrackerConfig
from dual_arm_control.nodes.diagnostics import CounterDiagnostics, refusal_logger
from dual_arm_control.nodes.messages import fill_object_state, quaternion, stamp_ns, vector3
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import ConfigParameters, NodeParameters
from dual_arm_control.runtime.node_settings import node_table
from dual_arm_control.runtime.tracker_step import TrackerStep
from rclpy.node import Node


class ObjectTrackerNode(Node):
    """Answer each mocap sample and each cycle with the object estimate at its stamp."""

    def __init__(self, node_name='object_tracker', **node_options):
        super().__init__(node_name, **node_options)
        settings = NodeParameters(self, node_table('object_tracker').settings)
        self._lockstep = settings['lockstep']
        self._diagnostics = CounterDiagnostics(self)
        parameters = ConfigParameters(self, TrackerConfig(), self._on_config)
        self.step = TrackerStep(parameters.config, refusal_logger(self.get_logger()))
        self.states_published = 0
        self._state_msg = contract.OBJECT_STATE.msg_type()
        self._state_msg.header.frame_id = contract.WORLD_FRAME
        self._state_msg.child_frame_id = 'object'
        self._state_pub = create_topic_publisher(self, contract.OBJECT_STATE)
        self._mocap_sub = self.create_subscription(
            contract.MOCAP_OBJECT_POSE.msg_type, contract.MOCAP_OBJECT_POSE.name, self._on_mocap,
            contract.MOCAP_OBJECT_POSE.subscription_qos(settings['lockstep']))
        self._container_pub = None
        if settings['track_container']:
            self._container_msg = contract.CONTAINER_STATE.msg_type()
            self._container_msg.header.frame_id = contract.WORLD_FRAME
            self._container_msg.child_frame_id = 'container'
            self._container_pub = create_topic_publisher(self, contract.CONTAINER_STATE)
            self.create_subscription(
                contract.MOCAP_CONTAINER_POSE.msg_type, contract.MOCAP_CONTAINER_POSE.name,
                self._on_container_mocap,
                contract.MOCAP_CONTAINER_POSE.subscription_qos(settings['lockstep']))
        if settings['lockstep']:
            self.create_subscription(contract.CLOCK.msg_type, contract.CLOCK.name,
                                     self._on_clock, contract.CLOCK.qos)
        self.get_logger().info(
            f'object tracker up: {self._mocap_sub.topic_name} -> {self._state_pub.topic_name}')

    @property
    def config(self):
        """Return the TrackerConfig the filter runs with (a pending change not included)."""
        return self.step.config

    @property
    def pending_config(self):
        """Return the accepted TrackerConfig waiting for the object to rest, or None."""
        return self.step.pending_config

    def _on_config(self, config):
        self.step.reconfigure(config)

    def _on_mocap(self, msg):
        sample_ns = stamp_ns(msg.header.stamp)
        state = self.step.sample(sample_ns, vector3(msg.pose.position),
                                 quaternion(msg.pose.orientation))
        if state is None and self._lockstep:
            state = self.step.at(sample_ns)
        if state is not None:
            self._publish(state)
            self._diagnostics.publish_if_due(state.stamp_ns, self._report)

    def _on_clock(self, msg):
        self._publish(self.step.at(stamp_ns(msg.clock)))
        if self._container_pub is not None:
            self._publish_container(self.step.container_at(stamp_ns(msg.clock)))

    def _on_container_mocap(self, msg):
        sample_ns = stamp_ns(msg.header.stamp)
        state = self.step.container_sample(sample_ns, vector3(msg.pose.position))
        if state is None and self._lockstep:
            state = self.step.container_at(sample_ns)
        if state is not None:
            self._publish_container(state)

    def _publish_container(self, state):
        fill_object_state(self._container_msg, state)
        self._container_pub.publish(self._container_msg)
        self.states_published += 1

    def _publish(self, state):
        fill_object_state(self._state_msg, state)
        self._state_pub.publish(self._state_msg)
        self.states_published += 1

    def _report(self):
        values = dict(self.step.counters, states_published=self.states_published)
        values.update({f'refused_{reason}': n for reason, n in self.step.refusals.counts.items()})
        tracking = self.step.tracking()
        values.update({'tracking': tracking,
                       'config_change_pending': self.step.pending_config is not None})
        if not tracking:
            return DiagnosticStatus.WARN, 'no object track', values
        if self.step.refusals.total:
            return DiagnosticStatus.WARN, 'tracking; invalid samples refused', values
        return DiagnosticStatus.OK, 'tracking', values


def main(args=None):
    """Run the tracker until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(ObjectTrackerNode, 'object_tracker', args)


if __name__ == '__main__':
    sys.exit(main())
