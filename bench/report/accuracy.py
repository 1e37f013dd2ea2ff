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

"""The accuracy sections: what accuracy costs in time, the headline table, the Cramer-Rao bound."""

from __future__ import annotations

from .formatting import fmt, md_table, ok_cells, section, windowed
from .plots import pareto_front


def accuracy_section(acc, crb) -> list[str]:
    lines = ['## What accuracy costs in time', '']
    cells = ok_cells(acc)
    if not cells:
        st = acc['status'] if acc else 'not run'
        bad = (
            [c for c in (acc or {}).get('results', {}).get('cells', []) if c['status'] != 'ok']
            if acc and acc.get('results')
            else []
        )
        return lines + [
            f'Accuracy benchmark: {st}.'
            + (f' {len(bad)} configurations unavailable.' if bad else ''),
            '',
        ]
    r = acc['results']
    lines += [
        f'{r["scenes_per_condition"]} seeded random scenes per condition (sun azimuth 0-360 deg, '
        'altitude '
        f'10-60 deg (10-50 when tilted), any bearing), {r["repeats_per_scene"]} timed estimates '
        'per scene, one core. Errors: '
        'estimated minus true heading, folded mod 180 deg for methods that only find the solar '
        'meridian. '
        'CRB: Cramer-Rao bound of the heading for the pixels the configuration reads (AoP noise '
        '1/(P sqrt(8N)) per superpixel, N = 5000 e-); RMS/CRB = 1 is a perfect estimator. '
        "Peak RSS: growth of the process' resident set during one estimate (numba kernels' "
        'arrays, numpy, '
        'OpenCV and Python together; the tracemalloc peak is in the JSON; docs/benchmarks.md).',
        '',
    ]
    lines += _headline(cells, r)
    header = [
        'method',
        'knobs',
        'pixels',
        'RMS (deg)',
        'p95 (deg)',
        'max (deg)',
        'ms median',
        'ms p95',
        'peak RSS MiB',
        'CRB (deg)',
        'RMS/CRB',
        'err^2/sigma^2',
        '> 5 sigma',
        'fails',
    ]
    for cond in list(dict.fromkeys(c['condition'] for c in cells)):
        cc = [c for c in cells if c['condition'] == cond]
        lines += [f'### {cond}: {r["conditions"].get(cond, "")}', '']
        rows = []
        for c in cc:
            mem = c.get('memory') or {}
            rows.append(
                [
                    c['method'],
                    c['knobs_label'],
                    fmt(c.get('pixels_used_median')),
                    fmt(c['error']['rms_deg']),
                    fmt(c['error']['p95_deg']),
                    fmt(c['error']['max_deg']),
                    fmt(c['time']['median_ms']),
                    fmt(c['time']['p95_ms']),
                    fmt(mem.get('resident_peak_mib')),
                    fmt(c.get('crb_rms_deg')),
                    fmt(c.get('rms_over_crb')),
                    fmt(c.get('sigma_calibration')),
                    fmt(c.get('beyond_5_sigma')),
                    c['error']['failures'],
                ]
            )
        lines += md_table(header, rows) + ['']
    bad = [c for c in r['cells'] if c['status'] != 'ok']
    if bad:
        lines += [
            'Configurations not measured: '
            + '; '.join(
                sorted({f'{c["method"]} ({c["knobs_label"]}): {c["status"][:90]}' for c in bad})[
                    :12
                ]
            ),
            '',
        ]
    for s in r.get('skipped_conditions', []):
        lines.append(f'- condition `{s["condition"]}` skipped: {s["reason"]}')
    return lines + ['']


#: The knob labels of the cells the README's tables quote, for windowed and strided methods.
REFERENCE_KNOBS = {'window': ('window 33 px',), 'stride': ('stride 8', 'stride 16')}


def reference_cell(cells, method, condition):
    """
    Return the cell with a method's reference knobs in a condition.

    With a sensor, the cell with the superpixel demosaic; None when there is no such cell.
    """
    labels = REFERENCE_KNOBS['window' if windowed(method) else 'stride']
    for lab in labels:
        for c in cells:
            if (
                c['method'] == method
                and c['condition'] == condition
                and c['knobs_label']
                in (lab, lab + ', superpixel demosaic', lab + ', correction invert')
            ):
                return c
    return None


