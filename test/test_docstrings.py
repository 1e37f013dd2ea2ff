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
Docstrings of public functions say parameters, returns and what they raise (issue 13).

The style is numpydoc as pvlib writes it: a one-line summary ending with a period, a blank line,
then ``Parameters``, ``Returns``, ``Raises`` and ``References`` sections. For every module in
:data:`COMPLETED` (only modules that pass are listed), each public function and each public method
of a public class must have

- a docstring whose first line is a summary ending with a period and is followed by a blank line
  (or is the whole docstring);
- a ``Parameters`` section naming each of its parameters (``self``/``cls`` excepted) when it has
  any;
- a ``Returns`` (or ``Yields``) section when its body returns (or yields) a value;
- a ``Raises`` section naming each exception class its own body raises by name (``raise exc``
  of an exception held in a lower-case variable re-raises an object, not a class, and is not
  counted).

Properties are attributes in numpydoc and need only the summary. The source is read with
:mod:`ast`, not imported, so nothing runs and nested helpers are not counted.

Every docstring of the tree (package, tests, benchmark, tools) is also checked for the damage a
former home-made formatter left (issue 23, :func:`damaged_docstrings`): a summary repeated as the
start of the next paragraph, and a sentence cut with one word left alone on a line.
"""

import ast
import difflib
from pathlib import Path
import re

from lint_paths import python_files, python_paths
import pytest

ROOT = Path(__file__).resolve().parents[1] / 'polarization_compass'

#: Modules whose public functions and methods are documented in full (paths under the package).
COMPLETED = (
    'conventions/__init__.py',
    'conventions/angles.py',
    'conventions/directions.py',
    'conventions/evectors.py',
    'conventions/quaternions.py',
    'conventions/rotations.py',
    'estimators/base.py',
    'estimators/registry.py',
    'estimators/zenith.py',
    'estimators/sm_asm.py',
    'estimators/symmetry.py',
    'estimators/least_squares.py',
    'estimators/_ls_sigma.py',
    'estimators/_outlier_trim.py',
    'estimators/sun_from_evectors.py',
    'estimators/jackknife.py',
    'estimators/mosaic_input.py',
    'estimators/__init__.py',
    'errormap.py',
    'errormap_io.py',
    'sweep_cells.py',
    'frame_io.py',
    'headings.py',
    'pipeline/__init__.py',
    'pipeline/attitude.py',
    'pipeline/camera_info.py',
    'pipeline/errors.py',
    'pipeline/front_end.py',
    'pipeline/methods.py',
    'pipeline/optical_centre.py',
    'pipeline/monitors.py',
    'pipeline/prior.py',
    'pipeline/real_image.py',
    'pipeline/sampling.py',
    'pipeline/sun.py',
    'solar.py',
    'solar_paper.py',
    'camera.py',
    'camera_pixels.py',
    'camera_file.py',
    'allowable.py',
    'correction/__init__.py',
    'correction/corrector.py',
    'correction/sensitivity.py',
    'correction/kernels.py',
    'correction/results.py',
    'correction/weights.py',
    'photodiode/geometry.py',
    'photodiode/readings.py',
    'photodiode/stokes.py',
    'photodiode/heading.py',
    'photodiode/knobs.py',
    'photodiode/calibrate.py',
    'photodiode/selfcheck.py',
    'photodiode/simulate.py',
    'mount.py',
    'mount_fit.py',
    'mount_recordings.py',
    'camera_turns.py',
    'demosaic.py',
    'mosaic.py',
    'demosaic_kernels.py',
    'fastmath.py',
    'instrumentation.py',
    'safe_load.py',
    'errors.py',
    'evaluation.py',
    'evaluation_report.py',
    'evaluation_stats.py',
    'motion.py',
    'recording.py',
    'simulated_sensors.py',
    'bag/__init__.py',
    'bag/codec.py',
    'bag/errors.py',
    'bag/image.py',
    'bag/reader.py',
    'bag/recovery.py',
    'bag/topic_map.py',
    'bag/writer.py',
    'specs/params/__init__.py',
    'specs/params/downstream.py',
    'specs/params/estimator.py',
    'specs/params/methods.py',
    'specs/params/simulator.py',
    'specs/params/site_sun.py',
    'specs/params/spec.py',
    'specs/topics.py',
    'graphs/__init__.py',
    'graphs/arguments.py',
    'graphs/build.py',
    'graphs/processes.py',
    'graphs/compass.py',
    'graphs/fusion.py',
    'graphs/node_specs.py',
    'graphs/paths.py',
    'graphs/replay.py',
    'graphs/ros_launch.py',
    'graphs/sim.py',
    'graphs/spec.py',
    'figures/__init__.py',
    'figures/axes.py',
    'figures/curves.py',
    'figures/surfaces.py',
    'figures/tilts.py',
    'plotting.py',
    'replay/__init__.py',
    'replay/outputs.py',
    'replay/processing.py',
    'replay/sync.py',
    'replay/threads.py',
    'sweep.py',
    'sweep_spec.py',
    'skyfit.py',
    'skyfit_assess.py',
    'polarizer_check.py',
    'sky.py',
    'sky_models.py',
    'sky_bdl.py',
    'render.py',
    'scene.py',
    'scene_load.py',
    'real_input.py',
    'errormap_store.py',
    'errormap_dataset.py',
    'errormap_netcdf.py',
    'sensor.py',
    'sensor_kernels.py',
    'sensor_calibration.py',
    'sensor_config.py',
    'rng.py',
    'runtime.py',
    'radiance.py',
    'atmosphere.py',
    'atmosphere_checks.py',
    'clouds.py',
    'clouds_kernels.py',
    'sweep_dask.py',
    'budget.py',
    'budget_config.py',
    'stamp_pairing.py',
    'estimators/speed.py',
    'optics.py',
    'optics_kernels.py',
    'ground.py',
)

#: Private classes whose public methods are the documented ``estimate`` of public estimators
#: (module, class): their methods are checked like those of a public class.
INHERITED_FROM = (
    ('estimators/least_squares.py', '_LSBase'),
    ('estimators/_disc_estimator.py', 'DiscEstimator'),
    ('correction/sensitivity.py', '_AttitudeSensitivity'),
)

_SECTIONS = (
    'Parameters',
    'Returns',
    'Yields',
    'Raises',
    'Warns',
    'See Also',
    'Notes',
    'References',
    'Examples',
    'Attributes',
    'Other Parameters',
    'Methods',
)


def _sections(doc: str) -> dict[str, list[str]]:
    """Split a numpydoc docstring into its underlined sections (title -> body lines)."""
    lines = doc.expandtabs().splitlines()
    out: dict[str, list[str]] = {}
    current = None
    i = 0
    while i < len(lines):
        title = lines[i].strip()
        under = lines[i + 1].strip() if i + 1 < len(lines) else ''
        if title in _SECTIONS and under and set(under) == {'-'} and len(under) >= len(title):
            current = title
            out[current] = []
            i += 2
            continue
        if current is not None:
            out[current].append(lines[i])
        i += 1
    return out


def _entry_names(body: list[str]) -> set[str]:
    """Names that a Parameters/Raises section documents (``a, b : float`` names a and b)."""
    if not body:
        return set()
    indents = [len(x) - len(x.lstrip()) for x in body if x.strip()]
    base = min(indents) if indents else 0
    names: set[str] = set()
    for line in body:
        if not line.strip() or len(line) - len(line.lstrip()) != base:
            continue
        head = line.strip().split(' : ')[0].rstrip(':').strip()
        for part in head.split(','):
            part = part.strip().lstrip('*')
            if re.fullmatch(r'[A-Za-z_][\w.]*', part):
                names.add(part)
    return names


def _own_nodes(func: ast.AST):
    """Nodes of a function's body, not descending into nested functions, lambdas or classes."""
    stack = list(ast.iter_child_nodes(func))
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        yield node
        stack.extend(ast.iter_child_nodes(node))


