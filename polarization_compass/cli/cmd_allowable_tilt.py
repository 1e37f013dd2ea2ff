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
`polarization-compass allowable-tilt`: the tilt envelope from an error map.

The envelope keeps every method under an error bound; it is shown beside the paper's eq 33.
"""

from __future__ import annotations

import json
import math
import sys

from ..errors import CompassError


def register(sub):
    p = sub.add_parser(
        'allowable-tilt',
        help='largest pitch/roll envelope keeping the heading error under a bound',
        description='Reads an error map (polarization-compass errormap) and prints, per sun '
        'altitude, the '
        "largest tilt radius sqrt(pitch^2 + roll^2) such that every method's error at every yaw "
        "stays under --max-error, the pitch-only and roll-only limits, and eq 33's radius "
        'ME^2 / h (same unit for all angles; eq 33 is homogeneous, so degrees or radians give the '
        'same answer), and where they disagree.',
    )
    p.add_argument('--max-error', type=float, required=True, help='error bound ME, deg')
    p.add_argument(
        '--sun-altitude',
        type=float,
        help='one sun altitude, deg (default: every altitude of the map)',
    )
    p.add_argument('--map', required=True, help='error map .npz')
    p.add_argument(
        '--methods', help="comma-separated subset of the map's methods (default: all of them)"
    )
    p.add_argument('--json', action='store_true', help='print JSON instead of a table')
    p.set_defaults(func=run)


def run(args) -> int:
    from ..allowable import allowable_envelope, format_envelopes
    from ..errormap_io import load_error_map

    if not (math.isfinite(args.max_error) and args.max_error > 0):
        raise CompassError(
            f'--max-error must be a positive number of degrees, got {args.max_error}'
        )
    if args.sun_altitude is not None and not math.isfinite(args.sun_altitude):
        raise CompassError('--sun-altitude must be finite')
    m = load_error_map(args.map)
    methods = None
    if args.methods:
        methods = [x.strip() for x in args.methods.split(',') if x.strip()]
        for x in methods:
            m.method_index(x)
    alts = (
        [args.sun_altitude]
        if args.sun_altitude is not None
        else [float(a) for a in m.sun_altitude_deg]
    )
    envs = [allowable_envelope(m, args.max_error, a, methods) for a in alts]
    if args.json:
        json.dump([e.to_json_dict() for e in envs], sys.stdout)
        sys.stdout.write('\n')
    else:
        print(format_envelopes(envs))
    return 0
