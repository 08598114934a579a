"""
MCAP bags in the rosbag2 layout: message definitions, a writer, a recorder and an inspector.

Files are readable by rosbag2's MCAP storage plugin, Foxglove and rosbags: profile 'ros2',
schemas in 'ros2msg' encoding with every dependency, 'cdr' messages and QoS channel metadata.
"""

from dual_arm_control.core.exceptions import DualArmControlError


class BagError(DualArmControlError):
    """A bag cannot be written or read; the message names the file and the problem."""