def _exc_name(node) -> str:
    node = node.func if isinstance(node, ast.Call) else node
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return ''


def _raised_names(func) -> set[str]:
    """Exception classes a function's own body raises by name and does not catch itself."""
    raised: set[str] = set()

    def visit(node, caught):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            return
        if isinstance(node, ast.Raise) and node.exc is not None:
            name = _exc_name(node.exc)
            if isinstance(node.exc, ast.Name) and name[:1].islower():
                name = ''  # re-raises an exception object held in a variable, not a class
            if name and name not in caught and not caught & {'*', 'Exception'}:
                raised.add(name)
        if isinstance(node, ast.Try):
            names = set()
            for h in node.handlers:
                if h.type is None:
                    names.add('*')
                elif isinstance(h.type, ast.Tuple):
                    names |= {_exc_name(e) for e in h.type.elts}
                else:
                    names.add(_exc_name(h.type))
            for child in node.body:
                visit(child, caught | names)
            for child in node.handlers + node.orelse + node.finalbody:
                visit(child, caught)
            return
        for child in ast.iter_child_nodes(node):
            visit(child, caught)

    for stmt in func.body:
        visit(stmt, frozenset())
    return raised


def _is_property(func) -> bool:
    for d in func.decorator_list:
        name = d.attr if isinstance(d, ast.Attribute) else getattr(d, 'id', '')
        if name in ('property', 'cached_property', 'setter'):
            return True
    return False


