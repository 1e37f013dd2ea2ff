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
`polarization-compass check-polarizer`: the polarizer convention the sky supports.

`polarization-compass check-polarizer INPUT... --camera CAMERA.yaml`: which polarizer convention
the sky supports (:mod:`polarization_compass.polarizer_check`), as JSON. Exit 0 whatever the
verdict; the JSON's ``verdict`` is ``supported``, ``contradicted`` (with ``fix``) or
``cannot_tell``.
"""

from __future__ import annotations

import json
import sys

from ._checks import check_range, check_together


def register(sub):
    p = sub.add_parser(
        'check-polarizer',
        help='which polarizer layout / 45 deg direction the sky supports',
        description='Fit the single-scattering sky under each polarizer hypothesis (both 45 deg '
        'directions; the four 2x2 phases for a raw mosaic) and report which one the '
        'sky supports and by what margin, or that the frames cannot tell. Clear skies '
        'with the sun away from the zenith and the image axes decide best.',
    )
    p.add_argument(
        'inputs',
        nargs='+',
        metavar='INPUT',
        help='raw mosaic (.png/.tif/.npy) or Stokes planes '
        '(.npz s0/s1/s2, 3-page .tif), same camera',
    )
    p.add_argument(
        '--camera',
        required=True,
        metavar='CAMERA.yaml',
        help="ROS camera_calibration file with the configured 'polarizer:' (default: IMX250MZR)",
    )
    p.add_argument(
        '--bits', type=int, help='significant bits of a raw mosaic in a 16-bit container'
    )
    p.add_argument(
        '--mask', metavar='MASK.png', help="static mask (non-zero = sky) of the inputs' size"
    )
    p.add_argument('--sun-altitude', type=float, help='sun altitude, deg (else fitted per frame)')
    p.add_argument('--pitch', type=float, help='known camera pitch, deg (default level)')
    p.add_argument('--roll', type=float, help='known camera roll, deg')
    p.add_argument('--indent', type=int, default=None, help='pretty-print the JSON')
    p.add_argument(
        '--plot',
        metavar='OUT.png',
        help='also write every hypothesis side by side: the AoP under it minus its fitted sky '
        '(the right convention is the nearly white panel)',
    )
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from ..polarizer_files import check_polarizer_files

    check_range('sun-altitude', args.sun_altitude, -90, 90)
    check_range('pitch', args.pitch, -89.999, 89.999)
    check_range('roll', args.roll, -180, 180)
    check_together('pitch', args.pitch, 'roll', args.roll)
    rep = check_polarizer_files(
        args.inputs,
        args.camera,
        args.bits,
        args.mask,
        args.sun_altitude,
        args.pitch or 0.0,
        args.roll or 0.0,
    )
    if args.plot:
        from ..errors import CompassError
        from ..polarizer_figure import save_polarizer_figure

        try:
            save_polarizer_figure(
                rep,
                args.inputs,
                args.camera,
                args.plot,
                args.bits,
                args.mask,
                args.pitch or 0.0,
                args.roll or 0.0,
            )
        except OSError as exc:
            raise CompassError(
                f'--plot: cannot write {args.plot}: {exc.strerror or exc}'
            ) from None
    json.dump(
        rep,
        sys.stdout,
        indent=args.indent,
        default=lambda v: v.item() if isinstance(v, np.generic) else str(v),
    )
    sys.stdout.write('\n')
    return 0
