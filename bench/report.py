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
"""

from __future__ import annotations

import math
from pathlib import Path

from polarization_compass.estimators import registry

from .common import read_json

PRIMARY_CONDITIONS = ('noise_imx250', 'ideal_level')
#: Errors below this (deg) are drawn at it (log axes; noise-free Rayleigh errors are ~1e-6 deg).
ERROR_FLOOR_DEG = 1e-7


def _log_axes(ax, ys=()):
    """Log-log axes without minor tick labels, and at least one decade of error range."""
    from matplotlib.ticker import NullFormatter

    ax.set_xscale('log')
    ax.set_yscale('log')
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())
    ys = [y for y in ys if y and y > 0]
    if ys:
        lo, hi = min(ys), max(ys)
        if hi / lo < 10.0:
            mid = math.sqrt(lo * hi)
            ax.set_ylim(mid / 10**0.6, mid * 10**0.6)


def method_colour(method: str) -> str:
    """Return a method's colour in the plots: its registry style's, black when unknown or unset."""
    style = registry.style(method)
    return style[0] if style else 'k'


def _method_rank(method: str) -> int:
    """Return a method's place in the plots: the registry's order, unknown methods last."""
    names = registry.names()
    return names.index(method) if method in names else len(names)


def _windowed(method: str) -> bool:
    """Tell whether a method reads a window (``window_px``) instead of a strided pixel set."""
    return registry.find(method) is not None and 'window_px' in registry.knob_names(method)


def _load(d: Path) -> dict:
    out = {}
    for p in sorted(Path(d).glob('*.json')):
        try:
            j = read_json(p)
        except ValueError:
            continue
        if isinstance(j, dict) and 'benchmark' in j:
            out[j['benchmark']] = j
    return out


def _f(x, digits=3, unit=''):
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


def _table(header, rows) -> list[str]:
    out = ['| ' + ' | '.join(header) + ' |', '|' + '|'.join('---' for _ in header) + '|']
    out += ['| ' + ' | '.join(str(c) for c in r) + ' |' for r in rows]
    return out


def _ok_cells(acc):
    if not acc or acc.get('status') != 'ok' or not acc.get('results'):
        return []
    return [c for c in acc['results']['cells'] if c['status'] == 'ok' and c['error']['n']]


# ------------------------------------------------------------------------------------------------
def pareto_front(points):
    """
    Return the points not dominated by a faster, at least as accurate point, by time.

    Points (time, error, ...) not dominated by a faster and at least as accurate point, by time.
    """
    front, best = [], math.inf
    for p in sorted(points, key=lambda q: (q[0], q[1])):
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def plot_pareto(acc_cells, crb_json, condition, out_path: Path):
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    cells = [c for c in acc_cells if c['condition'] == condition and c['time']['median_ms']]
    if not cells:
        return None
    floor = ERROR_FLOOR_DEG
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.6), dpi=110)
    methods = sorted(
        {c['method'] for c in cells},
        key=_method_rank,
    )
    crb_drawn = False
    for m in methods:
        col = method_colour(m)
        mc = [c for c in cells if c['method'] == m]
        for c in mc:
            mk = 's' if c.get('demosaic') == 'bilinear' else 'o'
            y = max(c['error']['rms_deg'], floor)
            ax1.scatter(
                c['time']['median_ms'],
                y,
                color=col,
                marker=mk,
                s=36,
                zorder=3,
                edgecolor='k',
                linewidth=0.4,
            )
            if c.get('pixels_used_median'):
                ax2.scatter(
                    c['pixels_used_median'],
                    y,
                    color=col,
                    marker=mk,
                    s=36,
                    zorder=3,
                    edgecolor='k',
                    linewidth=0.4,
                )
            if c.get('crb_rms_deg'):
                ax1.plot(
                    [c['time']['median_ms']] * 2, [c['crb_rms_deg'], y], ':', color=col, lw=0.8
                )
                ax1.scatter(
                    c['time']['median_ms'],
                    c['crb_rms_deg'],
                    color='0.35',
                    marker='x',
                    s=22,
                    zorder=2,
                    label=None if crb_drawn else 'Cramer-Rao bound, same pixels',
                )
                crb_drawn = True
        front = pareto_front(
            [(c['time']['median_ms'], max(c['error']['rms_deg'], floor)) for c in mc]
        )
        ax1.plot([p[0] for p in front], [p[1] for p in front], '-', color=col, lw=1.4, label=m)
    # CRB against pixel budget (paper's imager, level) from crb.json
    if crb_json and crb_json.get('status') == 'ok':
        rows = crb_json['results']['paper_imager_budgets']
        for alt, ls in ((30, '--'), (50, '-.')):
            key = f'crb_deg_sun_{alt:g}'
            pts = [(r['samples'], r[key]) for r in rows if r.get(key)]
            if pts:
                ax2.plot(
                    [p[0] for p in pts],
                    [p[1] for p in pts],
                    ls,
                    color='0.3',
                    label=f'Cramer-Rao bound, sun {alt} deg (5000 e-, DoP 0.7)',
                )
    for m in methods:
        ax2.scatter([], [], color=method_colour(m), marker='o', label=m)
    ax2.scatter([], [], color='w', edgecolor='k', marker='o', label='superpixel demosaic')
    ax2.scatter([], [], color='w', edgecolor='k', marker='s', label='full-resolution demosaic')
    ys = [max(c['error']['rms_deg'], floor) for c in cells] + [
        c['crb_rms_deg'] for c in cells if c.get('crb_rms_deg')
    ]
    for ax in (ax1, ax2):
        _log_axes(ax, ys)
        ax.grid(True, which='both', alpha=0.3)
        ax.set_ylabel('RMS heading error (deg)')
    ax1.set_xlabel('time per estimate, median, one core (ms)')
    ax2.set_xlabel('pixels used per estimate')
    ax1.set_title(f'Error against time ({condition}); lines: Pareto front per method', fontsize=10)
    ax2.set_title('Error against pixel budget, with the Cramer-Rao bound', fontsize=10)
    ax1.legend(fontsize=8, loc='best')
    ax2.legend(fontsize=7, loc='best')
    fig.tight_layout()
    fig.savefig(out_path)
    plt.close(fig)
    return out_path


def plot_conditions(acc_cells, out_path: Path):
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    conds = list(dict.fromkeys(c['condition'] for c in acc_cells))
    if not conds:
        return None
    n = len(conds)
    cols = min(4, n)
    rows = int(math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), dpi=100, squeeze=False)
    for ax, cond in zip(axes.flat, conds):
        cc = [c for c in acc_cells if c['condition'] == cond and c['time']['median_ms']]
        ys = []
        for m in dict.fromkeys(c['method'] for c in cc):
            mc = [c for c in cc if c['method'] == m]
            col = method_colour(m)
            pts = [
                (c['time']['median_ms'], max(c['error']['rms_deg'], ERROR_FLOOR_DEG)) for c in mc
            ]
            ys += [p[1] for p in pts]
            ax.scatter([p[0] for p in pts], [p[1] for p in pts], color=col, s=14, label=m)
            fr = pareto_front(pts)
            ax.plot([p[0] for p in fr], [p[1] for p in fr], color=col, lw=1)
        _log_axes(ax, ys)
        ax.set_title(cond, fontsize=9)
        ax.grid(True, which='both', alpha=0.3)
        ax.set_xlabel('ms per estimate', fontsize=8)
        ax.set_ylabel('RMS error (deg)', fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[n:]:
        ax.axis('off')
    fig.tight_layout()
    fig.savefig(out_path)
    plt.close(fig)
    return out_path


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
            f'| {name} | {g["mode"]} | {g["status"][:80]} | {_f(g.get("elapsed_s"))} | {s} -> {e} '
            '|'
        )
    return lines + ['']


def _accuracy_section(acc, crb) -> list[str]:
    lines = ['## What accuracy costs in time', '']
    cells = _ok_cells(acc)
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
                    _f(c.get('pixels_used_median')),
                    _f(c['error']['rms_deg']),
                    _f(c['error']['p95_deg']),
                    _f(c['error']['max_deg']),
                    _f(c['time']['median_ms']),
                    _f(c['time']['p95_ms']),
                    _f(mem.get('resident_peak_mib')),
                    _f(c.get('crb_rms_deg')),
                    _f(c.get('rms_over_crb')),
                    _f(c.get('sigma_calibration')),
                    _f(c.get('beyond_5_sigma')),
                    c['error']['failures'],
                ]
            )
        lines += _table(header, rows) + ['']
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


def _reference_cell(cells, method, condition):
    """
    Return the cell with a method's reference knobs in a condition.

    With a sensor, the cell with the superpixel demosaic; None when there is no such cell.
    """
    labels = REFERENCE_KNOBS['window' if _windowed(method) else 'stride']
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
                        _f(c['time']['median_ms']),
                        _f(c['error']['rms_deg']),
                        _f(c['error']['max_deg']),
                        _f(c.get('crb_rms_deg')),
                        _f(c.get('rms_over_crb')),
                    ]
                )
        lines += [
            '**Pareto-optimal settings** (IMX250MZR-like noise, level; time = estimate only, one '
            'core; '
            'add the demosaic: see Simulator/Node pipeline; tilt_aware on a level camera equals '
            'least_squares):',
            '',
        ]
        lines += _table(
            ['method', 'knobs', 'ms', 'RMS (deg)', 'max (deg)', 'CRB (deg)', 'RMS/CRB'], rows
        ) + ['']
    conds = list(dict.fromkeys(c['condition'] for c in cells))
    methods = list(dict.fromkeys(c['method'] for c in cells))
    rows = []
    for m in methods:
        row = [m]
        for cond in conds:
            c = _reference_cell(cells, m, cond)
            row.append(
                '-' if c is None else f'{_f(c["error"]["rms_deg"])} ({_f(c["error"]["max_deg"])})'
            )
        rows.append(row)
    lines += [
        '**Error by condition**, RMS (max) in deg, at reference settings (zenith: 33 px window; '
        'others: '
        'stride 8, or 16 in quick mode; superpixel demosaic where there is a sensor; the `invert` '
        'correction):',
        '',
    ]
    lines += _table(['method'] + conds, rows) + ['']
    rows = []
    for m in methods:
        row = [m]
        for cond in conds:
            c = _reference_cell(cells, m, cond)
            cal = None if c is None else c.get('sigma_calibration')
            row.append(
                '-' if cal is None else f'{_f(cal)} ({c.get("beyond_5_sigma")}/{c["error"]["n"]})'
            )
        rows.append(row)
    lines += [
        '**Sigma calibration by condition**, mean(err^2 / sigma^2) with the published floor '
        'max(sigma, sigma_floor_deg) (1 for an honest sigma; near 0 where the error is far below '
        'the floor), and (ok results more than 5 sigma off / ok results), same settings:',
        '',
    ]
    lines += _table(['method'] + conds, rows) + ['']
    return lines


def _section(title: str, group) -> tuple[list[str], dict | None]:
    """
    Return a section's heading and its group's results.

    The results are None (and the lines say why) when the group did not run or did not end ok.
    """
    lines = [f'## {title}', '']
    if not group or group.get('status') != 'ok':
        return lines + [f'{group["status"] if group else "not run"}', ''], None
    return lines, group['results']


def _crb_section(crb) -> list[str]:
    lines, r = _section('Cramer-Rao bound', crb)
    if r is None:
        return lines
    lines += [
        "Reference check (physics notes 4): the paper's sensor behind a 180 deg equidistant "
        'fisheye, '
        'N = 5000 e-, DoP_max 0.7, level camera, superpixels.',
        '',
    ]
    lines += _table(
        ['sun altitude (deg)', 'CRB, AoP only (deg)', 'CRB, AoP + DoP (deg)', 'superpixels'],
        [
            [
                _f(x['sun_altitude_deg']),
                _f(x['crb_deg']),
                _f(x.get('crb_with_dop_deg')),
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
    lines += _table(
        ['pixel stride', 'samples'] + [k.replace('crb_deg_sun_', 'sun ') + ' deg' for k in keys],
        [[x['pixel_stride'], x['samples']] + [_f(x[k]) for k in keys] for x in rows],
    )
    return lines + ['']


def _simulator_section(sim) -> list[str]:
    lines, r = _section('Simulator', sim)
    if r is None:
        return lines
    lines += [
        f'Camera {r["camera"]["width_px"]} x {r["camera"]["height_px"]}, tilted attitude, fixed '
        'sun. '
        '`stages` = pipeline stages that ran (instrumentation counts): undeclared effects never '
        'run.',
        '',
    ]
    rows = []
    for x in r['rows']:
        if x.get('status') != 'ok':
            rows.append([x['name'], '-', '-', '-', '-', x['status'][:60]])
            continue
        rows.append(
            [
                x['name'],
                x['pixels'],
                _f(x['single_thread']['median_ms']),
                _f(x['all_threads']['median_ms']),
                _f(x.get('relative_to_full', {}).get('single_thread')),
                ', '.join(x['stages']),
            ]
        )
    lines += _table(
        [
            'configuration',
            'pixels',
            'ms (1 thread)',
            'ms (all threads)',
            'x full (1 thread)',
            'stages',
        ],
        rows,
    )
    s = r.get('summary', {})
    if s.get('targets'):
        lines += [
            '',
            "Issue 2's targets (full 2448 x 2048 frame; the stages alone are "
            '`sensor.simulate_mosaic` '
            'and `demosaic.polarization_from_mosaic` timed on their own):',
            '',
        ]
        lines += _table(
            [
                'target',
                'target (ms)',
                'ms (1 thread)',
                'pass (1 thread)',
                'ms (all threads)',
                'pass (all threads)',
            ],
            [
                [
                    t['target'],
                    f'<= {_f(t["target_ms"])}',
                    _f(t['single_thread_median_ms']),
                    _pass(t['pass_single_thread']),
                    _f(t['all_threads_median_ms']),
                    _pass(t['pass_all_threads']),
                ]
                for t in s['targets']
            ],
        )
    if 'stride8_speedup_single_thread' in s:
        unpaired = s.get('stride8_speedup_unpaired_single_thread')
        lines += [
            '',
            'Stride 8 against full, paired (blocks of both renders within the same second, each '
            'in its '
            f'steady state): {_f(s["stride8_speedup_single_thread"])}x faster on one thread '
            f'(target >= 30x: {s["stride8_at_least_30x_single_thread"]}), '
            f'{_f(s.get("stride8_speedup_all_threads"))}x on all threads'
            + (
                f"; from the two rows' medians above, timed apart: {_f(unpaired)}x."
                if unpaired
                else '.'
            ),
        ]
    return lines + ['']


def _solar_section(sol) -> list[str]:
    lines, r = _section('Solar position', sol)
    if r is None:
        return lines
    rows = []
    for model, x in r['models'].items():
        rows.append(
            [
                model,
                _f(x['batch']['positions_per_s']),
                _f(x['per_call']['median_ms']),
                _f(x.get('cache_per_frame', {}).get('median_ms')),
                _f(x.get('cache_per_frame', {}).get('speedup_vs_per_call')),
            ]
        )
    lines += _table(
        [
            'model',
            f'batch ({r["batch_size"]} times), positions/s',
            'per call (ms)',
            'SunCache per frame (ms)',
            'cache speed-up',
        ],
        rows,
    )
    g = r.get('paper_vs_spa_great_circle_deg', {})
    lines += [
        '',
        f'`paper` against `spa` over the batch (sun up): mean {_f(g.get("mean"))} deg, '
        f'max {_f(g.get("max"))} deg great-circle.',
    ]
    return lines + ['']


def _errormap_section(em) -> list[str]:
    lines, r = _section("Error map throughput against issue 4's target", em)
    if r is None:
        return lines
    if 'rows' in r:  # written before the target sweep was measured
        return lines + [
            'Results in an older format (no projection of the target sweep): rerun '
            '`python -m bench.run --only errormap`.',
            '',
        ]
    lines += _errormap_target_lines(r)
    b = r.get('backends')
    if b:
        lines += _errormap_backend_lines(b)
    return lines


def _errormap_target_lines(r) -> list[str]:
    """Return the measured throughput against the target sweep, with the knobs and the note."""
    lines = []
    t, smp = r['target'], r['sample']
    lines += [
        f'Target: a pitch-only sweep of {t["cells"]} cells (sun {t["sun_altitude_deg"]}, yaw '
        f'{t["yaw_deg"]}, '
        f'pitch {t["pitch_deg"]}, roll {t["roll_deg"]} deg) x {len(r["methods"])} methods = '
        f'{t["estimates"]} '
        f'estimates in <= {_f(t["limit_s"])} s on all cores. Measured: the engine on a sub-grid '
        'of the same '
        f'domain ({len(smp["sun_altitude_deg"])} sun altitudes x {len(smp["pitch_deg"])} pitches '
        'x '
        f'{smp["yaw_count"]} yaws = {smp["cells"]} cells, {smp["estimates"]} estimates), '
        f'{r["workers"]} '
        f'workers, load average {_f(r["load_average_before"][0])} -> '
        f'{_f(r["load_average_after"][0])}.',
        '',
    ]
    lines += _table(
        [
            'workers',
            'start-up (s)',
            'wall (s)',
            'cells/s',
            'estimates/s',
            'CPU ms per cell',
            f'projected {t["cells"]}-cell sweep (s)',
            f'<= {_f(t["limit_s"])} s',
        ],
        [
            [
                r['workers'],
                _f(r['startup_s']),
                _f(r['wall_s']),
                _f(r['cells_per_s']),
                _f(r['estimates_per_s']),
                _f(r['cpu_ms_per_cell']),
                _f(r['projected_target_sweep_s']),
                _pass(r['pass']),
            ]
        ],
    )
    lines += [
        '',
        'Knobs: '
        + '; '.join(f'{m} {k} ({r["pixels"].get(m, "?")} px)' for m, k in r['knobs'].items()),
        '',
        f'{r["note"]}.',
        '',
    ]
    return lines


def _errormap_backend_lines(b) -> list[str]:
    """Return the comparison of the sweep backends (issue 17) and their projection."""
    lines = []
    smp = b['sample']
    lines += [
        f'Backends (issue 17) on a sub-grid of {smp["cells"]} cells in {smp["chunks"]} chunks '
        f'({len(smp["sun_altitude_deg"])} sun altitudes x {len(smp["pitch_deg"])} pitches x '
        f'{smp["yaw_count"]} yaws), load average {_f(b["load_average_before"][0])} -> '
        f'{_f(b["load_average_after"][0])}; maps identical to the in-process one: '
        f'{"yes" if b["identical_maps"] else "NO"}.',
        '',
    ]
    lines += _table(
        [
            'backend',
            'workers',
            'start-up (s)',
            'compute (s)',
            'cells/s',
            'tasks/s',
            'overhead share',
            'CPU ms per estimate',
        ],
        [
            [
                x['backend'],
                x['workers'],
                _f(x['startup_s']),
                _f(x['compute_s']),
                _f(x['cells_per_s']),
                _f(x['tasks_per_s']),
                _f(x['overhead_share']),
                _f(x['cpu_ms_per_estimate']),
            ]
            for x in b['rows']
        ],
    )
    proj = ', '.join(
        f'{n} workers {_f(v / 3600)} h' for n, v in b['projection_1e8_estimates_s'].items()
    )
    lines += [
        '',
        'Scaling 1 -> 2 workers (LocalCluster): efficiency '
        f'{_f(b["scaling_efficiency_1_to_2"])}; '
        'one LocalCluster worker / in process: '
        f'{_f(b["localcluster_per_worker_vs_in_process"])}. '
        f'Projected 10^8-estimate map: {proj}. {b["note"]}.',
        '',
    ]
    return lines


def _errormap_sampling_section(es) -> list[str]:
    lines, r = _section('Error map sampling against full resolution (issue 4)', es)
    if r is None:
        return lines
    lines += [
        f'{r["cells"]} random cells ({r["domain"]}; seed {r["seed"]}, camera {r["camera"]}): the '
        'error a map '
        'stores at the default sweep sampling against full resolution; target < '
        f'{_f(r["target_deg"])} deg.',
        '',
    ]
    rows = [
        [
            m,
            f'{v["knobs_default"]} ({v["pixels_default"]} px)',
            f'{v["knobs_full"]} ({v["pixels_full"]} px)',
            _f(v['max_abs_diff_deg']),
            _f(v['mean_abs_diff_deg']),
            f'{v["cells_compared"]} / {r["cells"]}',
            v['status_differs'],
            _pass(v['pass']),
        ]
        for m, v in r['per_method'].items()
    ]
    lines += _table(
        [
            'method',
            'default sampling',
            'full resolution',
            'max abs diff (deg)',
            'mean abs diff (deg)',
            'cells compared',
            'status differs',
            f'< {_f(r["target_deg"])} deg',
        ],
        rows,
    )
    return lines + ['', f'{r["note"]}.', '']


def _pipeline_section(pl) -> list[str]:
    lines, r = _section('Node pipeline latency', pl)
    if r is None:
        return lines
    rows = [
        [k, _f(v.get('median_ms')), _f(v.get('p95_ms'))] for k, v in r.get('stages', {}).items()
    ]
    lines += _table(['stage', 'ms median', 'ms p95'], rows)
    if r.get('end_to_end'):
        e = r['end_to_end']
        lines += [
            '',
            f'End to end (image published -> heading received, rclpy, loopback): '
            f'{e.get("status")}, median {_f(e.get("median_ms"))} ms, p95 {_f(e.get("p95_ms"))} ms '
            f'over {e.get("n")} frames.',
        ]
    return lines + ['']


def _pass(flag) -> str:
    return 'n/a' if flag is None else ('pass' if flag else '**FAIL**')


def _knobs_label(method: str, knobs: dict) -> str:
    if _windowed(method):
        return f'window {knobs.get("window_px")} px'
    st = knobs.get('stride')
    label = 'all superpixels' if st in (None, 1) else f'stride {st}'
    return label + (f', region {knobs["region"]}' if knobs.get('region') else '')


def _estimator_speed_section(es) -> list[str]:
    lines, r = _section("Estimator speed against issue 3's targets", es)
    if r is None:
        return lines
    cam = r['camera']
    lines += [
        f'From a {cam["width_px"]} x {cam["height_px"]} {r["bit_depth"]}-bit mosaic '
        f'({r["scene"]}), one core, '
        f"{r['repeats']} timed calls per row after a warm-up: the node's front end "
        '(`HeadingFrontEnd`), '
        "superpixel demosaic of the pixels the method reads + estimate, at the estimator's "
        'defaults. '
        '`tilt_aware` is given the known pitch and roll; the paper methods run uncorrected (their '
        'tilted '
        'error is the tilt error). Pass is judged on the median'
        + ('.' if r['targets_apply'] else '; targets apply to the full sensor only (n/a here).'),
        '',
    ]
    rows = []
    for x in r['rows']:
        tt = x['total']
        rows.append(
            [
                x['method'],
                x['attitude'],
                _knobs_label(x['method'], x['knobs']),
                x['pixels'],
                _f(x['demosaic']['median_ms']),
                _f(tt['median_ms']),
                _f(tt['p95_ms']),
                f'<= {_f(x["target_ms"])}' if x.get('target_ms') is not None else '-',
                _pass(x['pass_median']),
                _pass(x['pass_p95']),
                _f(x.get('abs_error_max_deg')),
            ]
        )
    lines += _table(
        [
            'method',
            'attitude',
            'knobs',
            'pixels',
            'demosaic ms',
            'total ms median',
            'total ms p95',
            'target (ms)',
            'pass (median)',
            'pass (p95)',
            'max abs error (deg)',
        ],
        rows,
    )
    if r.get('methods_missing'):
        lines += ['', f'Methods not available: {", ".join(r["methods_missing"])}.']
    return lines + ['']


def _replay_section(rp) -> list[str]:
    lines, r = _section('Offline replay speed (issue 6)', rp)
    if r is None:
        return lines
    tgt = f'>= {r["target_x_real_time"]:g}x'
    lines += [
        f'`{r["record_command"]}` ({r["frames"]} frames, {_f(r.get("bag_mib"))} MiB, recorded in '
        f'{_f(r.get("record_s"))} s), then `{r["replay_command"]}` at its default knobs (the '
        'shipped '
        'error map, figures written).',
        '',
    ]
    rows = [
        [
            f'whole command ({_f(r["bag_duration_s"])} s recording)',
            f'{_f(r["whole_command_s"])} s',
            f'{_f(r["whole_command_x_real_time"])}x',
            tgt,
            _pass(r['pass_whole_command']),
        ],
        [
            f'per frame after start-up (frames {r.get("skipped_frames")}..{r["frames"]})',
            f'{_f(r.get("per_frame_ms"))} ms (median {_f(r.get("per_frame_ms_median"))}, '
            f'p95 {_f(r.get("per_frame_ms_p95"))})',
            f'{_f(r.get("per_frame_x_real_time"))}x',
            tgt,
            _pass(r.get('pass_per_frame')),
        ],
        [
            '10-minute run (extrapolated: overhead + per-frame)',
            f'overhead {_f(r.get("overhead_s"))} s',
            f'{_f(r.get("long_run_x_real_time"))}x',
            tgt,
            _pass(r.get('pass_long_run')),
        ],
    ]
    lines += _table(['measure', 'time', 'x real time', 'target', 'pass'], rows)
    runs = r.get('runs') or []
    if len(runs) > 1:
        lines += [
            '',
            f'The run with the median per-frame time of {len(runs)} replays of the same bag; per '
            'frame in '
            'each: '
            + ', '.join(
                f'{_f(x.get("per_frame_ms"))} ms ({_f(x.get("per_frame_x_real_time"))}x)'
                for x in runs
            )
            + '.',
        ]
    al = r.get('all_methods')
    if al:
        lines += [
            '',
            "The command's default method set (the four plus tilt_aware, "
            f'`{al["replay_command"]}`), '
            f'replayed interleaved with the runs above: per frame {_f(al.get("per_frame_ms"))} ms '
            f'({_f(al.get("per_frame_x_real_time"))}x; runs: '
            + ', '.join(f'{_f(x.get("per_frame_x_real_time"))}x' for x in al.get('runs') or [])
            + f'), whole command {_f(al.get("whole_command_x_real_time"))}x, 10-minute run '
            f'{_f(al.get("long_run_x_real_time"))}x.',
        ]
    st = r.get('stage_ms_median') or {}
    lines += [
        '',
        f'Replay loop alone {_f(r.get("replay_loop_s"))} s '
        f'({_f(r.get("replay_loop_x_real_time"))}x); '
        f'CPU {_f(r.get("cpu_s"))} s ({_f(r.get("cpu_x_real_time"))}x on an idle core). Median '
        'per frame: ' + ', '.join(f'{k} {_f(v)} ms' for k, v in st.items()) + '.',
    ]
    return lines + ['']


def _graph_section(gr) -> list[str]:
    lines, r = _section('ROS graph at 10 Hz (issue 5)', gr)
    if r is None:
        return lines
    lines += [
        f'`polarization-compass sim --realtime` at {_f(r["rate_hz"])} Hz, {r["resolution"]}, '
        f'{r["expected_frames"]} frames ({r["turns"]:g} turn at {r["turn_rate_deg_s"]:g} deg/s). '
        'Sustained rate: '
        "the slowest estimator/corrector node's processed inputs per second (its last 100); "
        'latency: image '
        'published by the simulator to the heading at the evaluator (wall clock).',
        '',
    ]
    rows, detail = [], []
    for run in r['runs']:
        if run.get('status') != 'ok':
            rows.append(
                [run['graph'], run.get('status', '?')[:80], '-', '-', '-', '-', '-', '**FAIL**']
            )
            continue
        sim, ch, lat = run['simulator'], run['checks'], run['least_squares_corrected_latency_ms']
        rows.append(
            [
                run['graph'],
                f'{sim["frames"]}/{run["expected_frames"]} ({_pass(ch["all_frames_published"])})',
                f'{sim["late_frames"]} (target 0: {_pass(ch["no_late_frames"])})',
                f'{run["missed_total"]} (target 0: {_pass(ch["no_missed_frames"])})',
                f'{_f(run["sustained_rate_hz"])} Hz, {run.get("slowest_node")} (target 10: '
                f'{_pass(ch["sustained_rate"])})',
                _f(sim.get('publish_rate_hz')),
                f'{_f(lat["p50"])} / {_f(lat["p95"])} (target p95 <= {_f(lat["target_p95"])}: '
                f'{_pass(ch["least_squares_latency_p95"])})',
                _pass(run['pass']),
            ]
        )
        for name, d in run['streams'].items():
            detail.append(
                [
                    run['graph'],
                    name,
                    d['count'],
                    d['missed'],
                    _f(d['latency_ms_p50']),
                    _f(d['latency_ms_p95']),
                    _f(d['latency_ms_max']),
                ]
            )
    lines += _table(
        [
            'graph',
            'frames published',
            'late frames',
            'frames missed (all streams)',
            'sustained rate (slowest node)',
            'simulator publish rate (Hz)',
            'least_squares corrected latency p50 / p95 (ms)',
            'pass',
        ],
        rows,
    )
    for run in r['runs']:
        if run.get('status') == 'ok' and run.get('sim_exit_code'):
            lines += [
                '',
                f'Note: {run["graph"]}: `sim` exited {run["sim_exit_code"]} after the run '
                f"({run.get('sim_error', '')[:200]}); the evaluator's report was complete and is "
                'used.',
            ]
    if detail:
        lines += ['', 'Per stream:', '']
        lines += _table(
            ['graph', 'stream', 'frames', 'missed', 'latency p50 (ms)', 'p95 (ms)', 'max (ms)'],
            detail,
        )
    return lines + ['']


def _peers_section(pe) -> list[str]:
    lines, r = _section('Peers', pe)
    if r is None:
        return lines
    for peer in ('pyskylumos', 'polanalyser'):
        p = r['peers'].get(peer, {})
        where = (
            f' (Python {p.get("python")} at `{p.get("interpreter")}`)'
            if p.get('interpreter')
            else ''
        )
        lines.append(
            f'- {peer}: '
            f'{p.get("status")}{" " + str(p.get("version")) if p.get("version") else ""}{where}'
        )
    lines.append('')
    if r['ratios']:
        lines += _table(
            ['comparison', 'peer (ms)', 'ours (ms)', 'peer / ours'],
            [
                [k, _f(v['peer_ms']), _f(v['ours_ms']), _f(v['peer_over_ours'])]
                for k, v in r['ratios'].items()
            ],
        )
        lines += [
            '',
            f'Image size {r["image_size_px"][0]} x {r["image_size_px"][1]}, one thread each. '
            f'{r["note"]}.',
        ]
    return lines + ['']


def build(out_dir) -> list[Path]:
    d = Path(out_dir)
    groups = _load(d)
    if not groups:
        return []
    paths = []
    acc = groups.get('accuracy')
    crb = groups.get('crb')
    cells = _ok_cells(acc)
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
    lines += _accuracy_section(acc, crb)
    lines += _crb_section(crb)
    lines += _simulator_section(groups.get('simulator'))
    lines += _solar_section(groups.get('solar'))
    lines += _errormap_section(groups.get('errormap'))
    lines += _errormap_sampling_section(groups.get('errormap_sampling'))
    lines += _pipeline_section(groups.get('pipeline'))
    lines += _estimator_speed_section(groups.get('estimator_speed'))
    lines += _replay_section(groups.get('replay'))
    lines += _graph_section(groups.get('graph'))
    lines += _peers_section(groups.get('peers'))
    md = d / 'summary.md'
    md.write_text('\n'.join(lines).rstrip() + '\n')
    return [md] + paths
