"""
ROS-free core: paper equations as plain NumPy, pinocchio and proxsuite code.

Nothing in this package imports rclpy or message types; nodes translate messages to the
arrays and config objects defined here.
"""
