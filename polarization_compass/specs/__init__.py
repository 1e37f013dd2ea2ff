"""ROS-free specifications of the nodes: parameters (:mod:`.params`) and topics (:mod:`.topics`).

The nodes (:mod:`polarization_compass.nodes`), the graph description
(:mod:`polarization_compass.graphs`), the launch files, ``polarization-compass sim`` and the
replay all read these; none of them imports rclpy.
"""
