"""Live replay of a recorded run: every estimator, corrector and the evaluator on sim time.

    ros2 launch polarization_compass replay.launch.py report_dir:=out/replay
    ros2 bag play RUN_BAG --clock      # in a second terminal

The offline equivalent (no ROS install needed): `polarization-compass replay RUN_BAG`.

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""


def generate_launch_description():
    from polarization_compass.graphs import launch_description
    return launch_description("replay")
