"""Dual-arm grabbing with impact and tossing (Bombile and Billard 2022) for ROS 2 Jazzy."""
