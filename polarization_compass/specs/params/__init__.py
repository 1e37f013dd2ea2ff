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
Declarative parameter specifications of every node (ROS-free).

One :class:`Param` per ROS parameter: name, default, description, range or choices, and whether it
may change while the node runs. The nodes declare them from here
(:mod:`polarization_compass.nodes.rosparams` turns them into ``ParameterDescriptor`` s with
``FloatingPointRange`` / ``IntegerRange`` and validates every change in an on-set-parameters
callback); the graph test checks every shipped parameter file against them;
``docs/ros.md`` lists them.

The package: :mod:`.spec` (the :class:`Param` type and its checks), :mod:`.site_sun` (site and
sun), :mod:`.methods` (method choices), one module per node family (:mod:`.simulator`,
:mod:`.estimator`, :mod:`.downstream`); here the index of every node's table, the method knobs and
the docs' tables.
"""

from __future__ import annotations

import math

from .downstream import CORRECTOR, EVALUATOR, PLAYER_FLOW
from .estimator import ARRAY_ESTIMATOR, ESTIMATOR
from .methods import ALL_METHODS, PAPER_METHODS, TILT_METHODS
from .simulator import SIMULATOR
from .site_sun import apply_fix, SITE_SOURCE, SUN_PARAMS, sun_source
from .spec import layout_from_text, Param, parse_downstream, validate_value

__all__ = [
    'Param',
    'validate_value',
    'SIMULATOR',
    'ESTIMATOR',
    'CORRECTOR',
    'EVALUATOR',
    'PLAYER_FLOW',
    'ARRAY_ESTIMATOR',
    'ALL_METHODS',
    'PAPER_METHODS',
    'TILT_METHODS',
    'parse_downstream',
    'SPECS',
    'spec_by_name',
    'defaults',
    'layout_from_text',
    'knob_params',
    'KNOB_PREFIX',
    'SUN_PARAMS',
    'sun_source',
    'SITE_SOURCE',
    'apply_fix',
]


SPECS = {
    'sky_simulator': SIMULATOR,
    'heading_estimator': ESTIMATOR,
    'array_heading_estimator': ARRAY_ESTIMATOR,
    'tilt_corrector': CORRECTOR,
    'error_evaluator': EVALUATOR,
    'player_flow': PLAYER_FLOW,
}


def spec_by_name(specs) -> dict:
    """
    Return a node's parameter specifications by name.

    Parameters
    ----------
    specs : iterable of Param
        E.g. :data:`ESTIMATOR`.

    Returns
    -------
    dict
        ``{name: Param}``.

    """
    return {p.name: p for p in specs}


def defaults(specs) -> dict:
    """
    Return the default value of every parameter (tuples as lists, as ROS gives them).

    Parameters
    ----------
    specs : iterable of Param
        E.g. :data:`ESTIMATOR`.

    Returns
    -------
    dict
        ``{name: default}``.

    """
    return {
        p.name: (list(p.default) if isinstance(p.default, (list, tuple)) else p.default)
        for p in specs
    }


KNOB_PREFIX = 'knob.'


def knob_params(method: str, specs: dict | None = None) -> tuple:
    """
    Return the estimator's own knobs as run-time parameters ``knob.<name>``.

    Ranges come from the estimator. ``region`` and optional numbers become strings: ``""``
    means None, a region is ``"x0,y0,w,h"`` [px].

    Parameters
    ----------
    method : str
        A registered estimator name.
    specs : dict, optional
        Another knob table than the method's (a photodiode array's ``ARRAY_KNOBS``).

    Returns
    -------
    tuple of Param
        One parameter per knob, sorted by name, not read-only.

    """
    from ...estimators import registry

    specs = registry.get(method).knob_specs() if specs is None else specs
    out = []
    for name, k in sorted(specs.items()):
        lo = None if not math.isfinite(k.lo) else float(k.lo)
        hi = None if not math.isfinite(k.hi) else float(k.hi)
        desc = f'estimator knob: {k.doc}' if k.doc else 'estimator knob'
        if k.kind == 'int':
            out.append(
                Param(
                    KNOB_PREFIX + name,
                    int(k.default),
                    desc,
                    None if lo is None else int(lo),
                    None if hi is None else int(hi),
                )
            )
        elif k.kind == 'float':
            out.append(Param(KNOB_PREFIX + name, float(k.default), desc, lo, hi))
        elif k.kind == 'bool':
            out.append(Param(KNOB_PREFIX + name, bool(k.default), desc))
        elif k.kind == 'choice':
            out.append(
                Param(
                    KNOB_PREFIX + name,
                    str(k.default),
                    desc,
                    choices=tuple(str(c) for c in k.choices),
                )
            )
        else:  # region, float_or_none: text, "" = None
            d = (
                ''
                if k.default is None
                else ','.join(str(v) for v in k.default)
                if k.kind == 'region'
                else str(k.default)
            )
            out.append(
                Param(
                    KNOB_PREFIX + name,
                    d,
                    desc
                    + " ('' = none"
                    + (', else x0,y0,width,height)' if k.kind == 'region' else ', else a number)'),
                )
            )
    return tuple(out)


def knob_values(method: str, values: dict, specs: dict | None = None) -> dict:
    """
    Return estimator knobs from ``knob.<name>`` parameter values.

    Strings go back to None, tuples or choices (the inverse of :func:`knob_params`); knobs not in
    ``values`` are left out.

    Parameters
    ----------
    method : str
        A registered estimator name.
    values : dict
        Parameter values by full name (``knob.<name>``).
    specs : dict, optional
        As for :func:`knob_params`.

    Returns
    -------
    dict
        ``{knob name: value}`` for the estimator's constructor.

    """
    from ...estimators import registry

    specs = registry.get(method).knob_specs() if specs is None else specs
    out = {}
    for name, k in specs.items():
        key = KNOB_PREFIX + name
        if key not in values:
            continue
        v = values[key]
        if k.kind == 'region':
            v = None if v == '' else tuple(int(float(x)) for x in str(v).split(','))
        elif k.kind == 'float_or_none':
            v = None if v == '' else float(v)
        elif k.kind == 'choice':
            match = [c for c in k.choices if str(c) == v]
            v = match[0] if match else v
        out[name] = v
    return out


def markdown_tables() -> str:
    """
    Return the parameter tables of docs/ros.md (a test keeps the document equal to this).

    Returns
    -------
    str
        One Markdown table per node: parameter, default, range or choices, run time, meaning.

    """
    lines = []
    for node, specs in SPECS.items():
        lines += [
            '',
            f'#### {node}',
            '',
            '| parameter | default | range / choices | run time | meaning |',
            '|---|---|---|---|---|',
        ]
        for p in specs:
            if p.choices:
                rng = ' \\| '.join(p.choices)
            elif p.lo is not None:
                rng = f'[{p.lo:g}, {p.hi:g}]' + (f' {p.unit}' if p.unit else '')
            else:
                rng = p.unit
            d = str(p.default).lower() if isinstance(p.default, bool) else p.default
            d = '`""`' if d == '' else f'`{d}`'
            lines.append(
                f'| `{p.name}` | {d} | {rng} | {"no" if p.read_only else "yes"} | {p.description} '
                '|'
            )
    lines += [
        '',
        '#### heading_estimator knobs (`knob.<name>`, least_squares)',
        '',
        '| parameter | default | range / choices | meaning |',
        '|---|---|---|---|',
    ]
    for p in knob_params('least_squares'):
        if p.choices:
            rng = ' \\| '.join(p.choices)
        elif p.lo is not None and p.hi is not None:
            rng = f'[{p.lo:g}, {p.hi:g}]'
        elif p.lo is not None:
            rng = f'>= {p.lo:g}'
        else:
            rng = ''
        lines.append(
            f'| `{p.name}` | `{p.default}` | {rng} | '
            f'{p.description.replace("estimator knob: ", "")} |'
        )
    return '\n'.join(lines) + '\n'
