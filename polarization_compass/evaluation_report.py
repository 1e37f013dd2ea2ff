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
The evaluator's reports: matched samples and summary as CSV, the error plot, the text table.

Written by the ``error_evaluator`` node and the replay from the matches and summary of
:class:`~polarization_compass.evaluation.StampMatcher`; the table is what ``polarization-compass
sim`` prints from the summary.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from .evaluation import Match
from .evaluation_stats import STAT_FIELDS

__all__ = [
    'format_table',
    'plot_report',
    'write_samples_csv',
    'write_summary_csv',
]


def write_samples_csv(path, matches: list[Match], extra_fields: tuple = ()) -> Path:
    """
    Write one CSV row per matched estimate.

    Columns: ``stamp_s`` [s], ``stream``, ``true_bearing_deg``, ``estimated_bearing_deg``,
    ``error_deg`` [deg], ``axial`` (0/1), then ``extra_fields``.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory is created.
    matches : list of Match
        The matches, in the order to write.
    extra_fields : tuple of str, default ()
        Keys of :attr:`Match.extra` to add as columns (empty where a match lacks one).

    Returns
    -------
    pathlib.Path
        The file written.

    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open('w', newline='') as f:
        w = csv.writer(f)
        w.writerow(
            [
                'stamp_s',
                'stream',
                'true_bearing_deg',
                'estimated_bearing_deg',
                'error_deg',
                'axial',
                *extra_fields,
            ]
        )
        for m in matches:
            w.writerow(
                [
                    f'{m.stamp_ns / 1e9:.9f}',
                    m.stream,
                    f'{m.true_bearing_deg:.6f}',
                    f'{m.estimated_bearing_deg:.6f}',
                    f'{m.error_deg:.6f}',
                    int(m.axial),
                    *[m.extra.get(k, '') for k in extra_fields],
                ]
            )
    return p


def write_summary_csv(path, summary: dict, extra: dict | None = None) -> Path:
    """
    Write one CSV row per stream with its :meth:`StampMatcher.summary` fields.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory is created.
    summary : dict
        ``{stream: fields}`` as :meth:`StampMatcher.summary` returns.
    extra : dict, optional
        ``{stream: {column: value}}``: more columns (sorted by name), empty where missing.

    Returns
    -------
    pathlib.Path
        The file written.

    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    extra = extra or {}
    extra_cols = sorted({k for v in extra.values() for k in v})
    cols = [
        'stream',
        *STAT_FIELDS,
        'received',
        'matched',
        'missed',
        'unmatched',
        'axial',
        *extra_cols,
    ]
    with p.open('w', newline='') as f:
        w = csv.writer(f)
        w.writerow(cols)
        for name, d in summary.items():
            row = [name]
            for c in cols[1:]:
                v = d.get(c, extra.get(name, {}).get(c, ''))
                row.append(
                    f'{v:.6f}' if isinstance(v, float) else (int(v) if isinstance(v, bool) else v)
                )
            w.writerow(row)
    return p


def plot_report(path, matches: list[Match], title: str = '') -> Path | None:
    """
    Plot the error against the true bearing per stream, one panel per method.

    Like the paper's Fig 17. Streams named ``<method>/raw`` and ``<method>/corrected`` share a
    panel; each legend entry gives the stream's RMS error [deg].

    Parameters
    ----------
    path : str or os.PathLike
        Output image (format from the suffix, e.g. ``.png``); its directory is created.
    matches : list of Match
        The matched estimates.
    title : str, default ""
        Figure title, none when empty.

    Returns
    -------
    pathlib.Path or None
        The file written, or None when there is nothing to plot.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4 and
       Figs 17-19 (orientation error against the heading).

    """
    if not matches:
        return None
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    by_stream: dict[str, list[Match]] = {}
    for m in matches:
        by_stream.setdefault(m.stream, []).append(m)
    methods = sorted({s.split('/')[0] for s in by_stream})
    n = len(methods)
    fig, axes = plt.subplots(
        n, 1, figsize=(8.0, 2.4 * n + 0.6), dpi=100, sharex=True, squeeze=False
    )
    for ax, method in zip(axes[:, 0], methods):
        for name in sorted(s for s in by_stream if s.split('/')[0] == method):
            ms = sorted(by_stream[name], key=lambda m: m.stamp_ns)
            x = np.array([m.true_bearing_deg for m in ms])
            y = np.array([m.error_deg for m in ms])
            label = name.split('/', 1)[1] if '/' in name else name
            ax.plot(x, y, '.', ms=3, label=f'{label} (rms {math.sqrt(float(np.mean(y * y))):.2f})')
        ax.axhline(0.0, color='0.5', lw=0.6)
        ax.set_ylabel(f'{method}\nerror, deg')
        ax.legend(loc='upper right', fontsize=7)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel('true bearing of camera +y, deg clockwise from North')
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p)
    plt.close(fig)
    return p


