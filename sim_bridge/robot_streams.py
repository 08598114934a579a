"""
What the robots report each FRI cycle, on the topics of the contract: /clock, joint states, F/T.

Also the mocap samples the cycle delivers (the box's, and a conveyor's container's). The
bridge decides when each goes out (lockstep, tracker waits, F/T ticks); these publishers fill
their reused messages and send them.
"""

from dual_arm_control import contract
from dual_arm_control.nodes.messages import fill_joint_state, fill_pose, fill_wrench, time_msg
from sim_bridge.ground_truth import Stream


class RobotStreams:
    """Publishers of the robots' side: /clock, mocap, joint states and F/T wrenches per arm."""

    def __init__(self, node, container=False):
        self.clock = Stream(node, contract.CLOCK)
        self.mocap = Stream(node, contract.MOCAP_OBJECT_POSE, frame_id=contract.WORLD_FRAME)
        self.container_mocap = None if not container else Stream(
            node, contract.MOCAP_CONTAINER_POSE, frame_id=contract.WORLD_FRAME)
        self.joint_states = {arm: Stream(node, contract.JOINT_STATES, arm)
                             for arm in contract.ARMS}
        self.ft = {arm: Stream(node, contract.FT_WRENCH, arm, frame_id=f'{arm}_ft_sensor')
                   for arm in contract.ARMS}

    def streams(self):
        """Return every stream."""
        return [self.clock, self.mocap, *self.joint_states.values(), *self.ft.values(),
                *([self.container_mocap] if self.container_mocap else [])]

    def publish_mocap(self, cycle):
        """Publish the mocap samples delivered at the FRI cycle, in order (container first)."""
        for sample in cycle.container_mocap if self.container_mocap else ():
            fill_pose(self.container_mocap.msg, sample)
            self.container_mocap.publish()
        for sample in cycle.mocap:
            fill_pose(self.mocap.msg, sample)
            self.mocap.publish()

    def publish_joint_states(self, cycle):
        """Publish /clock and both arms' joint states of the FRI cycle."""
        self.clock.msg.clock = time_msg(cycle.stamp_ns)
        self.clock.publish()
        for arm in contract.ARMS:
            fill_joint_state(self.joint_states[arm].msg, contract.joint_names(arm),
                             cycle.joints[arm])
            self.joint_states[arm].publish()

    def publish_ft(self, cycle):
        """Publish both arms' F/T wrenches of the FRI cycle."""
        for arm in contract.ARMS:
            fill_wrench(self.ft[arm].msg, cycle.ft_wrenches[arm])
            self.ft[arm].publish()