def check_function(func, qualname: str) -> list[str]:
    """Return what is missing from the docstring of one function or method."""
    problems = []
    doc = ast.get_docstring(func, clean=True)
    if not doc:
        return [f'{qualname}: no docstring']
    lines = doc.splitlines()
    summary = lines[0].strip()
    if not summary or not summary.endswith('.'):
        problems.append(f'{qualname}: summary line does not end with a period: {summary!r}')
    if len(lines) > 1 and lines[1].strip():
        problems.append(f'{qualname}: summary is not one line followed by a blank line')
    if _is_property(func):
        return problems
    sections = _sections(doc)
    a = func.args
    params = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    params += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    params = [p for p in params if p not in ('self', 'cls')]
    if params:
        if 'Parameters' not in sections:
            problems.append(f'{qualname}: parameters {params} but no Parameters section')
        else:
            missing = [p for p in params if p not in _entry_names(sections['Parameters'])]
            if missing:
                problems.append(f'{qualname}: Parameters section does not name {missing}')
    nodes = list(_own_nodes(func))
    returns = any(
        isinstance(n, ast.Return)
        and n.value is not None
        and not (isinstance(n.value, ast.Constant) and n.value.value is None)
        for n in nodes
    )
    yields = any(isinstance(n, (ast.Yield, ast.YieldFrom)) for n in nodes)
    if yields and not ({'Yields', 'Returns'} & set(sections)):
        problems.append(f'{qualname}: yields values but has no Yields section')
    elif returns and 'Returns' not in sections:
        problems.append(f'{qualname}: returns a value but has no Returns section')
    raised = _raised_names(func)
    raised.discard('NotImplementedError')  # an abstract method's body, not a documented failure
    if raised:
        documented = {x.rsplit('.', 1)[-1] for x in _entry_names(sections.get('Raises', []))}
        missing = sorted(raised - documented)
        if missing:
            problems.append(
                f'{qualname}: raises {missing} but its Raises section does not name them'
            )
    return problems


def check_summary(node, qualname: str) -> list[str]:
    """Return the problems of a class docstring's summary line."""
    doc = ast.get_docstring(node, clean=True)
    if not doc:
        return [f'{qualname}: no docstring']
    lines = doc.splitlines()
    problems = []
    if not lines[0].strip().endswith('.'):
        problems.append(f'{qualname}: summary line does not end with a period: {lines[0]!r}')
    if len(lines) > 1 and lines[1].strip():
        problems.append(f'{qualname}: summary is not one line followed by a blank line')
    return problems


def check_source(source: str, name: str = '<source>', classes=()) -> list[str]:
    """
    Return the docstring problems of the public functions, classes and methods of a module.

    ``classes`` names private classes whose public methods are checked too.
    """
    tree = ast.parse(source, name)
    problems = []
    funcs = (ast.FunctionDef, ast.AsyncFunctionDef)
    for node in tree.body:
        if isinstance(node, funcs) and not node.name.startswith('_'):
            problems += check_function(node, f'{name}:{node.name}')
        elif isinstance(node, ast.ClassDef) and (
            not node.name.startswith('_') or node.name in classes
        ):
            if not node.name.startswith('_'):
                problems += check_summary(node, f'{name}:{node.name}')
            for item in node.body:
                if isinstance(item, funcs) and not item.name.startswith('_'):
                    problems += check_function(item, f'{name}:{node.name}.{item.name}')
    return problems


@pytest.mark.parametrize('module', COMPLETED)
def test_public_docstrings_complete(module):
    path = ROOT / module
    problems = check_source(path.read_text(), module)
    assert not problems, '\n'.join(problems)


@pytest.mark.parametrize('module, cls', INHERITED_FROM)
def test_inherited_estimate_docstrings_complete(module, cls):
    path = ROOT / module
    tree = ast.parse(path.read_text(), module)
    node = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == cls)
    problems = []
    for item in node.body:
        if isinstance(item, ast.FunctionDef) and not item.name.startswith('_'):
            problems += check_function(item, f'{module}:{cls}.{item.name}')
    assert not problems, '\n'.join(problems)


