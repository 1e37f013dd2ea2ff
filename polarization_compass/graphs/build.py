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

"""A graph by name from launch-argument strings (:func:`build`), and the nodes it starts."""

from __future__ import annotations

from .arguments import ARGUMENTS, parse_arg
from .compass import compass_graph
from .fusion import fusion_graph
from .replay import replay_graph
from .sim import sim_graph
from .spec import Graph, GRAPH_NAMES, GraphError


def build(name: str, args: dict | None = None) -> Graph:
    """
    Return the graph ``name`` for launch arguments ``args``.

    Parameters
    ----------
    name : str
        One of :data:`GRAPH_NAMES`.
    args : dict, optional
        ``{argument: text}`` (strings, as ``ros2 launch`` passes them); missing ones take their
        default.

    Returns
    -------
    Graph
        The graph (not yet checked: see :meth:`Graph.check`).

    Raises
    ------
    GraphError
        Unknown graph or argument, or an argument that :func:`parse_arg` refuses.

    """
    if name not in ARGUMENTS:
        raise GraphError(f'unknown graph {name!r}; known: {", ".join(GRAPH_NAMES)}')
    args = dict(args or {})
    specs = {a.name: a for a in ARGUMENTS[name]}
    unknown = set(args) - set(specs)
    if unknown:
        raise GraphError(
            f'graph {name!r} has no launch argument(s) {sorted(unknown)}; '
            f'known: {", ".join(sorted(specs))}'
        )
    values = {k: parse_arg(a, args.get(k, a.default)) for k, a in specs.items()}
    return {
        'sim': sim_graph,
        'compass': compass_graph,
        'replay': replay_graph,
        'fusion': fusion_graph,
    }[name](**values)


def node_lines(name: str, args: dict | None = None) -> list[str]:
    """
    Return one line per node that graph ``name`` starts: executable and name.

    The launch files quote this list (with the default arguments) in their docstrings, so that a
    reader sees what a launch starts without running it; ``test/test_launch_docs.py`` keeps the
    quoted lists equal to the generated graphs.

    Parameters
    ----------
    name : str
        One of :data:`GRAPH_NAMES`.
    args : dict, optional
        Launch arguments as for :func:`build`.

    Returns
    -------
    list of str
        ``"<executable> [/<namespace>/]<node name>"`` per node.

    """
    return [
        f'{n.executable:<18} {("/" + n.namespace.strip("/") + "/") if n.namespace else ""}{n.name}'
        for n in build(name, args).nodes
    ]
