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

"""The ``ros2 launch`` description of each graph (``launch/<name>.launch.py``)."""

from __future__ import annotations

import os

from .arguments import ARGUMENTS, parse_arg
from .build import build
from .paths import share_dir
from .spec import (
    FASTDDS_PROFILE,
    GRAPH_NAMES,
    GraphError,
    LaunchArg,
    SIGKILL_TIMEOUT_S,
    STOP_TIMEOUT_S,
)


def launch_description(name: str):
    """
    Return the LaunchDescription of graph ``name`` (used by ``launch/<name>.launch.py``).

    Declares the graph's launch arguments (plus ``large_image_transport``); the nodes are built
    from :func:`build` once the arguments are known (an OpaqueFunction), with the parameter files
    of the installed share directory. When the graph names a node whose exit ends it (the simulator
    with exit_when_done), the launch shuts down with it.

    * ``large_image_transport`` (every graph, default true) points Fast DDS at
      config/fastdds_large_images.xml for the launched nodes unless FASTDDS_DEFAULT_PROFILES_FILE
      is set; the camera driver must publish with the same profile (without it a full-resolution
      camera's best-effort images are lost in fragments: issue 15, docs/ros.md).
    * Every node gets ``sigterm_timeout`` = :data:`STOP_TIMEOUT_S` (the wait of
      ``polarization-compass sim``) and ``sigkill_timeout`` = :data:`SIGKILL_TIMEOUT_S` instead of
      launch's 5 s and 5 s: the evaluator draws its report figure when it stops and ten processes
      share two cores here.

    Parameters
    ----------
    name : str
        One of :data:`GRAPH_NAMES`.

    Returns
    -------
    launch.LaunchDescription
        The argument declarations and the OpaqueFunction that starts the nodes.

    Raises
    ------
    MissingDependencyError
        ``launch`` or ``launch_ros`` is not installed (a ROS 2 install has them).
    GraphError
        Unknown graph; when the launch runs, a bad argument or an inconsistent graph (one line).

    """
    from ..errors import MissingDependencyError

    try:
        from launch import LaunchDescription
        from launch.actions import (
            DeclareLaunchArgument,
            EmitEvent,
            OpaqueFunction,
            RegisterEventHandler,
            SetEnvironmentVariable,
        )
        from launch.event_handlers import OnProcessExit
        from launch.events import Shutdown
        from launch.substitutions import LaunchConfiguration
        from launch_ros.actions import Node
    except ImportError:
        raise MissingDependencyError(
            'ros2 launch (launch, launch_ros)',
            'ros-<distro>-launch-ros (e.g. sudo apt install ros-jazzy-launch-ros); '
            "here, 'polarization-compass sim' runs the sim graph without it",
        ) from None
    if name not in ARGUMENTS:
        raise GraphError(f'unknown graph {name!r}; known: {", ".join(GRAPH_NAMES)}')
    actions = [
        DeclareLaunchArgument(
            a.name,
            default_value=a.default,
            description=a.description + (f' ({", ".join(a.choices)})' if a.choices else ''),
        )
        for a in ARGUMENTS[name]
    ]
    actions.append(
        DeclareLaunchArgument(
            'large_image_transport',
            default_value='true',
            description="set FASTDDS_DEFAULT_PROFILES_FILE to the package's shared-memory profile "
            'for '
            'full-resolution images (unless already set); false when the camera is on another '
            'machine: the profile carries data over shared memory only',
        )
    )

    def make_nodes(context, *_, **__):
        values = {a.name: LaunchConfiguration(a.name).perform(context) for a in ARGUMENTS[name]}
        graph = build(name, values)
        problems = graph.check()
        if problems:
            raise GraphError('inconsistent graph: ' + '; '.join(problems))
        share = share_dir()
        out = []
        if parse_arg(
            LaunchArg('large_image_transport', 'true', '', 'bool'),
            LaunchConfiguration('large_image_transport').perform(context),
        ) and not os.environ.get('FASTDDS_DEFAULT_PROFILES_FILE'):
            out.append(
                SetEnvironmentVariable(
                    'FASTDDS_DEFAULT_PROFILES_FILE', str(share / FASTDDS_PROFILE)
                )
            )
        by_name = {}
        for n in graph.nodes:
            node = Node(
                package=n.package,
                executable=n.executable,
                name=n.name,
                namespace=n.namespace or None,
                parameters=[str(share / f) for f in n.param_files] + [dict(n.parameters)],
                remappings=list(n.remappings),
                output='screen',
                emulate_tty=True,
                # a node stops in < 1 s, the evaluator draws its figure first, ten processes
                # share two cores: launch's default 5 s before SIGTERM was too short (issue 15)
                sigterm_timeout=str(STOP_TIMEOUT_S),
                sigkill_timeout=str(SIGKILL_TIMEOUT_S),
            )
            by_name[n.name] = node
            out.append(node)
        if graph.shutdown_with:
            out.append(
                RegisterEventHandler(
                    OnProcessExit(
                        target_action=by_name[graph.shutdown_with],
                        on_exit=[
                            EmitEvent(event=Shutdown(reason=f'{graph.shutdown_with} finished'))
                        ],
                    )
                )
            )
        return out

    actions.append(OpaqueFunction(function=make_nodes))
    return LaunchDescription(actions)
