"""The ROS 2 bridge of dms: one robot's Zenoh keys as ROS 2 topics (docs/ros2.md).

It runs in an environment of its own (``dms ros2`` makes it) and imports nothing of
dms: it knows the keys and their JSON from the public contract.
"""