PLANTED = '''
def heading_deg(aop_rad, sun_azimuth_deg):
    """Heading of the camera from one AoP."""
    return aop_rad + sun_azimuth_deg


def documented_deg(aop_rad, sun_azimuth_deg=0.0):
    """Return the heading of the camera from one AoP.

    Parameters
    ----------
    aop_rad : float
        Angle of polarization [rad].
    sun_azimuth_deg : float, default 0
        Sun azimuth [deg].

    Returns
    -------
    float
        Heading [deg].
    """
    return aop_rad + sun_azimuth_deg


def half_documented(a, b):
    """Return a sum.

    Parameters
    ----------
    a : float
        First.
    """
    return a + b


def two_line_summary(a):
    """Return a sum of a
    and nothing else.

    Parameters
    ----------
    a : float
        First.

    Returns
    -------
    float
    """
    return a


def raising(a):
    """Check a.

    Parameters
    ----------
    a : float
        First.
    """
    if a < 0:
        raise ValueError('negative')


def reraises(a):
    """Check a.

    Parameters
    ----------
    a : object
        First.
    """
    if isinstance(a, BaseException):
        raise a


def converts(a):
    """Check a.

    Parameters
    ----------
    a : str
        First.
    """
    try:
        if not a:
            raise ValueError('empty')
    except ValueError:
        pass


class Public:
    def method(self, x):
        return x

    @property
    def attr(self):
        """The attribute."""
        return 1

    def _private(self, x):
        return x


def _private(a):
    return a
'''


def test_checker_flags_planted_functions():
    """The checker fails undocumented functions and passes a documented one (it can fail)."""
    problems = check_source(PLANTED, 'planted')
    text = '\n'.join(problems)
    assert 'planted:heading_deg: parameters' in text
    assert 'planted:heading_deg: returns a value but has no Returns section' in text
    assert "planted:half_documented: Parameters section does not name ['b']" in text
    assert 'planted:half_documented: returns a value' in text
    assert 'planted:two_line_summary: summary line does not end with a period' in text
    assert 'planted:two_line_summary: summary is not one line' in text
    assert "planted:raising: raises ['ValueError']" in text
    assert 'planted:Public.method: no docstring' in text
    assert 'planted:Public: no docstring' in text
    assert 'documented_deg' not in text and 'converts' not in text and 'reraises' not in text
    assert 'Public.attr' not in text and '_private' not in text
    assert len(problems) == 9, text


def test_checker_fails_a_completed_module_with_a_planted_function():
    """Appending an undocumented public function to a completed module makes it fail."""
    source = (ROOT / COMPLETED[0]).read_text()
    planted = source + '\n\ndef planted_deg(x_deg):\n    """Planted."""\n    return x_deg\n'
    problems = check_source(planted, COMPLETED[0])
    assert any('planted_deg: parameters' in p for p in problems), problems
    assert any('planted_deg: returns a value' in p for p in problems), problems


# ------------------------------------------------------------------------------------------------
# Damage a former home-made formatter left (issue 23): a summary line repeated as the start of the
# next paragraph, and sentences cut with one word left alone on a line.
# ------------------------------------------------------------------------------------------------
_WIDTH = 99
_TABLE_RE = re.compile(r'\S {2,}\S')


def _norm(text: str) -> str:
    return ' '.join(text.split()).rstrip('.:').lower()


def _paragraphs(lines: list[str]) -> list[list[tuple[int, str]]]:
    paras, cur = [], []
    for i, line in enumerate(lines):
        if line.strip():
            cur.append((i, line))
        elif cur:
            paras.append(cur)
            cur = []
    return paras + ([cur] if cur else [])


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _lone_words(para, col: int) -> list[tuple[int, str]]:
    """Return the one-word lines of a prose paragraph that cut a sentence."""
    out = []
    if para[0][1].strip().startswith(('>>>', '..')) or any(
        _TABLE_RE.search(line.strip()) for _, line in para
    ):
        return out
    for k, (i, line) in enumerate(para):
        word = line.strip()
        if ' ' in word or word in _SECTIONS or not re.search('[A-Za-z]', word):
            continue
        if set(word) <= set('-=~^'):
            continue

        def same(j):
            ok = 0 <= j < len(para) and _indent(para[j][1]) == _indent(line)
            return para[j][1] if ok and not set(para[j][1].strip()) <= set('-=') else None

        prev, nxt = same(k - 1), same(k + 1)
        if prev is not None and prev.rstrip().endswith('::'):
            continue
        if prev is None and nxt is not None:
            out.append((i, f'a sentence cut: {word!r} alone on a line'))
        elif prev is not None and col + len(prev.rstrip()) + 1 + len(word) <= _WIDTH:
            out.append((i, f'{word!r} alone on a line, fits on the one above'))
    return out


