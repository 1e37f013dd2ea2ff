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

"""`polarization-compass plot`: the paper's figures 7-14 from an error map, as PNG."""

from __future__ import annotations

import json
import math
import sys

from ..errors import CompassError


def register(sub):
    from ..figures import FIGURES

    p = sub.add_parser(
        'plot',
        help="draw the paper's figures 7-14 from an error map",
        description="fig7: pitch-only error surfaces per method; fig8/fig9: the methods' curves "
        'on one plot '
        '(all sun altitudes / one, enlarged, with their differences); fig10/fig11: roll-only '
        'surfaces (yaw over [-180, 180] / [-90, 270]); fig12/fig13: roll-only curves, fig13 with '
        'the '
        'pitch-only curve shifted by 90 deg; fig14: one method under pitch and roll. '
        '--figure all writes every figure into the directory --out.',
    )
    p.add_argument('map', help='error map .npz (polarization-compass errormap)')
    p.add_argument(
        '--figure',
        required=True,
        choices=list(FIGURES) + ['all'],
        metavar='NAME',
        help=f'{", ".join(FIGURES)} or all',
    )
    p.add_argument('--out', required=True, help='output .png (a directory with --figure all)')
    p.add_argument(
        '--sun-altitude', type=float, help='sun altitude node, deg (default: highest <= 50)'
    )
    p.add_argument('--pitch', type=float, help='pitch node for fig8/fig9, deg (default -20)')
    p.add_argument('--roll', type=float, help='roll node for fig12/fig13, deg (default -20)')
    p.add_argument(
        '--methods', help="comma-separated methods (default: the paper's four present in the map)"
    )
    p.add_argument('--method', help="fig14's method (default zenith)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..errormap_io import load_error_map
    from ..figures import save_all, save_figure

    for name in ('sun_altitude', 'pitch', 'roll'):
        v = getattr(args, name)
        if v is not None and not math.isfinite(v):
            raise CompassError(f'--{name.replace("_", "-")} must be finite')
    m = load_error_map(args.map)
    opts = {
        'sun_altitude': args.sun_altitude,
        'pitch': args.pitch,
        'roll': args.roll,
        'method': args.method,
        'methods': [x.strip() for x in args.methods.split(',') if x.strip()]
        if args.methods
        else None,
    }
    if args.figure == 'all':
        written = [str(p) for p in save_all(m, args.out, **opts)]
    else:
        if not str(args.out).lower().endswith('.png'):
            raise CompassError(f'--out must name a .png file, got {args.out!r}')
        written = [str(save_figure(m, args.figure, args.out, **opts))]
    json.dump({'written': written}, sys.stdout)
    sys.stdout.write('\n')
    return 0
