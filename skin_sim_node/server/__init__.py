"""The ROS 2 haptic server: the node and its display worker."""
