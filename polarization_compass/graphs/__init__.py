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

The package holds the description types (:mod:`.spec`), the launch arguments (:mod:`.arguments`),
the node specifications the graphs share (:mod:`.node_specs`), one module per graph (:mod:`.sim`,
:mod:`.compass`, :mod:`.replay`, :mod:`.fusion`), :func:`build` (:mod:`.build`), where the files
and executables are (:mod:`.paths`) and the ``ros2 launch`` description (:mod:`.ros_launch`); the
names below are its documented surface.
"""

from .arguments import ARGUMENTS, parse_arg
from .build import build, node_lines
from .compass import compass_graph
from .fusion import EKF_CONFIG, EKF_NODE, fusion_graph
from .paths import node_command, share_dir
from .replay import replay_graph
from .ros_launch import launch_description
from .sim import sim_graph
from .spec import (
    FASTDDS_PROFILE,
    Graph,
    GRAPH_NAMES,
    GraphError,
    LaunchArg,
    NodeSpec,
    PACKAGE,
    SIGKILL_TIMEOUT_S,
    STOP_TIMEOUT_S,
)

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
    'EKF_NODE',
    'node_command',
    'node_lines',
    'launch_description',
]
