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
What every section of the summary uses: number and table formatting, the group JSON files.

Also a method's colour and place in the plots (from the registry) and the sections' common heading.
"""

from __future__ import annotations

import math
from pathlib import Path

from polarization_compass.estimators import registry

from ..common import read_json

PRIMARY_CONDITIONS = ('noise_imx250', 'ideal_level')
#: Errors below this (deg) are drawn at it (log axes; noise-free Rayleigh errors are ~1e-6 deg).
ERROR_FLOOR_DEG = 1e-7


def method_colour(method: str) -> str:
    """Return a method's colour in the plots: its registry style's, black when unknown or unset."""
    style = registry.style(method)
    return style[0] if style else 'k'


def method_rank(method: str) -> int:
    """Return a method's place in the plots: the registry's order, unknown methods last."""
    names = registry.names()
    return names.index(method) if method in names else len(names)


def windowed(method: str) -> bool:
    """Tell whether a method reads a window (``window_px``) instead of a strided pixel set."""
    return registry.find(method) is not None and 'window_px' in registry.knob_names(method)


def load_groups(d: Path) -> dict:
    out = {}
    for p in sorted(Path(d).glob('*.json')):
        try:
            j = read_json(p)
        except ValueError:
            continue
        if isinstance(j, dict) and 'benchmark' in j:
            out[j['benchmark']] = j
    return out


def fmt(x, digits=3, unit=''):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return '-'
    if isinstance(x, (int,)) and not isinstance(x, bool):
        return f'{x}{unit}'
    ax = abs(x)
    if ax != 0 and (ax < 10**-(digits) or ax >= 1e5):
        return f'{x:.{max(1, digits - 1)}e}{unit}'
    if ax >= 100:
        return f'{x:.0f}{unit}'
    if ax >= 10:
        return f'{x:.1f}{unit}'
    return f'{x:.{digits}g}{unit}' if ax < 1 else f'{x:.{digits - 1}f}{unit}'


def md_table(header, rows) -> list[str]:
    out = ['| ' + ' | '.join(header) + ' |', '|' + '|'.join('---' for _ in header) + '|']
    out += ['| ' + ' | '.join(str(c) for c in r) + ' |' for r in rows]
    return out


def ok_cells(acc):
    if not acc or acc.get('status') != 'ok' or not acc.get('results'):
        return []
    return [c for c in acc['results']['cells'] if c['status'] == 'ok' and c['error']['n']]


def section(title: str, group) -> tuple[list[str], dict | None]:
    """
    Return a section's heading and its group's results.

    The results are None (and the lines say why) when the group did not run or did not end ok.
    """
    lines = [f'## {title}', '']
    if not group or group.get('status') != 'ok':
        return lines + [f'{group["status"] if group else "not run"}', ''], None
    return lines, group['results']


def pass_fail(flag) -> str:
    return 'n/a' if flag is None else ('pass' if flag else '**FAIL**')
