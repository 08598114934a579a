"""
gravity_comp_controller: a test controller for one arm (stand-in for the passive controller).

Answers every joint state with a torque command stamped like the state, as the bridge's lockstep
mode expects: mode 'gravity' commands the gravity torque of the arm's pinocchio model minus joint
damping times velocity; mode 'zero' commands zero torque (the arm falls). Run one instance per arm
in the arm's namespace: `--ros-args -r __ns:=/left -p arm:=left`. Triggered by the incoming state,
no timers.
"""

import sys

from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError
from dual_arm_control.description.cell import arm_model
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import parameter_descriptor
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from sensor_msgs.msg import JointState

MODES = ('gravity', 'zero')
MAX_JOINT_DAMPING = 100.0
LOG_THROTTLE_PERIOD = 1.0


def gravity_compensation_torque(gravity_torque, joint_velocity, joint_damping):
    """Return gravity torque [N m] minus joint_damping [N m s/rad] times velocity [rad/s]."""
    return np.asarray(gravity_torque) - joint_damping * np.asarray(joint_velocity)


class GravityCompController(Node):
    """Reply to each joint state of one arm with a gravity-compensation torque command."""

    def __init__(self, node_name='gravity_comp_controller', **node_options):
        super().__init__(node_name, **node_options)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._on_parameters_set)
        self.declare_parameter('arm', 'left', ParameterDescriptor(
            description='which arm this controller drives', read_only=True,
            additional_constraints=f'one of {contract.ARMS}'))
        self.declare_parameter('mode', 'gravity', ParameterDescriptor(
            description='gravity: gravity torque - damping * velocity; zero: no torque',
            additional_constraints=f'one of {MODES}'))
        self.declare_parameter('joint_damping', 2.0, parameter_descriptor(
            'viscous joint damping added to the gravity torque [N m s/rad]',
            floating_range=(0.0, MAX_JOINT_DAMPING)))
        self.arm = self.get_parameter('arm').value
        self.mode = self.get_parameter('mode').value
        self.joint_damping = self.get_parameter('joint_damping').value
        self._model = arm_model(self.arm)
        self._joint_names = contract.joint_names(self.arm)
        self._command_pub = create_topic_publisher(self, contract.TORQUE_COMMAND)
        self._state_sub = self.create_subscription(
            contract.JOINT_STATES.msg_type, contract.JOINT_STATES.name, self._on_joint_state,
            contract.JOINT_STATES.qos)
        self.get_logger().info(
            f'{self.arm} gravity compensation: mode {self.mode}, joint damping '
            f'{self.joint_damping} N m s/rad, '
            f'state {self._state_sub.topic_name} -> command {self._command_pub.topic_name}')

    def _on_set_parameters(self, parameters):
        """Refuse an unknown arm or mode (ranges are checked by the descriptors)."""
        for parameter in parameters:
            if parameter.name == 'arm' and parameter.value not in contract.ARMS:
                return SetParametersResult(
                    successful=False, reason=f'arm must be one of {contract.ARMS}, got '
                                             f'{parameter.value!r}')
            if parameter.name == 'mode' and parameter.value not in MODES:
                return SetParametersResult(
                    successful=False, reason=f'mode must be one of {MODES}, got '
                                             f'{parameter.value!r}')
        return SetParametersResult(successful=True)

    def _on_parameters_set(self, parameters):
        """Apply a new mode or damping from the next state on."""
        for parameter in parameters:
            if parameter.name == 'mode':
                self.mode = parameter.value
            elif parameter.name == 'joint_damping':
                self.joint_damping = parameter.value

    def _on_joint_state(self, msg):
        """Answer the state with a torque command carrying the state's stamp."""
        if list(msg.name) != self._joint_names:
            self.get_logger().error(
                f'joint state names {list(msg.name)} are not {self._joint_names}; no command',
                throttle_duration_sec=LOG_THROTTLE_PERIOD)
            return
        if self.mode == 'zero':
            torque = np.zeros(len(self._joint_names))
        else:
            try:
                torque = gravity_compensation_torque(
                    self._model.gravity_torque(np.array(msg.position)), msg.velocity,
                    self.joint_damping)
            except DualArmControlError as error:
                self.get_logger().error(f'no command for this state: {error}',
                                        throttle_duration_sec=LOG_THROTTLE_PERIOD)
                return
        command = JointState()
        command.header.stamp = msg.header.stamp
        command.name = self._joint_names
        command.position = msg.position
        command.effort = torque.tolist()
        self._command_pub.publish(command)


def main(args=None):
    """Run one arm's controller until Ctrl-C or SIGTERM."""
    return run_node(GravityCompController, 'gravity_comp_controller', args)


if __name__ == '__main__':
    sys.exit(main())
