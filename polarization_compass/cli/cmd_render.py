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

"""`polarization-compass render`: one frame of a scene to an .npz file (and optional PNGs)."""

from __future__ import annotations

import json
import sys

from ._checks import check_range, check_together
from ..camera_pixels import PixelSelection
from ..conventions import CameraAttitude
from ..errors import CompassError


def register(sub):
    p = sub.add_parser(
        'render',
        help='render one polarization frame of a scene to .npz',
        description='Render AoP (eq 28 convention), DoP and the validity mask of a scene. '
        "--yaw is the camera's true bearing (eq 21): with --sun-azimuth 0 it "
        "equals the paper's psi.",
    )
    p.add_argument('--scene', help="scene YAML (default: the paper's Nanjing set-up)")
    p.add_argument('--time', help="UTC time, ISO 8601 (default: the scene's)")
    p.add_argument(
        '--yaw', type=float, help='true bearing of the camera +y axis, deg clockwise from North'
    )
    p.add_argument('--pitch', type=float, help='pitch (rotation about camera x), deg')
    p.add_argument('--roll', type=float, help='roll (rotation about camera y), deg')
    p.add_argument(
        '--sun-altitude',
        type=float,
        help='fix the sun instead of computing it from time and place: altitude, deg (needs '
        '--sun-azimuth; --time is then not used and meta records no time)',
    )
    p.add_argument(
        '--sun-azimuth', type=float, help='fix the sun: azimuth clockwise from North, deg'
    )
    p.add_argument(
        '--stride',
        type=int,
        metavar='N',
        help='render every N-th row and column only (centred on the image); scenes without sensor '
        'effects only: a polarization mosaic needs contiguous pixels, so a scene that declares '
        'sensor effects refuses N > 1 (exit status 2)',
    )
    p.add_argument('--seed', type=int, help='noise seed (scenes with sensor effects)')
    p.add_argument('--out', required=True, help='output .npz')
    p.add_argument('--png', metavar='DIR', help='also write viewable AoP/DoP PNGs into DIR')
    p.set_defaults(func=run)


def run(args) -> int:
    from ..frame_io import save_frame_npz
    from ..render import Renderer, SunDirection
    from ..scene import parse_time_utc
    from ..scene_load import load_scene

    check_range('yaw', args.yaw, -360, 720)
    check_range('pitch', args.pitch, -90, 90)
    check_range('roll', args.roll, -180, 180)
    check_range('sun-altitude', args.sun_altitude, -90, 90)
    check_range('sun-azimuth', args.sun_azimuth, -360, 720)
    check_together('sun-altitude', args.sun_altitude, 'sun-azimuth', args.sun_azimuth)
    if args.stride is not None and args.stride < 1:
        raise CompassError(f'--stride must be >= 1, got {args.stride}')
    if args.seed is not None and not (0 <= args.seed < 2**63):
        raise CompassError(f'--seed must be in [0, 2^63), got {args.seed}')
    scene = load_scene(args.scene)
    if args.stride is not None and args.stride > 1 and scene.effects:
        raise CompassError(
            f'--stride {args.stride} needs a scene without sensor effects: scene {scene.name!r} '
            f'declares {", ".join(scene.effects)}, and a polarization mosaic and its demosaic '
            'need '
            'contiguous pixels; render the full frame (drop --stride) or use an ideal-sensor scene'
        )
    if args.time:
        scene = scene.replace(time_utc=parse_time_utc(args.time))
    a = scene.attitude
    att = CameraAttitude(
        a.bearing_deg if args.yaw is None else args.yaw,
        a.pitch_deg if args.pitch is None else args.pitch,
        a.roll_deg if args.roll is None else args.roll,
    )
    pixels = PixelSelection.strided(args.stride) if args.stride and args.stride > 1 else None
    renderer = Renderer(scene, pixels=pixels)
    sun = (
        SunDirection(args.sun_azimuth, args.sun_altitude)
        if args.sun_altitude is not None
        else None
    )
    frame = renderer.render(attitude=att, sun=sun, seed=args.seed)
    path = save_frame_npz(args.out, frame)
    written = [str(path)]
    if args.png:
        from ..plotting import save_frame_pngs

        written += [str(p) for p in save_frame_pngs(frame, args.png)]
    summary = {
        'out': written,
        'shape': list(frame.aop_rad.shape),
        'valid_fraction': float(frame.valid.mean()),
        'sun_azimuth_deg': frame.sun.azimuth_deg,
        'sun_altitude_deg': frame.sun.altitude_deg,
        'sun_source': frame.meta['sun_source'],
        'time_utc': frame.meta['time_utc'],
        'psi_deg': frame.psi_deg,
        'effects': frame.meta['effects'],
        'sky': frame.meta['sky']['model'],
    }
    json.dump(summary, sys.stdout)
    sys.stdout.write('\n')
    return 0
