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
Each launch file shows, in its docstring, the nodes it starts with the default arguments.

The generated graph (:mod:`polarization_compass.graphs`) stays the single source of the nodes; the
list in the docstring is a copy for readers, and this test fails as soon as the two differ (a node
added, removed or renamed in the graph without the launch file's docstring following).
"""

import ast
from pathlib import Path

from polarization_compass import graphs
import pytest

LAUNCH_DIR = Path(__file__).resolve().parents[1] / 'launch'
HEADING = 'Nodes started with the default arguments'


def quoted_nodes(path: Path) -> list[str]:
    """Return the indented block after the docstring's HEADING paragraph, whitespace-normalised."""
    doc = ast.get_docstring(ast.parse(path.read_text()), clean=True) or ''
    lines = doc.splitlines()
    starts = [i for i, line in enumerate(lines) if line.startswith(HEADING)]
    assert len(starts) == 1, f'{path.name}: expected one "{HEADING}" paragraph'
    i = starts[0]
    while i < len(lines) and lines[i].strip():  # the rest of the heading paragraph
        i += 1
    out = []
    for line in lines[i + 1 :]:
        if not line.startswith('    '):
            break
        out.append(' '.join(line.split()))
    return out


@pytest.mark.parametrize('name', graphs.GRAPH_NAMES)
def test_launch_docstring_lists_the_generated_nodes(name):
    path = LAUNCH_DIR / f'{name}.launch.py'
    expected = [' '.join(line.split()) for line in graphs.node_lines(name)]
    assert quoted_nodes(path) == expected


def test_every_launch_file_is_a_graph():
    assert sorted(p.name for p in LAUNCH_DIR.glob('*.launch.py')) == sorted(
        f'{n}.launch.py' for n in graphs.GRAPH_NAMES
    )


def test_a_changed_graph_is_noticed(tmp_path, monkeypatch):
    """The check fails when the graph gains a node the docstring does not list."""
    path = LAUNCH_DIR / 'compass.launch.py'
    listed = quoted_nodes(path)
    real = graphs.node_lines
    monkeypatch.setattr(graphs, 'node_lines', lambda n, a=None: real(n, a) + ['extra  extra_node'])
    assert quoted_nodes(path) == listed
    assert [' '.join(x.split()) for x in graphs.node_lines('compass')] != listed
