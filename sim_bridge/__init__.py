"""MuJoCo digital twin of the two FRI-connected iiwa arms and its ROS 2 bridge node."""
