"""
The robot's own safety hold: what a KUKA arm does on its own when its torque commands stop.

Under FRI command loss the robot holds its position: gravity compensation, a joint stiffness
toward the joint positions where the commands stopped, and joint damping (config/cell.yaml
hold_stiffness, hold_damping). Without a stop position the hold is gravity + damping only (a
brake that lets the arm drift). The hold never commands a torque beyond the drives' limits.
"""

from dual_arm_control.core.passive_control import hold_torque
import numpy as np


def hold_command(gravity, position, velocity, damping, stiffness, stop_position, limits,
                 gravity_compensated=False):
    """
    Return the (7,) joint torque command [N m] of the safety hold, within the limits.

    gravity: (7,) gravity torque [N m]; position, velocity: the joints [rad, rad/s]; damping
    [N m s/rad], stiffness [N m/rad] (7,); stop_position (7,) [rad] or None (no stiffness);
    limits (7,) [N m]. gravity_compensated: the robot adds gravity to the command itself, so
    the gravity term is left out (and the limits apply to the sum). The command is clipped so
    the drives never see a torque beyond their limits, as the robot's own hold would.
    """
    torque = hold_torque(gravity, velocity, damping)
    if stop_position is not None:
        torque = torque + np.asarray(stiffness) * (np.asarray(stop_position) - position)
    torque = np.clip(torque, -limits, limits)
    return torque - gravity if gravity_compensated else torque
