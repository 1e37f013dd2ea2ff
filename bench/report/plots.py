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

"""The Pareto plots of the summary: error against time per method and knob set."""

from __future__ import annotations

import math
from pathlib import Path

from .formatting import ERROR_FLOOR_DEG, method_colour, method_rank


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
        key=method_rank,
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
