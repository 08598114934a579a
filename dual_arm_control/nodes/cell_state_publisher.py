"""
cell_state_publisher: the cell's URDF and TF, as robot_state_publisher would publish them.

Publishes the cell URDF (dual_arm_control.description.cell_urdf) once on /robot_description
(std_msgs/String, transient local), the fixed joints, the scene and the scenario's targets once
on /tf_static, and on /tf each arm's joint transforms from /<arm>/joint_states and the frame
'object' from the tracker's /object/state (skipped while it has no estimate), at most once per
`tf_period` of sim time per source, stamped with the input's stamp. It takes no part in the
lockstep exchange (nothing waits for it) and works the same on the real robots' joint states.
"""

import sys

from dual_arm_control import contract
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.description.cell import load_cell
from dual_arm_control.description.cell_urdf import cell_urdf
from dual_arm_control.nodes.messages import (joint_state_of, object_state_of, set_quaternion,
                                             set_vector3, stamp_ns)
from dual_arm_control.nodes.process import CountingPublisher, run_node
from dual_arm_control.parameters import NodeParameters
from dual_arm_control.runtime.cell_frames import (CellFrames, object_transform,
                                                  target_transforms, UpdateSchedule)
from dual_arm_control.runtime.node_settings import node_table
from dual_arm_control.runtime.timing import seconds_to_ns
from dual_arm_control.scenario import load_scenario
from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from std_msgs.msg import String


def transform_message(stamp, transform):
    """Return the TransformStamped of a FrameTransform at a builtin_interfaces/Time stamp."""
    msg = TransformStamped(child_frame_id=transform.child)
    msg.header.stamp = stamp
    msg.header.frame_id = transform.parent
    set_vector3(msg.transform.translation, transform.translation)
    set_quaternion(msg.transform.rotation, transform.rotation)
    return msg


class CellStatePublisher(Node):
    """Publish /robot_description, /tf_static and rate-limited /tf for the cell."""

    def __init__(self, node_name='cell_state_publisher', **node_options):
        super().__init__(node_name, **node_options)
        settings = NodeParameters(self, node_table('cell_state_publisher').settings,
                                  on_change=self._on_setting)
        cell = load_cell()
        urdf = cell_urdf(cell)
        self.frames = CellFrames(urdf)
        self.schedule = UpdateSchedule(seconds_to_ns(settings['tf_period']))
        self.refused = 0
        static = list(self.frames.static_transforms)
        if settings['scenario']:
            static += target_transforms(load_scenario(settings['scenario']), cell)
        self._description_pub = self._publisher(contract.ROBOT_DESCRIPTION)
        self._static_pub = self._publisher(contract.TF_STATIC)
        self._tf_pub = self._publisher(contract.TF)
        self._description_pub.publish(String(data=urdf))
        stamp = self.get_clock().now().to_msg()
        self._static_pub.publish(contract.TF_STATIC.msg_type(
            transforms=[transform_message(stamp, transform) for transform in static]))
        for arm in contract.ARMS:
            self.create_subscription(
                contract.JOINT_STATES.msg_type, contract.JOINT_STATES.resolved(arm),
                lambda msg, arm=arm: self._on_joint_state(arm, msg),
                contract.JOINT_STATES.subscription_qos(lockstep=False))
        self.create_subscription(
            contract.OBJECT_STATE.msg_type, contract.OBJECT_STATE.name, self._on_object_state,
            contract.OBJECT_STATE.subscription_qos(lockstep=False))
        self.get_logger().info(f'cell state publisher up: {len(self.frames.links)} links, '
                               f'{len(static)} static frames, /tf every '
                               f'{settings["tf_period"]:g} s')

    def _on_setting(self, name, value):
        if name == 'tf_period':
            self.schedule.period_ns = seconds_to_ns(value)

    def _publisher(self, topic):
        return self.create_publisher(topic.msg_type, topic.name, topic.qos,
                                     publisher_class=CountingPublisher)

    def _refuse(self, error):
        self.refused += 1
        self.get_logger().warning(f'input refused ({self.refused} so far): {error}',
                                  throttle_duration_sec=5.0)

    def _on_joint_state(self, arm, msg):
        if not self.schedule.due(arm, stamp_ns(msg.header.stamp)):
            return
        try:
            sample = joint_state_of(msg, contract.joint_names(arm))
        except InputError as error:
            self._refuse(error)
            return
        self._send(msg.header.stamp, self.frames.arm_transforms(arm, sample.position))

    def _on_object_state(self, msg):
        if msg.pose.covariance[0] == contract.NO_ESTIMATE_COVARIANCE or \
                not self.schedule.due('object', stamp_ns(msg.header.stamp)):
            return
        try:
            state = object_state_of(msg)
        except InputError as error:
            self._refuse(error)
            return
        self._send(msg.header.stamp, [object_transform(state.position, state.quat_xyzw)])

    def _send(self, stamp, transforms):
        self._tf_pub.publish(contract.TF.msg_type(
            transforms=[transform_message(stamp, transform) for transform in transforms]))


def main(args=None):
    """Run the cell state publisher until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(CellStatePublisher, 'cell_state_publisher', args)


if __name__ == '__main__':
    sys.exit(main())
