# Copyright 2026 polarization_compass developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Launch the simulation graph with robot_localization's ekf_node fusing the heading.

The sim graph (sky_simulator -> estimators -> correctors -> error_evaluator, on sim time) plus
robot_localization's ekf_node with the shipped config/ekf_heading_example.yaml: the simulator's
wheel odometry (odometry/wheel: the turn's yaw rate with a bias and noise, and odom -> base_link on
/tf) and the compass heading in, /odometry/filtered out; the evaluator scores it as stream
<method>/fused beside the raw and corrected headings. Ends when the simulator finishes.

    ros2 launch polarization_compass fusion.launch.py [fuse:=tilt_aware] [pitch_deg:=-20.0] ...

Needs robot_localization (ros-<distro>-robot-localization; here ../shared/ros-cpp). See
docs/ros.md, "Fusing the heading".

Nodes started with the default arguments (generated from polarization_compass.graphs;
test/test_launch_docs.py keeps this list current; `--show-args` lists the arguments):

    sky_simulator      sky_simulator
    heading_estimator  heading_estimator_least_squares
    heading_estimator  heading_estimator_tilt_aware
    tilt_corrector     tilt_corrector_least_squares
    error_evaluator    error_evaluator
    ekf_node           ekf_filter_node

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""


def generate_launch_description():
    from polarization_compass.graphs import launch_description

    return launch_description('fusion')
