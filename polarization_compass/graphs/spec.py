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
The types that describe a node graph: :class:`LaunchArg`, :class:`NodeSpec`, :class:`Graph`.

Also the constants every graph and its runners share: the package name, the graph names, the Fast
DDS profile and the stop timeouts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..errors import CompassError
from ..specs import topics as T
from ..specs.params import SUN_PARAMS

PACKAGE = 'polarization_compass'
GRAPH_NAMES = ('sim', 'compass', 'replay', 'fusion')
#: Fast DDS profile for full-resolution images on one machine (shared memory with a large segment):
#: with the default transports, best-effort 10 MB images are lost in fragments. Used by
#: ``polarization-compass sim`` and the tests; optional on a robot (docs/ros.md).
FASTDDS_PROFILE = 'config/fastdds_large_images.xml'
#: Seconds a node gets to stop after SIGINT before SIGTERM (then SIGKILL after SIGKILL_TIMEOUT_S
#: more): ``sigterm_timeout`` of every launched node and the wait of ``polarization-compass sim``.
#: A node stops in well under a second (nodes.runner), but the evaluator draws its report figure at
#: the end and ten processes share two cores here: launch's default of 5 s was measured too short
#: (issue 15).
STOP_TIMEOUT_S = 20.0
SIGKILL_TIMEOUT_S = 5.0


#: ``attitude_source`` of the sim graph (the simulator's ``topic`` needs a publisher outside it)
SIM_ATTITUDE_SOURCES = ('motion', 'tf')


class GraphError(CompassError):
    """Unknown graph, bad launch argument or an inconsistent graph."""


@dataclass(frozen=True)
class LaunchArg:
    """
    Describe one launch argument of a graph (a string, as ``ros2 launch`` passes it).

    Parameters
    ----------
    name : str
        Argument name, units in the name (e.g. ``rate_hz``).
    default : str
        Default text.
    description : str
        Meaning, shown by ``ros2 launch --show-args``.
    kind : {"str", "bool", "float", "int", "list"}, default "str"
        How :func:`parse_arg` reads the text (``list``: comma separated).
    choices : tuple of str, default ()
        Allowed values (for a list: allowed items).

    """

    name: str
    default: str
    description: str
    kind: str = 'str'  # str | bool | float | int | list (comma separated)
    choices: tuple = ()


@dataclass(frozen=True)
class NodeSpec:
    """
    Describe one node of a graph.

    Parameters
    ----------
    executable : str
        Console script of ``setup.py``, e.g. ``"heading_estimator"``.
    name : str
        Node name.
    namespace : str, default ""
        Node namespace ("" = root).
    param_files : tuple of str, default ()
        Parameter files, paths in the package's share directory.
    parameters : dict, default {}
        Inline parameters, applied after the files.
    remappings : tuple of tuple of str, default ()
        ``((from, to), ...)`` topic remappings.
    publishes, subscribes : tuple of tuple of str, default ()
        ``((topic, type), ...)`` before remapping (the names of
        :mod:`polarization_compass.specs.topics`).
    package : str, default "polarization_compass"
        ROS package of the executable.

    """

    executable: str
    name: str
    namespace: str = ''
    param_files: tuple = ()
    parameters: dict = field(default_factory=dict)
    remappings: tuple = ()  # ((from, to), ...)
    publishes: tuple = ()  # ((topic, type), ...)
    subscribes: tuple = ()
    package: str = PACKAGE

    def remap(self, topic: str) -> str:
        """
        Return a topic's name after this node's remappings (namespace not applied).

        Parameters
        ----------
        topic : str
            Topic name as the node code uses it.

        Returns
        -------
        str
            The remapped name, or ``topic`` when no remapping names it.

        """
        for a, b in self.remappings:
            if a == topic:
                return b
        return topic

    def resolved(self, topic: str) -> str:
        """
        Return the absolute name of a (possibly relative) topic after remapping and namespacing.

        Parameters
        ----------
        topic : str
            Topic name as the node code uses it.

        Returns
        -------
        str
            Absolute topic name, e.g. ``"/array/imu/data"``.

        """
        t = self.remap(topic)
        if t.startswith('/'):
            return t
        ns = self.namespace.strip('/')
        if t.startswith('~/'):  # node-private: under the node's own name
            t = f'{self.name}/{t[2:]}'
        return f'/{ns}/{t}' if ns else f'/{t}'

    def resolved_publishes(self) -> list[tuple[str, str]]:
        """
        Return the topics this node publishes, resolved (:meth:`resolved`).

        Returns
        -------
        list of tuple of str
            ``(absolute topic, type)`` pairs.

        """
        return [(self.resolved(t), ty) for t, ty in self.publishes]

    def resolved_subscribes(self) -> list[tuple[str, str]]:
        """
        Return the topics this node subscribes to, resolved (:meth:`resolved`).

        Returns
        -------
        list of tuple of str
            ``(absolute topic, type)`` pairs.

        """
        return [(self.resolved(t), ty) for t, ty in self.subscribes]

    def ros_arguments(self, share: Path) -> list[str]:
        """
        Return the ``--ros-args ...`` to run the executable directly, as ``ros2 launch`` would.

        Parameters
        ----------
        share : pathlib.Path
            The package's share directory (:func:`share_dir`), where the parameter files are.

        Returns
        -------
        list of str
            Node name, namespace, ``--params-file`` per file, ``-p name:=value`` per inline
            parameter (YAML scalars) and ``-r from:=to`` per remapping.

        """
        args = ['--ros-args', '-r', f'__node:={self.name}']
        if self.namespace:
            args += ['-r', f'__ns:=/{self.namespace.strip("/")}']
        for f in self.param_files:
            args += ['--params-file', str(Path(share) / f)]
        for k, v in self.parameters.items():
            args += ['-p', f'{k}:={_yaml_scalar(v)}']
        for a, b in self.remappings:
            args += ['-r', f'{a}:={b}']
        return args


