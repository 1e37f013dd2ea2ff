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

Nothing outside ``cli/`` imports ``cli/`` (issue 23, one road): the bench and the tests' helper
modules use the core (:mod:`polarization_compass.headings` turns an input into headings); only the
tests of the command line (``test/test_*.py``) import it, and running the command as a program
(``python -m polarization_compass.cli`` in a subprocess) is not an import.

The graph is read from the source with :mod:`ast`, not by importing, so a module that is never
imported in the test run is checked too.
"""

import ast
from pathlib import Path

import pytest

PKG = 'polarization_compass'
REPO = Path(__file__).resolve().parents[1]
ROOT = REPO / PKG
ADAPTERS = ('nodes', 'cli')
#: calls that import the module their first argument names
IMPORT_CALLS = ('import_module', 'optional_import', '__import__')


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


def imported_names(path: Path) -> set[str]:
    """
    List the absolute module names a file outside the package imports, anywhere in its body.

    ``import a.b``, ``from a.b import c`` (as ``a.b`` and ``a.b.c``) and calls such as
    ``importlib.import_module('a.b')`` with a literal name (:data:`IMPORT_CALLS`).

    Parameters
    ----------
    path : Path
        A Python file (not in the package: relative imports are not resolved).

    Returns
    -------
    set of str
        The imported names.

    """
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
            names.update(f'{node.module}.{a.name}' for a in node.names)
        elif isinstance(node, ast.Call) and node.args:
            f = node.func
            fname = f.attr if isinstance(f, ast.Attribute) else getattr(f, 'id', '')
            arg = node.args[0]
            if fname in IMPORT_CALLS and isinstance(arg, ast.Constant):
                names.add(str(arg.value))
    return names


def cli_importers(files) -> list[str]:
    """Files (outside the package) that import ``polarization_compass.cli`` or a module of it."""
    cli = f'{PKG}.cli'
    return sorted(
        str(f)
        for f in files
        if any(n == cli or n.startswith(cli + '.') for n in imported_names(f))
    )


def users_of_the_core(repo: Path = REPO) -> list[Path]:
    """Files outside the package that must not import the CLI: ``bench/`` and the test helpers."""
    helpers = [p for p in (repo / 'test').glob('*.py') if not p.name.startswith('test_')]
    return sorted(repo.glob('bench/**/*.py')) + sorted(helpers)


def test_nothing_outside_the_cli_imports_it():
    files = users_of_the_core()
    assert any(f.name == 'disc_golden.py' for f in files)  # the checked set is not empty
    assert any(f.parent.name == 'bench' for f in files)
    assert cli_importers(files) == []


def test_the_cli_check_sees_every_form_of_import(tmp_path):
    """The checker itself: planted imports of the CLI in each form are reported, a run is not."""
    (tmp_path / 'test').mkdir()
    (tmp_path / 'bench').mkdir()
    planted = {
        'bench/a.py': f'def f():\n    from {PKG}.cli.cmd_estimate import run\n',
        'bench/b.py': f'import {PKG}.cli\n',
        'bench/c.py': f'from {PKG} import cli\n',
        'bench/d.py': f"import importlib\nimportlib.import_module('{PKG}.cli.cmd_sim')\n",
        'test/helper.py': f"optional_import('{PKG}.cli')\n",
    }
    allowed = {
        'bench/run.py': f"import subprocess\nsubprocess.run(['python', '-m', '{PKG}.cli'])\n",
        'bench/core.py': f'from {PKG}.headings import estimate_file\nfrom {PKG} import climate\n',
        'test/test_cli.py': f'from {PKG}.cli import main\n',
    }
    for rel, text in {**planted, **allowed}.items():
        (tmp_path / rel).write_text(text)
    files = users_of_the_core(tmp_path)
    assert str(tmp_path / 'test' / 'test_cli.py') not in map(str, files)
    assert cli_importers(files) == sorted(str(tmp_path / rel) for rel in planted)


@pytest.mark.parametrize('adapter', ADAPTERS)
def test_the_adapters_exist(adapter):
    """Guard against a renamed package making the layer test vacuous."""
    graph = import_graph()
    assert any(m.startswith(f'{PKG}.{adapter}.') for m in graph)
