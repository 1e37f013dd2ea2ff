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
Quality of the array headings on the real POL-OP sessions: wrong sides, outliers, coverage.

Reads ../shared/data/real-polop in place (GPL-3.0; see test/polop_json.py), runs what
``estimate-array --method tilt_aware --pitch 0 --roll 0 --geometry G`` runs on every sample of
every turn, and prints per session: the statuses, the RMS error of the ok results, how many ok
results are more than 90 deg (a wrong side) or 150 deg off, how many lie beyond 3 sigma, the
2-sigma coverage, what decided the side, and the units found unusable per reason.

Usage: python tools/polop_quality.py [--geometry config/arrays/pol_op_8unit.yaml] [--enable-all]
[--knob NAME=VALUE ...] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from polarization_compass.conventions import wrap_180_deg  # noqa: E402
from polarization_compass.photodiode.geometry import (  # noqa: E402
    geometry_from_dict,
    geometry_to_dict,
    load_array_geometry,
)
from polarization_compass.photodiode.heading import make_array_estimator  # noqa: E402
from polarization_compass.photodiode.selfcheck import estimate_recording_checked  # noqa: E402
from polarization_compass.solar import sun_position  # noqa: E402
import polop_json as pj  # noqa: E402


def sun_of(row, turn):
    t = np.datetime64(turn.time_utc.rstrip('Z'), 's') + np.timedelta64(int(turn.t_offset_s), 's')
    p = sun_position(t, float(row['lat']), float(row['lon']))
    return float(p.azimuth_deg), float(p.altitude_deg)


def session_quality(row, geometry, knobs) -> dict:
    est = make_array_estimator('tilt_aware', geometry, **knobs)
    status, err, sig, by, unusable = {}, [], [], {}, {}
    for turn in pj.load_session(row):
        az, alt = sun_of(row, turn)
        for r, ref in zip(
            estimate_recording_checked(est, turn.intensities, az, alt, 0.0, 0.0),
            turn.reference_bearing_deg,
        ):
            status[r.status.value] = status.get(r.status.value, 0) + 1
            for k, v in (r.extras.get('units_unusable') or {}).items():
                unusable[k] = unusable.get(k, 0) + int(v)
            if r.status.value == 'ok':
                err.append(float(wrap_180_deg(r.bearing_deg - ref)))
                sig.append(r.sigma_deg)
                b = str(r.extras.get('ambiguity_resolved_by'))
                by[b] = by.get(b, 0) + 1
    n = sum(status.values())
    e, s = np.abs(np.array(err)), np.array(sig)
    return {
        'samples': n,
        'status_pct': {k: round(100.0 * v / n, 1) for k, v in sorted(status.items())},
        'rms_deg': float(np.sqrt(np.mean(e**2))) if e.size else None,
        'ok_off_90': int(np.sum(e > 90)),
        'ok_off_150': int(np.sum(e > 150)),
        'ok_beyond_3sigma': int(np.sum(e > 3 * s)),
        'cov2': float(np.mean(e < 2 * s)) if e.size else None,
        'side_by': by,
        'units_unusable': unusable,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--geometry', default='config/arrays/pol_op_8unit.yaml')
    ap.add_argument('--enable-all', action='store_true', help='also use the disabled units')
    ap.add_argument('--knob', action='append', default=[], metavar='NAME=VALUE')
    ap.add_argument('--json', help='write the numbers as JSON')
    args = ap.parse_args()
    if not pj.available():
        print(pj.skip_reason(), file=sys.stderr)
        return 2
    g = load_array_geometry(args.geometry)
    if args.enable_all:
        d = geometry_to_dict(g)
        for u in d['units']:
            u.pop('enabled', None)
        g = geometry_from_dict(d)
    knobs = {}
    for kv in args.knob:
        k, v = kv.split('=', 1)
        knobs[k] = v if not v.replace('.', '', 1).lstrip('-').isdigit() else float(v)
    out = {}
    for row in pj.sessions():
        q = session_quality(row, g, knobs)
        out[row['session']] = q
        sp = q['status_pct']
        print(
            f'{row["session"]:<26} n {q["samples"]} ok {sp.get("ok", 0):.1f}% amb '
            f'{sp.get("ambiguous", 0):.1f}% poor {sp.get("poor_fit", 0):.1f}% '
            f'rms {q["rms_deg"] or float("nan"):.2f} >90 {q["ok_off_90"]} >150 '
            f'{q["ok_off_150"]} >3sig {q["ok_beyond_3sigma"]} cov2 {q["cov2"] or float("nan"):.3f}'
        )
        print(f'    statuses {sp}  side by {q["side_by"]}  unusable {q["units_unusable"]}')
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
