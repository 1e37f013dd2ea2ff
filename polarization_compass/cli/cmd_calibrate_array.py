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
`polarization-compass calibrate-array`: channel gains of a photodiode array.

The gains are relative, and come from full turns.
"""

from __future__ import annotations

import sys

import yaml


def register(sub):
    p = sub.add_parser(
        'calibrate-array',
        help='channel gains of a photodiode array from recordings of full turns',
        description="Estimate each unit's relative channel gains (mean 1) with a jackknife "
        'uncertainty from one or more recordings of full turns (no rig: the readings of an '
        'ideal polarizer set must be consistent with one Stokes vector) and write the '
        "geometry with 'gains' and 'gains_sigma'. Units with fewer than 4 channels or too "
        'little polarization variation keep their gains (reported); disabled units are left '
        'alone. Check the result with estimate-array before keeping it: on sensors whose angle '
        'errors are not gain errors the gains make the heading worse (docs/photodiode-arrays.md).',
    )
    p.add_argument(
        'recordings',
        metavar='RECORDING',
        nargs='+',
        help='.npz or .csv recordings (one turn each)',
    )
    p.add_argument('--geometry', required=True, help='sensor description YAML')
    p.add_argument('--out', required=True, help='calibrated sensor description YAML to write')
    p.add_argument(
        '--min-condition',
        type=float,
        default=3.0,
        help='singular-value ratio a unit needs to be calibrated (default 3)',
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from ._checks import check_range
    from ..photodiode.calibrate import calibrate_gains
    from ..photodiode.geometry import geometry_to_dict, load_array_geometry
    from ..photodiode.readings import load_array_recording

    check_range('min-condition', args.min_condition, 1.0, 1e6)
    g = load_array_geometry(args.geometry)
    recs = []
    for path in args.recordings:
        r = load_array_recording(path)
        r.check_against(g)
        recs.append(r.intensities)
    cal = calibrate_gains(recs, g, args.min_condition)
    sig = [
        s if s is not None else (list(u.gains_sigma) if u.gains_sigma is not None else None)
        for s, u in zip(cal.gains_sigma, g.units)
    ]
    out = g.with_gains(cal.gains, None)
    d = geometry_to_dict(out)
    for unit_d, s in zip(d['units'], sig):
        if s is not None:
            unit_d['gains_sigma'] = [float(v) for v in s]
    with open(args.out, 'w', encoding='utf-8') as fh:
        fh.write('# written by polarization-compass calibrate-array\n')
        yaml.safe_dump(d, fh, sort_keys=False)
    for note in cal.notes:
        print(note, file=sys.stderr)
    for i, (gains, s, c, note, change) in enumerate(
        zip(cal.gains, cal.gains_sigma, cal.condition, cal.note, cal.angle_change_deg)
    ):
        if not g.units[i].enabled:
            continue
        gs = ' '.join(f'{v:.4f}' for v in gains)
        ss = ' '.join(f'{v:.4f}' for v in s) if s is not None else '-'
        ch = f'  angle change {change:.2f} deg rms' if change is not None else ''
        print(
            f'unit {i}: gains {gs}  sigma {ss}  condition {c:.2f}{ch}'
            + (f'  ({note})' if note else ''),
            file=sys.stderr,
        )
    print(_ADVICE, file=sys.stderr)
    return 0


_ADVICE = (
    "use these gains only if the angle changes above are comparable to the units' angle "
    'residuals against the sky (estimate-array on a turn with a reference, before/after); where '
    'the residuals are much larger (the real 8-unit POL-OP sensor: 12-30 deg against 2-4 deg) '
    'the gains fit other defects and make the heading worse: keep the old geometry '
    '(docs/photodiode-arrays.md)'
)
