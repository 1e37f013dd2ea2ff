#!/usr/bin/env python3

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
Real-data results for docs/photodiode-arrays.md.

The 36 turns of ../shared/data/real-polop (GPL-3.0, read in place) through the photodiode-array
estimators; per session heading error against the reference, sigma coverage, statuses; a figure of
the error through one turn.

Usage: python tools/polop_results.py [--plot docs/figures/photodiode_turn_error.png] [--json
out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from polarization_compass.conventions import fold_axial_deg, wrap_180_deg  # noqa: E402
from polarization_compass.photodiode.calibrate import calibrate_gains  # noqa: E402
from polarization_compass.photodiode.geometry import geometry_from_dict  # noqa: E402
from polarization_compass.photodiode.heading import (  # noqa: E402
    estimate_recording,
    make_array_estimator,
)
from polarization_compass.solar import sun_position  # noqa: E402
import polop_json as pj  # noqa: E402


def sun_of(row, turn):
    t = np.datetime64(turn.time_utc.rstrip('Z'), 's') + np.timedelta64(int(turn.t_offset_s), 's')
    p = sun_position(t, float(row['lat']), float(row['lon']))
    return p.azimuth_deg, p.altitude_deg


def run_session(row, turns, geometry, method):
    tilt = 0.0 if method == 'tilt_aware' else None
    est = make_array_estimator(method, geometry)
    out = []
    for turn in turns:
        az, alt = sun_of(row, turn)
        res = estimate_recording(est, turn.intensities, az, alt, tilt, tilt)
        out.append((turn, res))
    return out


def summarise(per_turn) -> dict:
    status, e_ok, s_ok, e_amb = {}, [], [], []
    for turn, res in per_turn:
        for r, ref in zip(res, turn.reference_bearing_deg):
            status[r.status.value] = status.get(r.status.value, 0) + 1
            if r.status.value == 'ok':
                e_ok.append(float(wrap_180_deg(r.bearing_deg - ref)))
                s_ok.append(r.sigma_deg)
            elif r.status.value == 'ambiguous':
                e_amb.append(float(fold_axial_deg(r.bearing_deg - ref)))
    n = sum(status.values())
    e, s = np.array(e_ok), np.array(s_ok)
    d = {
        'samples': n,
        'status_pct': {k: round(100.0 * v / n, 1) for k, v in sorted(status.items())},
    }
    if e.size:
        a = np.abs(e)
        d.update(
            rms_deg=float(np.sqrt(np.mean(e**2))),
            p95_deg=float(np.percentile(a, 95)),
            mean_deg=float(np.mean(e)),
            rms_minus_mean_deg=float(np.std(e)),
            flips_pct=float(100 * np.mean(a > 90)),
            cov1=float(np.mean(a < s)),
            cov2=float(np.mean(a < 2 * s)),
            median_sigma_deg=float(np.median(s)),
        )
    if e_amb:
        d['ambiguous_axial_rms_deg'] = float(np.sqrt(np.mean(np.square(e_amb))))
    return d


def plot_turn(per_turn_by_label, path):
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(
        len(per_turn_by_label),
        1,
        figsize=(9, 3.2 * len(per_turn_by_label)),
        dpi=110,
        squeeze=False,
    )
    for ax, (label, (turn, res)) in zip(axes[:, 0], per_turn_by_label.items()):
        idx = np.arange(len(res))
        err = np.array(
            [
                wrap_180_deg(r.bearing_deg - b) if r.status.value == 'ok' else np.nan
                for r, b in zip(res, turn.reference_bearing_deg)
            ]
        )
        amb = np.array(
            [
                fold_axial_deg(r.bearing_deg - b) if r.status.value == 'ambiguous' else np.nan
                for r, b in zip(res, turn.reference_bearing_deg)
            ]
        )
        sig = np.array([r.sigma_deg if r.status.value == 'ok' else np.nan for r in res])
        ax.fill_between(
            idx, -2 * sig, 2 * sig, color='tab:blue', alpha=0.18, lw=0, label='+-2 sigma'
        )
        ax.plot(idx, err, '.', ms=3, color='tab:blue', label='error, status ok')
        if np.isfinite(amb).any():
            ax.plot(idx, amb, '.', ms=3, color='tab:orange', label='axial error, ambiguous')
        bad = [i for i, r in enumerate(res) if not r.ok]
        if bad:
            ax.plot(
                bad,
                np.zeros(len(bad)) - 38,
                '|',
                color='tab:red',
                label='no heading (poor_fit ...)',
            )
        ax2 = ax.twinx()
        ax2.plot(
            idx, np.degrees(np.unwrap(np.radians(turn.reference_bearing_deg))), color='0.5', lw=1
        )
        ax2.set_ylabel('reference bearing, deg', color='0.4')
        ax.axhline(0, color='k', lw=0.6)
        ax.set_ylim(-40, 40)
        ax.set_xlabel('sample (no timestamps in the data: ~5 s still, one turn, ~5 s still)')
        ax.set_ylabel('heading error, deg')
        ax.set_title(label, fontsize=9)
        ax.legend(loc='upper left', fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--plot', help='PNG of the error through one turn per session')
    ap.add_argument('--json', help='write the numbers as JSON')
    args = ap.parse_args()
    if not pj.available():
        print(pj.skip_reason(), file=sys.stderr)
        return 2
    rows = pj.sessions()
    turns = {r['session']: pj.load_session(r) for r in rows}
    raw = geometry_from_dict(pj.geometry_dict())
    clear = [t.intensities for r in rows for t in turns[r['session']] if t.sky == 'clear']
    cal = calibrate_gains(clear, raw)
    calibrated = raw.with_gains(cal.gains)
    results = {
        'calibration': {
            'gains': cal.gains,
            'gains_sigma': cal.gains_sigma,
            'condition': cal.condition,
            'note': cal.note,
        }
    }
    figure = {}
    for gname, geo in (('raw gains', raw), ('calibrated gains', calibrated)):
        for method in ('tilt_aware', 'least_squares'):
            for r in rows:
                per = run_session(r, turns[r['session']], geo, method)
                key = f'{method} | {gname} | {r["session"]} ({turns[r["session"]][0].sky})'
                results[key] = summarise(per)
                if gname == 'raw gains' and method == 'tilt_aware':
                    figure[
                        f'{r["session"]} ({turns[r["session"]][0].sky}), turn 6, tilt_aware '
                        '(pitch = roll = 0), '
                        f'raw gains'
                    ] = per[5]
    print(
        f'{"method | gains | session":<68} {"ok%":>5} {"amb%":>5} {"poor%":>5} {"rms":>5} '
        f'{"p95":>5} {"mean":>6} '
        f'{"sd":>5} {"cov1":>5} {"cov2":>5} {"sig":>5}'
    )
    for k, d in results.items():
        if k == 'calibration':
            continue
        sp = d['status_pct']
        print(
            f'{k:<68} {sp.get("ok", 0):>5.1f} {sp.get("ambiguous", 0):>5.1f} '
            f'{sp.get("poor_fit", 0):>5.1f} '
            f'{d.get("rms_deg", float("nan")):>5.1f} {d.get("p95_deg", float("nan")):>5.1f} '
            f'{d.get("mean_deg", float("nan")):>6.1f} '
            f'{d.get("rms_minus_mean_deg", float("nan")):>5.1f} '
            f'{d.get("cov1", float("nan")):>5.2f} {d.get("cov2", float("nan")):>5.2f} '
            f'{d.get("median_sigma_deg", float("nan")):>5.1f}'
        )
    print('calibration condition per unit:', [round(c, 2) for c in cal.condition])
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if args.plot:
        plot_turn(figure, args.plot)
    return 0


if __name__ == '__main__':
    sys.exit(main())