def _headline(cells, r) -> list[str]:
    """
    Return two compact tables for the README: Pareto front and error by condition.

    The Pareto front in the noisy condition, and each method's error by condition at fixed
    reference knobs.
    """
    lines = []
    noisy = [c for c in cells if c['condition'] == 'noise_imx250']
    if noisy:
        rows = []
        for m in dict.fromkeys(c['method'] for c in noisy):
            if m == 'tilt_aware' and 'least_squares' in {c['method'] for c in noisy}:
                continue  # level camera: tilt_aware is least_squares (same numbers)
            mc = [c for c in noisy if c['method'] == m]
            front = pareto_front(
                [(c['time']['median_ms'], c['error']['rms_deg'], i) for i, c in enumerate(mc)]
            )
            for _, _, i in front:
                c = mc[i]
                rows.append(
                    [
                        m,
                        c['knobs_label'],
                        fmt(c['time']['median_ms']),
                        fmt(c['error']['rms_deg']),
                        fmt(c['error']['max_deg']),
                        fmt(c.get('crb_rms_deg')),
                        fmt(c.get('rms_over_crb')),
                    ]
                )
        lines += [
            '**Pareto-optimal settings** (IMX250MZR-like noise, level; time = estimate only, one '
            'core; '
            'add the demosaic: see Simulator/Node pipeline; tilt_aware on a level camera equals '
            'least_squares):',
            '',
        ]
        lines += md_table(
            ['method', 'knobs', 'ms', 'RMS (deg)', 'max (deg)', 'CRB (deg)', 'RMS/CRB'], rows
        ) + ['']
    conds = list(dict.fromkeys(c['condition'] for c in cells))
    methods = list(dict.fromkeys(c['method'] for c in cells))
    rows = []
    for m in methods:
        row = [m]
        for cond in conds:
            c = reference_cell(cells, m, cond)
            row.append(
                '-'
                if c is None
                else f'{fmt(c["error"]["rms_deg"])} ({fmt(c["error"]["max_deg"])})'
            )
        rows.append(row)
    lines += [
        '**Error by condition**, RMS (max) in deg, at reference settings (zenith: 33 px window; '
        'others: '
        'stride 8, or 16 in quick mode; superpixel demosaic where there is a sensor; the `invert` '
        'correction):',
        '',
    ]
    lines += md_table(['method'] + conds, rows) + ['']
    rows = []
    for m in methods:
        row = [m]
        for cond in conds:
            c = reference_cell(cells, m, cond)
            cal = None if c is None else c.get('sigma_calibration')
            row.append(
                '-' if cal is None else f'{fmt(cal)} ({c.get("beyond_5_sigma")}/{c["error"]["n"]})'
            )
        rows.append(row)
    lines += [
        '**Sigma calibration by condition**, mean(err^2 / sigma^2) with the published floor '
        'max(sigma, sigma_floor_deg) (1 for an honest sigma; near 0 where the error is far below '
        'the floor), and (ok results more than 5 sigma off / ok results), same settings:',
        '',
    ]
    lines += md_table(['method'] + conds, rows) + ['']
    return lines


def crb_section(crb) -> list[str]:
    lines, r = section('Cramer-Rao bound', crb)
    if r is None:
        return lines
    lines += [
        "Reference check (physics notes 4): the paper's sensor behind a 180 deg equidistant "
        'fisheye, '
        'N = 5000 e-, DoP_max 0.7, level camera, superpixels.',
        '',
    ]
    lines += md_table(
        ['sun altitude (deg)', 'CRB, AoP only (deg)', 'CRB, AoP + DoP (deg)', 'superpixels'],
        [
            [
                fmt(x['sun_altitude_deg']),
                fmt(x['crb_deg']),
                fmt(x.get('crb_with_dop_deg')),
                x['superpixels'],
            ]
            for x in r['reference_fisheye']['rows']
        ],
    )
    ch = r['reference_fisheye']['checks']
    lines.append('')
    for k, v in ch.items():
        lines.append(
            f'- {k}: computed {v["computed_deg"]}, reference {v["reference_deg"]} deg, '
            f'within a factor 2: {v["within_factor_2"]}'
        )
    lines += [
        '',
        "The paper's imager (pinhole, 2448 x 2048), level, by pixel budget (stride on the full "
        'grid):',
        '',
    ]
    rows = r['paper_imager_budgets']
    keys = [k for k in rows[0] if k.startswith('crb_deg_sun_')]
    lines += md_table(
        ['pixel stride', 'samples'] + [k.replace('crb_deg_sun_', 'sun ') + ' deg' for k in keys],
        [[x['pixel_stride'], x['samples']] + [fmt(x[k]) for k in keys] for x in rows],
    )
    return lines + ['']
