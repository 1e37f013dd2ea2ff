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
The package's import graph points downwards only (issue 13).

Layers: the core and the ROS-free applications (everything outside ``nodes`` and ``cli``) never
import the adapters; ``nodes`` (rclpy) and ``cli`` do not import each other; and no two modules
import each other, directly or through others, counting imports inside functions too (a lazy
import that closes a cycle is still a cycle in the design).

The graph is read from the source with :mod:`ast`, not by importing, so a module that is never
imported in the test run is checked too.
"""

import ast
from pathlib import Path

import pytest

PKG = 'polarization_compass'
ROOT = Path(__file__).resolve().parents[1] / PKG
ADAPTERS = ('nodes', 'cli')


def _module_name(path: Path, root: Path = ROOT) -> str:
    rel = path.relative_to(root.parent).with_suffix('')
    parts = list(rel.parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """Return the absolute module a ``from ... import`` names (relative levels resolved)."""
    if node.level == 0:
        return node.module or ''
    base = module.split('.')
    if not is_package:
        base = base[:-1]
    if node.level > 1:
        base = base[: len(base) - (node.level - 1)]
    return '.'.join(base + ([node.module] if node.module else []))


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """Map each module of the package to the package modules it imports (anywhere in its body)."""
    files = {_module_name(p, root): p for p in root.rglob('*.py')}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        is_package = path.name == '__init__.py'
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(name, is_package, node)
                # `from pkg import mod` imports the submodule pkg.mod when it exists
                targets = [base] + [f'{base}.{a.name}' for a in node.names]
            for t in targets:
                # the deepest package module that the target names
                while t and t not in files:
                    t = t.rpartition('.')[0]
                # a module's own parent packages are imported before it anyway: not an edge
                if t.startswith(PKG) and t != name and not name.startswith(t + '.'):
                    deps.add(t)
        graph[name] = deps
    return graph


def _layer(module: str) -> str:
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and parts[1] in ADAPTERS else 'core'


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """Edges that point upwards (core -> adapter) or sideways between the adapters."""
    bad = []
    for mod, deps in sorted(graph.items()):
        for dep in sorted(deps):
            src, dst = _layer(mod), _layer(dep)
            if dst != 'core' and dst != src:
                bad.append(f'{mod} -> {dep}')
    return bad


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_module_below_the_adapters_imports_them():
    assert layer_violations(import_graph()) == []


def test_no_import_cycles():
    assert cycles(import_graph()) == []


def test_the_checks_see_an_upward_import_and_a_cycle(tmp_path):
    """The checker itself: a planted upward import and a planted cycle are both reported."""
    pkg = tmp_path / PKG
    (pkg / 'nodes').mkdir(parents=True)
    (pkg / '__init__.py').write_text('')
    (pkg / 'nodes' / '__init__.py').write_text('')
    (pkg / 'nodes' / 'n.py').write_text('import rclpy\n')
    (pkg / 'a.py').write_text('def f():\n    from .b import g\n')
    (pkg / 'b.py').write_text('from . import a\n')
    (pkg / 'core.py').write_text('from .nodes import n\n')
    graph = import_graph(pkg)
    assert layer_violations(graph) == [
        f'{PKG}.core -> {PKG}.nodes',
        f'{PKG}.core -> {PKG}.nodes.n',
    ]
    assert cycles(graph) == [[f'{PKG}.a', f'{PKG}.b']]


@pytest.mark.parametrize('adapter', ADAPTERS)
def test_the_adapters_exist(adapter):
    """Guard against a renamed package making the layer test vacuous."""
    graph = import_graph()
    assert any(m.startswith(f'{PKG}.{adapter}.') for m in graph)
