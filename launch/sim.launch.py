"""The simulation graph: sky_simulator -> heading_estimator per method -> tilt_corrector per paper method
-> error_evaluator, on sim time from the simulator's /clock. Ends when the simulator finishes (exit_when_done).

    ros2 launch polarization_compass sim.launch.py [methods:=zenith,least_squares] [lockstep:=true] ...

Without ros2 launch (e.g. a pip-only install): `polarization-compass sim` starts the same graph.

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""


def generate_launch_description():
    from polarization_compass.graphs import launch_description
    return launch_description("sim")
