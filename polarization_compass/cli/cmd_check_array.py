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
`polarization-compass check-array`: a photodiode array's polarizer angle convention and wiring.

Both are read from the data: the ephemeris' sun is the only reference needed.
"""

from __future__ import annotations

import sys

from ._checks import check_range, check_together


def register(sub):
    p = sub.add_parser(
        'check-array',
        help="detect a photodiode array's angle_zero / angle_sense from a recording",
        description='Scores the four polarizer conventions (angle_zero meridian|horizontal x '
        "angle_sense cw|ccw) by how well each makes the units' E-vectors agree with one "
        "sun at the ephemeris' elevation (no reference heading needed); best first. Then the "
        'wiring mistakes (azimuths counted the other way, units one position out of order). '
        "Exit 0 when the geometry's convention is the clear winner and no mistake fits the "
        'readings clearly better, 1 otherwise.',
    )
    p.add_argument('recording', metavar='RECORDING', help='.npz or .csv recording')
    p.add_argument('--geometry', required=True, help='sensor description YAML')
    p.add_argument('--lat', type=float, required=True, help='site latitude, deg')
    p.add_argument('--lon', type=float, required=True, help='site longitude, deg')
    p.add_argument('--time', required=True, help='UTC time of t_offset_s = 0, ISO 8601')
    p.add_argument(
        '--pitch', type=float, default=None, help='pitch, deg (default 0: level ground)'
    )
    p.add_argument('--roll', type=float, default=None, help='roll, deg (default 0)')
    p.set_defaults(func=run)


def run(args) -> int:
    from .cmd_estimate_array import sun_per_sample
    from ..photodiode.geometry import load_array_geometry
    from ..photodiode.readings import load_array_recording
    from ..photodiode.selfcheck import check_convention, contradicting_hypothesis

    check_range('lat', args.lat, -90, 90)
    check_range('lon', args.lon, -180, 180)
    check_range('pitch', args.pitch, -89.999, 89.999)
    check_range('roll', args.roll, -180, 180)
    check_together('pitch', args.pitch, 'roll', args.roll)
    g = load_array_geometry(args.geometry)
    rec = load_array_recording(args.recording)
    rec.check_against(g)
    az, alt = sun_per_sample(args.time, rec.t_offset_s, rec.n_samples, args.lat, args.lon)
    pitch = 0.0 if args.pitch is None else args.pitch
    roll = 0.0 if args.roll is None else args.roll
    scores, verdict = check_convention(rec.intensities, g, az, alt, pitch, roll)
    print(
        f'{"angle_zero":<11} {"angle_sense":<11} {"misfit_deg":>10} {"sun_el_diff_deg":>15} '
        f'{"fitted":>7}'
    )
    for s in scores:
        m = '-' if s.misfit_median_deg is None else f'{s.misfit_median_deg:.1f}'
        e = (
            '-'
            if s.sun_elevation_diff_median_deg is None
            else f'{s.sun_elevation_diff_median_deg:.1f}'
        )
        print(f'{s.angle_zero:<11} {s.angle_sense:<11} {m:>10} {e:>15} {s.fitted_fraction:>7.2f}')
    print(verdict)
    best = scores[0]
    ok = verdict.startswith('clear') and (best.angle_zero, best.angle_sense) == (
        g.angle_zero,
        g.angle_sense,
    )
    if not ok:
        print(
            f'the geometry says angle_zero {g.angle_zero}, angle_sense {g.angle_sense}',
            file=sys.stderr,
        )
    bad = contradicting_hypothesis(rec.intensities, g, az, alt, pitch, roll, max_samples=400)
    if bad is None:
        print('wiring: no common mistake fits the readings clearly better than the geometry')
    else:
        print(
            f'WIRING: the readings fit "{bad[0]}" better than the geometry (median misfit '
            f'{bad[1]:.1f} vs {bad[2]:.1f} deg)'
        )
    return 0 if ok and bad is None else 1
