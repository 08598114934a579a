"""
ROS-free runtime: the step objects of each node role, their schedule and their policies.

Nodes (rclpy shells) and the in-process runner are both built from these pieces, so a graph run
and an in-process run of the same scenario and seed are the same episode.
"""
