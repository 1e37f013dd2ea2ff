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

"""Outputs of a replay: ``replay.csv``, ``summary.csv``/``summary.json`` and the figures."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from .processing import MethodRow
from .threads import ReplayResult

__all__ = ['write_outputs', 'plot_replay']


def _fmt(v):
    if v is None:
        return ''
    if isinstance(v, float):
        return f'{v:.6f}'
    return v


def write_outputs(result: ReplayResult, out_dir, bag_path: str = '', plots: bool = True) -> dict:
    """
    Write a replay's ``replay.csv``, ``summary.csv``, ``summary.json`` and figures.

    ``replay.csv`` has one row per frame and method (:data:`MethodRow.CSV_FIELDS`; angles [deg],
    times [s]); ``summary.csv``/``summary.json`` the evaluator's statistics per stream [deg], the
    statuses per method, the skip counts per topic and reason, the bag's problems and the speed.
    Empty cells, never NaN, where a value does not exist.

    Parameters
    ----------
    result : ReplayResult
        What :func:`~polarization_compass.replay.threads.replay_bag` returned.
    out_dir : str or os.PathLike
        Output directory (created).
    bag_path : str, default ""
        The bag, recorded in ``summary.json``.
    plots : bool, default True
        Also draw the figures (:func:`plot_replay`).

    Returns
    -------
    dict
        ``{"csv", "summary_csv", "summary_json"[, figure keys]: pathlib.Path}``.

    """
    from ..evaluation_report import write_summary_csv

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = result.rows[0].stamp_ns if result.rows else 0
    paths = {}
    p = out / 'replay.csv'
    with p.open('w', newline='') as f:
        w = csv.writer(f)
        w.writerow(MethodRow.CSV_FIELDS)
        for r in result.rows:
            w.writerow(
                [
                    f'{r.stamp_ns / 1e9:.9f}',
                    f'{(r.stamp_ns - t0) / 1e9:.6f}',
                    r.method,
                    r.status,
                    *(
                        _fmt(v)
                        for v in (
                            r.raw_bearing_deg,
                            r.corrected_bearing_deg,
                            r.reference_bearing_deg,
                            r.raw_error_deg,
                            r.corrected_error_deg,
                        )
                    ),
                    r.correction_status,
                    _fmt(r.sigma_deg),
                    r.pixels,
                    *(
                        _fmt(v)
                        for v in (
                            r.pitch_deg,
                            r.roll_deg,
                            r.sun_azimuth_deg,
                            r.sun_altitude_deg,
                            r.prior_bearing_deg,
                        )
                    ),
                    r.reason,
                ]
            )
    paths['csv'] = p
    paths['summary_csv'] = write_summary_csv(out / 'summary.csv', result.summary)
    statuses: dict = {}
    for r in result.rows:
        statuses.setdefault(r.method, {}).setdefault(r.status, 0)
        statuses[r.method][r.status] += 1
    js = {
        'bag': str(bag_path),
        'error_map': result.error_map,
        'frames': result.frames,
        'bag_duration_s': result.bag_duration_s,
        'wall_s': result.wall_s,
        'cpu_s': result.cpu_s,
        'speed_x_real_time': result.speed_x_real_time,
        'speed_x_real_time_cpu': result.speed_x_real_time_cpu,
        'statistics': result.summary,
        'statuses': statuses,
        'topics': result.tally.to_dict(),
        'problems': result.plan.problems,
        'timing_ms_median': {k: float(np.median(v)) for k, v in result.timing_ms.items() if v},
    }
    p = out / 'summary.json'
    p.write_text(json.dumps(js, indent=1, default=float, allow_nan=False))
    paths['summary_json'] = p
    if plots:
        paths.update(plot_replay(result, out))
    return paths


def plot_replay(result: ReplayResult, out_dir) -> dict:
    """
    Draw the replay's figures like the paper's.

    Error against time per method (``errors_raw.png``, Figs 17-19), raw against corrected per
    method (``errors_corrected.png``, Figs 20-22), and the evaluator's error against the reference
    bearing (``errors_vs_bearing.png``); errors [deg], time [s] from the first frame.

    Parameters
    ----------
    result : ReplayResult
        What :func:`~polarization_compass.replay.threads.replay_bag` returned.
    out_dir : str or os.PathLike
        Output directory (must exist).

    Returns
    -------
    dict
        ``{"plot_raw", "plot_corrected", "plot_vs_bearing": pathlib.Path}``, only those drawn (none
        without evaluated headings).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4, Figs 17-22.

    """
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from ..evaluation_report import plot_report

    out = Path(out_dir)
    paths = {}
    rows = result.rows
    if not rows:
        return paths
    methods, series = _error_series(rows)
    tilt_txt = _tilt_text(rows)
    if not any(series[m]['raw'] for m in methods):
        return paths
    paths['plot_raw'] = _plot_raw(plt, series, methods, tilt_txt, out / 'errors_raw.png')
    corrected = [m for m in methods if series[m]['cor']]
    if corrected:
        paths['plot_corrected'] = _plot_corrected(
            plt, series, corrected, tilt_txt, out / 'errors_corrected.png'
        )
    p = plot_report(
        out / 'errors_vs_bearing.png', result.matches, title='error against reference bearing'
    )
    if p is not None:
        paths['plot_vs_bearing'] = p
    return paths


def _error_series(rows) -> tuple[list, dict]:
    """Return the methods in row order and their raw and corrected errors [deg] by time [s]."""
    t0 = rows[0].stamp_ns
    methods = list(dict.fromkeys(r.method for r in rows))
    series = {}
    for r in rows:
        s = series.setdefault(r.method, {'t': [], 'raw': [], 'tc': [], 'cor': []})
        if r.raw_error_deg is not None:
            s['t'].append((r.stamp_ns - t0) / 1e9)
            s['raw'].append(r.raw_error_deg)
        if r.corrected_error_deg is not None:
            s['tc'].append((r.stamp_ns - t0) / 1e9)
            s['cor'].append(r.corrected_error_deg)
    return methods, series


def _tilt_text(rows) -> str:
    """Return the figures' note on the IMU tilt: mean pitch and roll [deg], or unknown."""
    pitch = [r.pitch_deg for r in rows if r.pitch_deg is not None]
    roll = [r.roll_deg for r in rows if r.roll_deg is not None]
    return (
        f'IMU pitch {round(float(np.mean(pitch)), 1) + 0.0:.1f} deg, roll '
        f'{round(float(np.mean(roll)), 1) + 0.0:.1f}'
        ' deg (mean)'
        if pitch
        else 'tilt unknown'
    )