def _repeats(summary_para, para) -> bool:
    """Tell whether ``para`` starts with the summary again (or without the summary's verb)."""
    summary = _norm(' '.join(line for _, line in summary_para))
    text = _norm(' '.join(line for _, line in para))
    for s in {summary, summary.split(' ', 1)[-1]}:
        head = text[: len(s)]
        if len(s) > 15 and (head == s or difflib.SequenceMatcher(None, s, head).ratio() > 0.85):
            return True
    # or restated: the same first four words, with or without the summary's verb
    words = re.findall(r"[\w'`-]+", summary)
    first = re.findall(r"[\w'`-]+", text)[:4]
    return len(words) >= 4 and first in (words[:4], words[1:5])


def damaged_docstrings(source: str) -> list[tuple[int, str]]:
    """
    Return (line, what) for each damaged docstring of a Python source.

    Damage: the second paragraph starts with the summary again (equal, or nearly: 85 % alike, or
    with the same first four words; with or without the summary's first word, its verb), or a
    prose line holds one word that either starts a paragraph that goes on (a cut sentence) or fits
    on the line above. Tables, doctests, directives and numpydoc section lines are not prose.
    """
    out = []
    for node in ast.walk(ast.parse(source)):
        body = getattr(node, 'body', None)
        if not isinstance(body, list):
            continue
        for st in body:
            if not (
                isinstance(st, ast.Expr)
                and isinstance(st.value, ast.Constant)
                and isinstance(st.value.value, str)
            ):
                continue
            first = st.value.lineno
            paras = _paragraphs(st.value.value.expandtabs().split('\n'))
            if len(paras) >= 2 and _repeats(paras[0], paras[1]):
                out.append((first + paras[1][0][0], 'the summary repeated as the next paragraph'))
            for para in paras:
                out += [(first + i, what) for i, what in _lone_words(para, st.value.col_offset)]
    return sorted(out)


def test_no_damaged_docstrings():
    """No docstring of the package, tests, benchmark or tools repeats its summary or cuts lines."""
    repo = ROOT.parent
    found = []
    for path in python_files([str(repo / p) for p in python_paths(str(repo))]):
        rel = str(Path(path).relative_to(repo))
        hits = damaged_docstrings(Path(path).read_text())
        found += [f'{rel}:{line}: {what}' for line, what in hits]
    assert not found, '\n'.join(found)


DAMAGED = '''
def repeated(a):
    """
    Return the heading of a frame.

    Return the heading of a frame, from the E-vectors of its usable pixels.
    """


def nearly_repeated(a):
    """
    Return the heading of one frame.

    The heading of one frame, from the E-vectors of its usable pixels.
    """


def cut(a):
    """
    Solve the eigenproblem of a symmetric 3 x 3 matrix for its largest eigenvector here.

    The
    same LAPACK routine as numpy's (the same bits here), without numpy's ~10 us of Python per call.
    """


def short_line(a):
    """
    Solve it.

    Build with the config; call
    apply.
    """


def fine(a, b):
    """
    Return the heading of a frame.

    From the E-vectors of its usable pixels, which the method selects from the mosaic of the frame
    first.

    Parameters
    ----------
    a
        The first.
    b : float
        The second [deg].

    Returns
    -------
    float
        Heading.

    Notes
    -----
    ``/clock``     with clock_mode sim
    ``/diag``
    """
'''


def test_damage_checker_flags_planted_docstrings():
    """Each kind of damage is found where it was planted, and a sound docstring passes."""
    hits = damaged_docstrings(DAMAGED)
    lines = DAMAGED.split('\n')
    found = {(lines[n - 1].strip(), what.split(':')[0].split(' alone')[0]) for n, what in hits}
    assert found == {
        (
            'Return the heading of a frame, from the E-vectors of its usable pixels.',
            'the summary repeated as the next paragraph',
        ),
        (
            'The heading of one frame, from the E-vectors of its usable pixels.',
            'the summary repeated as the next paragraph',
        ),
        ('The', 'a sentence cut'),
        ('apply.', "'apply.'"),
    }, hits
