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
The single description of each node graph (ROS-free).

``launch/sim.launch.py``, ``compass.launch.py`` and ``replay.launch.py`` build their
LaunchDescription from here, and ``polarization-compass sim`` (``make sim``) starts the very same
graph as subprocesses without ``ros2 launch`` (:meth:`NodeSpec.command`). A graph lists its nodes:
executable (a console script of ``setup.py``), node name, namespace, parameter files (paths in the
package's share directory), inline parameters (applied after the files) and remappings, plus the
topics each node publishes and subscribes to (from :mod:`polarization_compass.specs.topics`, the
names the node code itself uses) so that the wiring can be checked without running anything.

Graphs
------
``sim``      sky_simulator -> one heading_estimator per method -> one tilt_corrector per paper
             method -> error_evaluator; sim time from the simulator's ``/clock``.
``compass``  a real camera and IMU: one heading_estimator (``method``) and its tilt_corrector;
             the input topics are launch arguments (remappings).
``replay``   ``ros2 bag play --clock`` of a recorded run: the sim graph without the simulator,
             ``use_sim_time`` on, the site from the bag's NavSatFix.
``fusion``   the sim graph plus robot_localization's ``ekf_node`` configured from the shipped
             ``config/ekf_heading_example.yaml``: the simulator's wheel odometry and a compass
             heading fused; the evaluator scores ``/odometry/filtered`` too.

Launch arguments are strings (as ``ros2 launch`` passes them); :func:`build` parses them with the
types of :data:`ARGUMENTS`.

"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
import os
from pathlib import Path
import shutil
import sys

import yaml

from .errors import CompassError
from .estimators import registry
from .specs import topics as T
from .specs.params import ALL_METHODS, PAPER_METHODS, SUN_PARAMS

__all__ = [
    'PACKAGE',
    'LaunchArg',
    'NodeSpec',
    'Graph',
    'ARGUMENTS',
    'build',
    'sim_graph',
    'compass_graph',
    'replay_graph',
    'fusion_graph',
    'EKF_CONFIG',
    'share_dir',
    'GraphError',
    'parse_arg',
    'GRAPH_NAMES',
    'FASTDDS_PROFILE',
    'STOP_TIMEOUT_S',
    'SIGKILL_TIMEOUT_S',
]

