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
Builds ``summary.md``, ``pareto.png`` and ``pareto_conditions.png`` from the group JSON files.

Only reads ``<dir>/*.json``; a group that is missing, unavailable or failed is listed as such.
One module per kind of section (:mod:`.accuracy`, :mod:`.simulation`, :mod:`.errormaps`,
:mod:`.speed`, :mod:`.ros`), the plots (:mod:`.plots`) and what they share (:mod:`.formatting`).
"""

from __future__ import annotations

from pathlib import Path

from .accuracy import accuracy_section, crb_section
from .errormaps import errormap_sampling_section, errormap_section
from .formatting import fmt, load_groups, method_colour, ok_cells, PRIMARY_CONDITIONS
from .plots import pareto_front, plot_conditions, plot_pareto
from .ros import graph_section, peers_section, replay_section
from .sensors import photodiode_section
from .simulation import simulator_section, solar_section
from .speed import estimator_speed_section, pipeline_section

__all__ = ['build', 'method_colour', 'pareto_front']


# ------------------------------------------------------------------------------------------------
def _header(groups) -> list[str]:
    anyg = next(iter(groups.values()))
    m = anyg['machine']
    modes = sorted({g['mode'] for g in groups.values()})
    lines = ['# Benchmark results', '']
    if modes != ['full']:
        lines += [
            f'> **Mode: {", ".join(modes)}.** Quick mode checks that the suite runs (few scenes, '
            'few knobs, '
            'peers at half size) on a machine that may be shared; its numbers are indicative '
            'only. '
            "The README's numbers come from `make bench` (full mode) on an idle machine.",
            '',
        ]
    lines += [
        f'- Machine: {m["cpu_model"]}, {m["usable_cores"]} cores, {m["ram_gib"]} GiB RAM; '
        f'{m["platform"]}',
        f'- Python {m["python"]}, numpy {m["numpy"]}, numba {m["numba"]}, OpenCV {m["opencv"]}, '
        f'scipy {m["scipy"]}, pvlib {m["pvlib"]}',
        f'- Date {m["date_utc"]}, git commit `{(m["git_commit"] or "?")[:10]}`'
        f'{" (working tree modified)" if m.get("git_dirty") else ""}',
        '- Timings: one core (numba 1 thread, BLAS 1 thread), wall clock, median and 95th '
        'percentile.',
        '',
        '| group | mode | status | elapsed (s) | load avg at start -> end (1 min) |',
        '|---|---|---|---|---|',
    ]
    for name, g in groups.items():
        la = g.get('load_average', {})
        s, e = (la.get('start') or [None])[0], (la.get('end') or [None])[0]
        lines.append(
            f'| {name} | {g["mode"]} | {g["status"][:80]} | {fmt(g.get("elapsed_s"))} '
            f'| {s} -> {e} |'
        )
    return lines + ['']


def build(out_dir) -> list[Path]:
    d = Path(out_dir)
    groups = load_groups(d)
    if not groups:
        return []
    paths = []
    acc = groups.get('accuracy')
    crb = groups.get('crb')
    cells = ok_cells(acc)
    conds = {c['condition'] for c in cells}
    primary = next((c for c in PRIMARY_CONDITIONS if c in conds), next(iter(conds), None))
    if primary:
        p = plot_pareto(cells, crb, primary, d / 'pareto.png')
        if p:
            paths.append(p)
        p = plot_conditions(cells, d / 'pareto_conditions.png')
        if p:
            paths.append(p)
    lines = _header(groups)
    if paths:
        lines += [f'![Pareto plot]({paths[0].name})', '']
    lines += accuracy_section(acc, crb)
    lines += crb_section(crb)
    lines += simulator_section(groups.get('simulator'))
    lines += solar_section(groups.get('solar'))
    lines += errormap_section(groups.get('errormap'))
    lines += errormap_sampling_section(groups.get('errormap_sampling'))
    lines += pipeline_section(groups.get('pipeline'))
    lines += estimator_speed_section(groups.get('estimator_speed'))
    lines += replay_section(groups.get('replay'))
    lines += graph_section(groups.get('graph'))
    lines += peers_section(groups.get('peers'))
    lines += photodiode_section(groups.get('photodiode'))
    md = d / 'summary.md'
    md.write_text('\n'.join(lines).rstrip() + '\n')
    return [md] + paths