def _plot_raw(plt, series: dict, methods: list, tilt_txt: str, p: Path) -> Path:
    """Draw every method's raw error against time into ``p`` (Figs 17-19); return ``p``."""
    fig, ax = plt.subplots(figsize=(8.0, 4.2), dpi=110)
    for m in methods:
        s = series[m]
        if s['raw']:
            ax.plot(
                s['t'],
                s['raw'],
                '-',
                lw=1.0,
                marker='.',
                ms=2.5,
                label=f'{m} (rms {_rms(s["raw"]):.2f})',
            )
    ax.axhline(0.0, color='0.5', lw=0.6)
    ax.set_xlabel('time since first image, s')
    ax.set_ylabel('heading error (estimate - reference), deg')
    ax.set_title(f'Raw heading error per method; {tilt_txt}', fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc='best')
    fig.tight_layout()
    fig.savefig(p)
    plt.close(fig)
    return p


def _plot_corrected(plt, series: dict, corrected: list, tilt_txt: str, p: Path) -> Path:
    """Draw raw against corrected error, one panel per method, into ``p`` (Figs 20-22)."""
    n = len(corrected)
    fig, axes = plt.subplots(
        n, 1, figsize=(8.0, 2.3 * n + 0.8), dpi=110, sharex=True, squeeze=False
    )
    for ax, m in zip(axes[:, 0], corrected):
        s = series[m]
        ax.plot(
            s['t'],
            s['raw'],
            '-',
            lw=1.0,
            color='tab:red',
            label=f'raw (rms {_rms(s["raw"]):.2f})',
        )
        ax.plot(
            s['tc'],
            s['cor'],
            '-',
            lw=1.0,
            color='tab:blue',
            label=f'corrected (rms {_rms(s["cor"]):.2f})',
        )
        ax.axhline(0.0, color='0.5', lw=0.6)
        ax.set_ylabel(f'{m}\nerror, deg')
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc='best')
    axes[-1, 0].set_xlabel('time since first image, s')
    fig.suptitle(f'Tilt correction with the error map; {tilt_txt}', fontsize=9)
    fig.tight_layout()
    fig.savefig(p)
    plt.close(fig)
    return p


def _rms(v) -> float:
    a = np.asarray(v, dtype=float)
    return float(math.sqrt(float(np.mean(a * a)))) if a.size else 0.0
