"""ROS 2 nodes: thin rclpy adapters over the ROS-free layers below.

Every module here may import rclpy and the message packages; nothing outside ``nodes`` imports
this package (``test/test_layers.py`` checks it). The node specifications they read (parameters,
topics, graphs) live in :mod:`polarization_compass.specs`, shared with the launch files,
``polarization-compass sim`` and the replay.
"""