def format_table(summary: dict, realtime: bool = False) -> str:
    """
    Format the per-method table of error statistics, frames and latency.

    One row per method and stream kind (raw, corrected, fused): frames, missed, not received,
    mean, RMS, p95 and max error [deg] and the p95 latency [ms]; then the nodes' processing times
    and notes on frames not published or missed.

    Parameters
    ----------
    summary : dict
        The evaluator's summary (``evaluation_summary.json``): ``truth_frames``, ``streams``
        (:meth:`~polarization_compass.evaluation.StampMatcher.summary`) and optionally ``nodes``.
    realtime : bool, default False
        Whether the run was at the camera rate; a lockstep run gets a note that its latency
        includes waiting for the slowest node.

    Returns
    -------
    str
        The table, lines joined with newlines.

    """
    streams = summary.get('streams', {})
    from .estimators import registry
    from .evaluation import not_received

    order = list(registry.names())
    methods = sorted({k.split('/')[0] for k in streams}, key=lambda m: (order + [m]).index(m))
    n = summary.get('truth_frames', 0)
    head = (
        f'{"method":<14} {"kind":<10} {"frames":>7} {"missed":>6} {"not_received":>12} '
        f'{"mean":>8} {"rms":>8} {"p95":>8} '
        f'{"max":>8} {"lat p95 ms":>10}'
    )
    lines = [f'heading error = estimated - true bearing (deg), {n} frames', head, '-' * len(head)]
    if any(k.endswith('/fused') for k in streams):
        lines[0] += (
            "; fused = robot_localization's filtered yaw at the truth stamps "
            '(odometry fused: the wheel odometry alone)'
        )
    for m in methods:
        for kind in ('raw', 'corrected', 'fused'):
            d = streams.get(f'{m}/{kind}')
            if d is None:
                continue
            label = (
                'tilt-aware' if kind == 'raw' and m in registry.tilt_methods() else kind
            )  # its raw heading is final
            # a filter's yaw is sampled at the truth stamps: no arrival latency of its own
            lat = '-' if kind == 'fused' else f'{d.get("latency_ms_p95", 0.0):.1f}'
            lines.append(
                f'{m:<14} {label:<10} {d["count"]:>7d} {d["missed"]:>6d} '
                f'{d.get("not_received", not_received(streams, f"{m}/{kind}")):>12d} '
                f'{d["mean"]:>8.3f} {d["rms"]:>8.3f} '
                f'{d["p95"]:>8.3f} {d["max"]:>8.3f} {lat:>10}'
            )
    nodes = summary.get('nodes', {})
    if nodes:
        lines.append(
            'per node (wall ms from input to output, p50/p95; rate over the last 100 inputs):'
        )
        for name, v in nodes.items():
            if 'processing_ms_p50' in v:
                lines.append(
                    f'  {name:<34} {float(v["processing_ms_p50"]):8.1f} '
                    f'{float(v["processing_ms_p95"]):8.1f} ms '
                    f'{float(v.get("rate_hz", 0)):6.1f} Hz  rejected {v.get("rejected", "0")}'
                )
            elif 'frame_ms_p95' in v:
                lines.append(
                    f'  {name:<34} frame p95 {float(v["frame_ms_p95"]):.1f} ms, {v.get("frames")} '
                    'frames, '
                    f'{v.get("late_frames")} late'
                )
    for name, d in streams.items():
        if d.get('not_published'):
            why = ', '.join(f'{k} x{v}' for k, v in sorted(d['not_published'].items()))
            lines.append(f'note: {name}: frames not published: {why}')
    if any(d.get('missed') for d in streams.values()):
        lines.append(
            'missed: truth frames without an estimate; not_received: those that no node declined '
            '(lost on the way, e.g. images dropped by best-effort transport)'
        )
    if not realtime:
        lines.append(
            '(lockstep run: latency includes waiting for the slowest node; use --realtime to '
            'measure it)'
        )
    return '\n'.join(lines)
