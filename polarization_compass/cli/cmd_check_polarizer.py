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
from ..errors import CompassError


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
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from ..camera import load_camera_yaml, PixelSelection, select_pixels
    from ..estimators.mosaic_input import _grid_rays
    from ..polarizer_check import check_polarizer
    from ..real_input import load_mask, load_polarization_input

    check_range('sun-altitude', args.sun_altitude, -90, 90)
    check_range('pitch', args.pitch, -89.999, 89.999)
    check_range('roll', args.roll, -180, 180)
    check_together('pitch', args.pitch, 'roll', args.roll)
    cf = load_camera_yaml(args.camera)
    cam = cf.camera
    H, W = cam.shape
    inputs, shapes = [], []
    for path in args.inputs:
        inp = load_polarization_input(path, args.bits)
        if inp.kind == 'frame':
            raise CompassError(
                f'{path}: check-polarizer reads raw mosaics or Stokes planes, not frame files'
            )
        if inp.kind == 'mosaic':
            if inp.mosaic.shape != (H, W):
                raise CompassError(
                    f'{path}: the mosaic is {inp.mosaic.shape[1]} x {inp.mosaic.shape[0]}, the '
                    'camera '
                    f'file says {W} x {H}'
                )
            inputs.append(('mosaic', inp.mosaic, inp.saturation_level))
            shapes.append(inp.mosaic.shape)
        else:
            shp = inp.stokes[0].shape
            if shp not in ((H, W), (H // 2, W // 2)):
                raise CompassError(
                    f'{path}: Stokes planes of {shp[1]} x {shp[0]} fit neither the {W} x {H} '
                    'sensor '
                    'nor its superpixels'
                )
            inputs.append(('stokes', inp.stokes, None))
            shapes.append(shp)
    if len({k for k, _, _ in inputs}) > 1:
        raise CompassError('check-polarizer: give either raw mosaics or Stokes planes, not both')

    def rays_for_shape(shape):
        if tuple(shape) == (H, W):
            sp = select_pixels(cam, PixelSelection.full())
            return sp.rays_cam, sp.has_ray
        if tuple(shape) == (H // 2, W // 2):
            _, _, rays, ok = _grid_rays(cam, (1.5, 2.0, W // 2), (1.5, 2.0, H // 2))
            return rays, ok
        raise CompassError(f'no rays for a {shape} grid')

    masks = None
    if args.mask:
        masks = []
        for shp, (kind, _, _) in zip(shapes, inputs):
            m = load_mask(args.mask, shp)
            if kind == 'mosaic':  # to the superpixel grid: a block is sky when all of it is
                m = (
                    m[: 2 * (H // 2), : 2 * (W // 2)]
                    .reshape(H // 2, 2, W // 2, 2)
                    .all(axis=(1, 3))
                )
            masks.append(m)
    rep = check_polarizer(
        inputs,
        cam,
        cf.layout,
        cf.pol45_toward,
        rays_for_shape,
        args.sun_altitude,
        args.pitch or 0.0,
        args.roll or 0.0,
        masks,
    )
    rep['camera_file'] = args.camera
    rep['configured_in_file'] = cf.layout_given
    json.dump(
        rep,
        sys.stdout,
        indent=args.indent,
        default=lambda v: v.item() if isinstance(v, np.generic) else str(v),
    )
    sys.stdout.write('\n')
    return 0
