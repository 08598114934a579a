"""The rclpy node shells: they translate messages and parameters and call the core."""
