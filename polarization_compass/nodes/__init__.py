"""ROS 2 nodes (thin adapters over the core library).

Importing this package does not import rclpy: :mod:`.topics` and :mod:`.params` are ROS-free and
are shared with :mod:`polarization_compass.graphs`, the launch files and ``polarization-compass sim``.
The node modules (``sky_simulator``, ``heading_estimator``, ``tilt_corrector``, ``error_evaluator``)
and :mod:`.msgs` / :mod:`.diagnostics` / :mod:`.rosparams` need rclpy and the message packages.
"""
