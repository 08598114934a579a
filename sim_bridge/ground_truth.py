"""
The simulator's ground truth on topics: object, tools, pad wrenches and a conveyor's container.

For evaluation and recording only; no node of the control graph subscribes. Published at most
once per `period` of sim time, and only on the topics someone subscribes to (a recorder, a
viewer): a message nobody takes is not built.
"""

from dual_arm_control import contract
from dual_arm_control.nodes.messages import fill_odometry, set_odometry, set_vector3, time_msg
from dual_arm_control.nodes.process import create_topic_publisher
import numpy as np

_IDENTITY_QUAT = np.array([0.0, 0.0, 0.0, 1.0])


class Stream:
    """A publisher of the contract and the message it reuses (filled in place, then sent)."""

    def __init__(self, node, topic, arm=None, frame_id=None, child_frame_id=None):
        self.publisher = create_topic_publisher(node, topic, arm)
        self.msg = topic.msg_type()
        if frame_id is not None:
            self.msg.header.frame_id = frame_id
        if child_frame_id is not None:
            self.msg.child_frame_id = child_frame_id

    def publish(self):
        """Send the message as it is filled now."""
        self.publisher.publish(self.msg)

    @property
    def subscribed(self):
        """Return True if the topic has a subscriber now."""
        return self.publisher.get_subscription_count() > 0


class GroundTruthStreams:
    """Publishers of the twin's ground truth; publish(twin, stamp_ns) sends one set."""

    def __init__(self, node, container=False):
        self.object = Stream(node, contract.GROUND_TRUTH_OBJECT, frame_id=contract.WORLD_FRAME,
                             child_frame_id='object')
        self.container = None if not container else Stream(
            node, contract.GROUND_TRUTH_CONTAINER, frame_id=contract.WORLD_FRAME,
            child_frame_id='container')
        self.tools, self.pad_wrenches = {}, {}
        for arm in contract.ARMS:
            self.tools[arm] = Stream(node, contract.GROUND_TRUTH_TOOL, arm,
                                     frame_id=contract.WORLD_FRAME, child_frame_id=f'{arm}_tool')
            self.pad_wrenches[arm] = Stream(node, contract.GROUND_TRUTH_PAD_WRENCH, arm,
                                            frame_id=contract.WORLD_FRAME)

    def streams(self):
        """Return every stream."""
        return [self.object, *self.tools.values(), *self.pad_wrenches.values(),
                *([self.container] if self.container else [])]

    def publish(self, twin, stamp_ns):
        """Publish the twin's current ground truth stamped stamp_ns."""
        stamp = time_msg(stamp_ns)
        if self.object.subscribed:
            self.object.msg.header.stamp = stamp
            set_odometry(self.object.msg, *twin.object_pose(), *twin.object_twist())
            self.object.publish()
        if self.container is not None and self.container.subscribed:
            position, velocity = twin.container.pose(twin.data)
            self.container.msg.header.stamp = stamp
            set_odometry(self.container.msg, position, _IDENTITY_QUAT, velocity, np.zeros(3))
            self.container.publish()
        for arm in contract.ARMS:
            tool = self.tools[arm]
            if tool.subscribed:
                p_world_tool, R_world_tool = twin.tool_pose(arm)
                tool.msg.header.stamp = stamp
                fill_odometry(tool.msg, p_world_tool, R_world_tool, *twin.tool_twist(arm))
                tool.publish()
            wrench = self.pad_wrenches[arm]
            if wrench.subscribed:
                force_world, torque_world = twin.pad_wrench(arm)
                wrench.msg.header.stamp = stamp
                set_vector3(wrench.msg.wrench.force, force_world)
                set_vector3(wrench.msg.wrench.torque, torque_world)
                wrench.publish()