def _yaml_scalar(v) -> str:
    text = yaml.safe_dump(v, default_flow_style=True, width=10_000).strip()
    if text.endswith('\n...'):
        text = text[:-4].strip()
    if text.endswith('...'):
        text = text[:-3].strip()
    return text


@dataclass(frozen=True)
class Graph:
    """
    Describe one node graph: its nodes and what it expects from outside.

    Parameters
    ----------
    name : str
        Graph name (one of :data:`GRAPH_NAMES`).
    description : str
        One-line description.
    nodes : tuple of NodeSpec
        The nodes.
    external_inputs : tuple of str, default ()
        Absolute topics expected from outside the graph (a camera driver, ``ros2 bag play``).
    shutdown_with : str, optional
        Name of the node whose exit ends the whole graph.

    """

    name: str
    description: str
    nodes: tuple
    external_inputs: tuple = ()  # absolute topics expected from outside the graph
    shutdown_with: str | None = None  # node name whose exit ends the whole graph

    def node(self, name: str) -> NodeSpec:
        """
        Return the node named ``name``.

        Parameters
        ----------
        name : str
            Node name.

        Returns
        -------
        NodeSpec
            The node.

        Raises
        ------
        GraphError
            The graph has no such node.

        """
        for n in self.nodes:
            if n.name == name:
                return n
        raise GraphError(f'graph {self.name!r} has no node {name!r}')

    def published_topics(self) -> dict:
        """
        Return every topic the graph's nodes publish, resolved, with its types.

        Returns
        -------
        dict
            ``{absolute topic: set of types}``.

        """
        out: dict = {}
        for n in self.nodes:
            for t, ty in n.resolved_publishes():
                out.setdefault(t, set()).add(ty)
        return out

    def check(self) -> list[str]:
        """
        Return the wiring problems of the graph.

        A subscription nobody in the graph (or outside it) publishes, a topic with two types,
        duplicate node names, a corrector whose site (gps/fix or parameters) is not its
        estimator's.

        Returns
        -------
        list of str
            One line per problem; empty when the graph is consistent.

        """
        problems = []
        names = [(n.namespace, n.name) for n in self.nodes]
        if len(set(names)) != len(names):
            problems.append('duplicate node names')
        pubs = self.published_topics()
        for t, types in pubs.items():
            if len(types) > 1:
                problems.append(f'{t} is published with several types {sorted(types)}')
        for n in self.nodes:
            for t, ty in n.resolved_subscribes():
                if t in self.external_inputs:
                    continue
                if t not in pubs:
                    problems.append(
                        f'{n.name} subscribes to {t}, which nothing in graph {self.name!r} '
                        'publishes'
                    )
                elif ty not in pubs[t]:
                    problems.append(
                        f'{n.name} subscribes to {t} as {ty}, published as {sorted(pubs[t])}'
                    )

        # the corrector computes the sun (error-map lookup) for the site its estimator used
        def fix(n):
            return n.resolved(T.FIX) if any(t == T.FIX for t, _ in n.subscribes) else None

        estimators = {
            (n.namespace, n.parameters.get('method')): n
            for n in self.nodes
            if n.executable == 'heading_estimator'
        }
        for n in self.nodes:
            est = estimators.get((n.namespace, n.parameters.get('method')))
            if n.executable == 'tilt_corrector' and est is not None and fix(n) != fix(est):
                problems.append(
                    f'{n.name} takes the site from {fix(n) or "its parameters"} but {est.name} '
                    'from '
                    f'{fix(est) or "its parameters"}: set the same site_source and fix topic'
                )
            if n.executable == 'tilt_corrector' and est is not None:
                differ = [
                    k
                    for k in SUN_PARAMS + ('site_source',)
                    if n.parameters.get(k) != est.parameters.get(k)
                ]
                if differ:
                    problems.append(f'{n.name} and {est.name} set different {", ".join(differ)}')
        return problems
