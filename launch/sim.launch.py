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
Launch the simulation graph on sim time.

The simulation graph: sky_simulator -> heading_estimator per method -> tilt_corrector per paper
method -> error_evaluator, on sim time from the simulator's /clock. Ends when the simulator
finishes (exit_when_done).

    ros2 launch polarization_compass sim.launch.py [methods:=zenith,least_squares]
    [lockstep:=false] ...

Lockstep by default (every frame processed: the README table on any machine); lockstep:=false runs
in real time and measures drops and latency. Every node gets 20 s to stop after SIGINT before
SIGTERM (graphs.STOP_TIMEOUT_S, see docs/ros.md "Starting and stopping"). attitude_source:=tf
renders from TF (tf2_ros) with the simulated motion broadcast there, no wheel odometry (docs/ros.md
"Attitude from TF"); the default, motion, renders frames ahead.

Without ros2 launch (e.g. a pip-only install): `polarization-compass sim` starts the same graph.

Nodes started with the default arguments (generated from polarization_compass.graphs;
test/test_launch_docs.py keeps this list current; `--show-args` lists the arguments):

    sky_simulator      sky_simulator
    heading_estimator  heading_estimator_zenith
    heading_estimator  heading_estimator_sm_asm
    heading_estimator  heading_estimator_symmetry
    heading_estimator  heading_estimator_least_squares
    heading_estimator  heading_estimator_tilt_aware
    tilt_corrector     tilt_corrector_zenith
    tilt_corrector     tilt_corrector_sm_asm
    tilt_corrector     tilt_corrector_symmetry
    tilt_corrector     tilt_corrector_least_squares
    error_evaluator    error_evaluator

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""


def generate_launch_description():
    from polarization_compass.graphs import launch_description

    return launch_description('sim')
