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
Mount calibration on the real POL-OP sessions, leave one out (docs/photodiode-arrays.md).

The mount is fitted (:func:`polarization_compass.mount_fit.fit_mount`) from the turns of the other
sessions and applied to the held-out one (``tilt_aware``, body level): within-turn scatter of the
bearing plus IMU yaw, RMS error against the reference and ok results off by more than 90 deg,
before and after (the sky gate of ``fit_mount_recordings`` names the sessions it used). Also
from the other clear-sky session alone. The data are ../shared/data/real-polop (GPL-3.0, read in
place).

Usage: python tools/mount_calibration.py [--plot docs/figures/mount_calibration.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from polarization_compass.conventions import wrap_180_deg  # noqa: E402
from polarization_compass.estimators.base import Status  # noqa: E402
from polarization_compass.mount_fit import MountFitError, turn_samples  # noqa: E402
from polarization_compass.mount_recordings import (  # noqa: E402
    fit_mount_recordings,
    heading_scatter_deg,
)
from polarization_compass.photodiode.geometry import geometry_from_dict  # noqa: E402
from polarization_compass.photodiode.heading import (  # noqa: E402
    estimate_recording,
    make_array_estimator,
)
from polarization_compass.photodiode.stokes import fit_stokes  # noqa: E402
from polarization_compass.solar import sun_position  # noqa: E402
import polop_json as pj  # noqa: E402

STEP = 4  # every 4th sample: ~100 per turn


def load(row, geometry) -> dict:
    """Return one session's turns: readings, IMU yaw, turn label, sun, reference, fit samples."""
    s = {'session': row['session'], 'I': [], 'yaw': [], 'turn': [], 'az': [], 'alt': [], 'ref': []}
    for turn in pj.load_session(row):
        yaw = np.radians(float(row['H0_intensity_deg']) - turn.reference_bearing_deg)[::STEP]
        t = np.datetime64(turn.time_utc.rstrip('Z'), 's')
        t = t + np.timedelta64(int(turn.t_offset_s), 's')
        p = sun_position(t, float(row['lat']), float(row['lon']))
        n = yaw.size
        s['I'].append(turn.intensities[::STEP])
        s['yaw'].append(yaw)
        s['turn'].append(np.full(n, turn.index))
        s['az'].append(np.full(n, float(p.azimuth_deg)))
        s['alt'].append(np.full(n, float(p.altitude_deg)))
        s['ref'].append(turn.reference_bearing_deg[::STEP])
    s = {k: (np.concatenate(v) if isinstance(v, list) else v) for k, v in s.items()}
    st = fit_stokes(s['I'], geometry)
    s['fit'] = turn_samples(st, geometry, s['yaw'], s['turn'], s['az'], s['alt'])
    return s


def evaluate(s, geometry) -> dict:
    """Return scatter, rms error, ok count and gross errors of tilt_aware on one session."""
    est = make_array_estimator('tilt_aware', geometry)
    res = estimate_recording(est, s['I'], s['az'], s['alt'], 0.0, 0.0)
    ok = np.array([r.status == Status.OK for r in res])
    b = np.array([r.bearing_deg if r.status == Status.OK else np.nan for r in res])
    err = wrap_180_deg(np.where(ok, b, 0.0) - s['ref'])
    scatter, n = heading_scatter_deg(b, s['yaw'], s['turn'], ok)
    return {
        'scatter_deg': scatter,
        'ok': n,
        'rms_deg': float(np.sqrt(np.mean(err[ok] ** 2))),
        'off90': int(np.sum(np.abs(err[ok]) > 90.0)),
        'err': np.where(ok, err, np.nan),
    }


def leave_one_out(sessions, geometry, sources=None) -> list:
    """Per held-out session: the mount from the others (or ``sources``) and before/after."""
    rows = []
    for i, s in enumerate(sessions):
        src = [o for j, o in enumerate(sessions) if j != i] if sources is None else sources[i]
        if not src:
            continue
        parts = [o['fit'] for o in src]
        for j, p in enumerate(parts):  # distinct turn labels per session
            p.turn = p.turn % 1000 + 1000 * j
        try:
            fit = fit_mount_recordings(geometry, parts)
            mount, refused, warning = fit.mount, '', fit.warning
            used = [src[i - 1]['session'][:5] for i in fit.used]
        except MountFitError as exc:
            mount, refused, warning, used = None, str(exc), '', []
        before = evaluate(s, geometry)
        rows.append(
            {
                'session': s['session'],
                'from': ' + '.join(o['session'][:5] for o in src),
                'used': ' + '.join(used),
                'sun_alt': float(np.mean(s['alt'])),
                'mount': mount,
                'refused': refused,
                'warning': warning,
                'before': before,
                'after': before if mount is None else evaluate(s, geometry.with_mount(mount)),
            }
        )
    return rows


def table(rows) -> str:
    """Return the markdown table of :func:`leave_one_out` rows."""
    out = [
        '| held out | sun | mount from | used (sky gate) | pitch, roll (deg) | '
        'within-turn scatter (deg) | RMS vs reference (deg) | ok off > 90 deg |',
        '|---|---|---|---|---|---|---|---|',
    ]
    for r in rows:
        m, b, a = r['mount'], r['before'], r['after']
        mount = (
            'refused: ' + r['refused'].split(': ', 1)[-1][:40]
            if m is None
            else f'{m.pitch_deg:.1f} +- {m.pitch_sigma_deg:.1f}, {m.roll_deg:.1f} +- '
            f'{m.roll_sigma_deg:.1f}'
            + (' (disagree: widened)' if 'disagree' in r.get('warning', '') else '')
        )
        out.append(
            f'| {r["session"]} | {r["sun_alt"]:.0f} | {r["from"]} | {r["used"] or "-"} | '
            f'{mount} | '
            f'{b["scatter_deg"]:.2f} -> {a["scatter_deg"]:.2f} | '
            f'{b["rms_deg"]:.1f} -> {a["rms_deg"]:.1f} | {b["off90"]} -> {a["off90"]} |'
        )
    return '\n'.join(out)


def plot(rows, sessions, path) -> None:
    """Error against the sun's azimuth relative to the front, by sun altitude, before/after."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    by = {s['session']: s for s in sessions}
    for r in sorted(rows, key=lambda r: r['sun_alt']):
        s = by[r['session']]
        rel = (s['az'] - s['ref']) % 360.0  # sun azimuth relative to the front, clockwise
        for ax, key in zip(axes, ('before', 'after')):
            e = r[key]['err']
            # the reference's own per-turn offset (+-5 deg) is not the mount's: centre each turn
            for t in np.unique(s['turn']):
                sel = (s['turn'] == t) & np.isfinite(e)
                e[sel] -= np.median(e[sel]) if sel.any() else 0.0
            ax.plot(rel, e, '.', ms=2, label=f'sun {r["sun_alt"]:.0f} deg ({r["session"][:5]})')
    titles = ('level mount (before)', 'mount from the other clear session(s) (after)')
    for ax, key in zip(axes, titles):
        ax.set_title(key)
        ax.set_xlabel('sun azimuth relative to the front, deg (clockwise)')
        ax.set_xlim(0, 360)
        ax.set_ylim(-30, 30)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel('heading error minus its turn median, deg')
    axes[0].legend(markerscale=6, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--plot', help='write the figure here (PNG)')
    args = ap.parse_args()
    if not pj.available():
        print(pj.skip_reason(), file=sys.stderr)
        return 1
    g = geometry_from_dict(pj.geometry_dict())
    sessions = [load(row, g) for row in pj.sessions()]
    rows = leave_one_out(sessions, g)
    clear = [s for s in sessions if not s['session'].startswith('16-33')]
    other_clear = [[o for o in clear if o is not s] if s in clear else [] for s in sessions]
    rows += leave_one_out(sessions, g, other_clear)
    print(table(rows))
    for r in rows:
        if r['refused'] or r['warning']:
            print(f'{r["session"]} from {r["from"]}: {r["refused"] or r["warning"]}')
    if args.plot:
        plot([rows[0], rows[3], rows[4]], sessions, args.plot)  # mounts from clear skies only
    return 0


if __name__ == '__main__':
    sys.exit(main())
