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
`polarization-compass estimate-array`: headings from a photodiode-array recording.

One CSV row per sample.
"""

from __future__ import annotations

import csv
import math
import sys

from ._checks import check_range, check_together
from ._progress import advance_to, progress_bar


def register(sub):
    p = sub.add_parser(
        'estimate-array',
        help='heading of a photodiode-array compass per sample (CSV)',
        description="Heading of the body's front from a photodiode-array recording (.npz with "
        "'intensities' samples x units x channels and optional 't_offset_s', or CSV with "
        'u<unit>_c<channel> columns and optional t_offset_s). Rows: sample, t_offset_s, '
        'bearing_deg (body front, clockwise from true North), yaw_enu_deg (REP-103), '
        'sigma_deg, status, units_used, misfit_rms_deg, reason, side_by (what decided the '
        '180 deg side: sun_elevation, brightness, prior or empty), units_unusable (units whose '
        'readings were not measurements in that sample, per reason: saturated, zero_channel, '
        'dop_above_1, ...). When the readings fit a common wiring mistake (another polarizer '
        'convention, azimuths counted the other way, units one position out of order) clearly '
        'better than the geometry, no sample keeps a heading (poor_fit, the mistake named).',
    )
    p.add_argument('recording', metavar='RECORDING', help='.npz or .csv recording')
    p.add_argument('--geometry', required=True, help='sensor description YAML')
    p.add_argument('--lat', type=float, required=True, help='site latitude, deg')
    p.add_argument('--lon', type=float, required=True, help='site longitude, deg')
    p.add_argument('--time', required=True, help='UTC time of t_offset_s = 0, ISO 8601')
    p.add_argument(
        '--method', default='least_squares', help='least_squares (default) or tilt_aware'
    )
    p.add_argument(
        '--pitch', type=float, help="known pitch, deg (paper's alpha; tilt_aware needs it)"
    )
    p.add_argument('--roll', type=float, help="known roll, deg (paper's beta)")
    p.add_argument(
        '--prior-bearing', type=float, help='prior bearing of the front, deg (180 deg ambiguity)'
    )
    p.add_argument(
        '--knob',
        action='append',
        default=[],
        metavar='NAME=VALUE',
        help='array estimator knob (repeatable)',
    )
    p.add_argument('--out', required=True, help="output CSV ('-' for stdout)")
    p.set_defaults(func=run)


def sun_per_sample(time_iso: str, t_offset_s, n: int, lat: float, lon: float):
    """
    Return the sun azimuth/altitude (deg) per sample.

    Arrays (n,), for --time plus the recording's offsets.
    """
    import numpy as np

    from ..solar import sun_position, to_epoch_us

    us0 = int(to_epoch_us(time_iso)[0][0])
    offs = np.zeros(n) if t_offset_s is None else np.asarray(t_offset_s, dtype=float)
    times = (us0 + np.round(offs * 1e6).astype(np.int64)).astype('datetime64[us]')
    pos = sun_position(times, lat, lon, 0.0)
    return np.asarray(pos.azimuth_deg, dtype=float), np.asarray(pos.altitude_deg, dtype=float)


def _fmt(v, digits=4):
    return '' if v is None or not math.isfinite(v) else f'{v:.{digits}f}'


_COLUMNS = (
    'sample',
    't_offset_s',
    'bearing_deg',
    'yaw_enu_deg',
    'sigma_deg',
    'status',
    'units_used',
    'misfit_rms_deg',
    'reason',
    'side_by',
    'units_unusable',
)


def _row(i: int, t: float, r) -> list:
    heading = r.ok
    unusable = r.extras.get('units_unusable') or {}
    return [
        i,
        _fmt(t, 6),
        _fmt(r.bearing_deg) if heading else '',
        _fmt(r.yaw_enu_deg) if heading else '',
        _fmt(r.sigma_deg) if heading else '',
        r.status.value,
        r.pixels,
        _fmt(r.extras.get('misfit_rms_deg'), 3),
        r.reason,
        r.extras.get('ambiguity_resolved_by') or '',
        ';'.join(f'{k}={v}' for k, v in unusable.items()),
    ]


def _summary(results) -> str:
    counts, unusable = {}, {}
    for r in results:
        counts[r.status.value] = counts.get(r.status.value, 0) + 1
        for k, v in (r.extras.get('units_unusable') or {}).items():
            unusable[k] = unusable.get(k, 0) + int(v)
    line = f'{len(results)} sample(s): ' + ', '.join(f'{k} {v}' for k, v in sorted(counts.items()))
    if unusable:
        line += '; unit-samples not measuring: ' + ', '.join(
            f'{k} {v}' for k, v in sorted(unusable.items())
        )
    return line


def run(args) -> int:
    from .cmd_estimate import parse_knobs
    from ..photodiode.geometry import load_array_geometry
    from ..photodiode.heading import make_array_estimator
    from ..photodiode.readings import load_array_recording
    from ..photodiode.selfcheck import estimate_recording_checked

    check_range('lat', args.lat, -90, 90)
    check_range('lon', args.lon, -180, 180)
    check_range('pitch', args.pitch, -89.999, 89.999)
    check_range('roll', args.roll, -180, 180)
    check_range('prior-bearing', args.prior_bearing, -360, 720)
    check_together('pitch', args.pitch, 'roll', args.roll)
    geometry = load_array_geometry(args.geometry)
    est = make_array_estimator(args.method, geometry, **parse_knobs(args.knob))
    rec = load_array_recording(args.recording)
    rec.check_against(geometry)
    az, alt = sun_per_sample(args.time, rec.t_offset_s, rec.n_samples, args.lat, args.lon)
    with progress_bar('estimate-array', ' samples', rec.n_samples) as bar:
        results = estimate_recording_checked(
            est,
            rec.intensities,
            az,
            alt,
            args.pitch,
            args.roll,
            args.prior_bearing,
            progress=lambda k, n: advance_to(bar, k, n),
        )
    fh = sys.stdout if args.out == '-' else open(args.out, 'w', newline='', encoding='utf-8')
    try:
        w = csv.writer(fh)
        w.writerow(_COLUMNS)
        for i, r in enumerate(results):
            t = 0.0 if rec.t_offset_s is None else float(rec.t_offset_s[i])
            w.writerow(_row(i, t, r))
    finally:
        if fh is not sys.stdout:
            fh.close()
    print(_summary(results), file=sys.stderr)
    return 0
