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
`polarization-compass estimate`: headings from a frame file or a real camera image, as JSON.

The command parses its options and prints; the road from the input to the headings is
:func:`polarization_compass.headings.estimate_file`.

Real images (:mod:`polarization_compass.real_input`: a raw mosaic PNG/TIFF/.npy, Stokes planes .npz
or 3-page TIFF) need ``--camera CAMERA.yaml`` (ROS camera_calibration plus ``polarizer:``) and the
sun (``--lat --lon --time`` or ``--sun-azimuth --sun-altitude``); ``--mask`` excludes obstructions.
Every usable result is then checked against the whole sky
(:func:`polarization_compass.skyfit_assess.assess_result`: misfit sigma, 180 deg side,
``poor_fit``) and, with several methods, against each other (``inconsistent``).

Reads a ``render`` output (.npz). When it holds the raw mosaic, the mosaic is demosaiced (the
scene's demosaic method and polarizer layout from the frame's meta, else superpixel and the
IMX250MZR layout, and the output says which) and each method reads only the pixels it needs;
otherwise the stored AoP/DoP are used. The sun comes from the frame's meta; without it, from
--lat/--lon/--time.
"""

from __future__ import annotations

import json
import sys

from ._checks import check_range, check_together
from ..errors import CompassError


def register(sub):
    p = sub.add_parser(
        'estimate',
        help='heading from a frame file (JSON, one object per method)',
        description="Estimate the heading from a frame written by 'render' or from a real camera "
        "image (with --camera; docs/real-cameras.md). psi is the paper's yaw "
        "(bearing of camera +y minus the sun's azimuth), bearing the true bearing of "
        'camera +y, yaw_enu the REP-103 yaw (90 - bearing). On real images each result '
        'is checked against the whole sky: status poor_fit / inconsistent when it '
        'does not hold.',
    )
    _add_input_options(p)
    _add_sun_options(p)
    _add_method_options(p)
    p.add_argument('--indent', type=int, default=None, help='pretty-print the JSON')
    p.add_argument(
        '--plot',
        metavar='OUT.png',
        help='also write the diagnostic figure: AoP, DoP, pixels used and masked by reason, '
        'residual against the fitted sky, fitted sun and solar meridian, each heading with its '
        'sigma (README "What the compass sees")',
    )
    p.set_defaults(func=run)


def _add_input_options(p) -> None:
    """Add the input and how to read it: frame file or real image, camera, mask, demosaic."""
    p.add_argument(
        'frame',
        metavar='INPUT',
        help="frame file written by 'polarization-compass render', or a "
        'real image: raw mosaic (.png/.tif 8/16-bit, .npy) or Stokes '
        'planes (.npz with s0, s1, s2, or a 3-page .tif)',
    )
    p.add_argument(
        '--camera',
        metavar='CAMERA.yaml',
        help="ROS camera_calibration file plus 'polarizer: {layout, "
        "pol45_toward}' (needed for real images)",
    )
    p.add_argument(
        '--bits', type=int, help='significant bits of a raw mosaic in a 16-bit container (10, 12)'
    )
    p.add_argument(
        '--mask',
        metavar='MASK.png',
        help="static mask of the input's size: non-zero = sky, zero = obstruction",
    )
    p.add_argument(
        '--demosaic',
        choices=('superpixel', 'bilinear'),
        default='superpixel',
        help='demosaic of a raw mosaic input (default superpixel)',
    )
    p.add_argument(
        '--ifov-k',
        type=float,
        default=None,
        metavar='K',
        help='IFOV check of a raw mosaic: a pixel whose (I0+I90)-(I45+I135) exceeds K noise '
        'sigmas is not used (default 4; 0 = off; docs/real-cameras.md)',
    )
    p.add_argument(
        '--use-stored',
        action='store_true',
        help='use the stored AoP/DoP even when the frame holds a mosaic',
    )


def _add_sun_options(p) -> None:
    """Add where the sun was: given, or the site and time for the ephemeris."""
    p.add_argument(
        '--sun-azimuth',
        type=float,
        help='given sun azimuth, deg clockwise from North (instead of --lat/--lon/--time)',
    )
    p.add_argument('--sun-altitude', type=float, help='given sun altitude, deg')
    p.add_argument('--lat', type=float, help='site latitude, deg (only when the frame has no sun)')
    p.add_argument('--lon', type=float, help='site longitude, deg')
    p.add_argument('--time', help='UTC time, ISO 8601 (only when the frame has no sun)')


def _add_method_options(p) -> None:
    """Add the methods, their knobs, the known tilt and prior, and the whole-sky check."""
    from ..estimators import registry

    p.add_argument(
        '--no-sky-check',
        action='store_true',
        help='skip the whole-sky check (misfit sigma, 180 deg side, poor_fit, inconsistent)',
    )
    p.add_argument(
        '--method',
        default='all',
        help=' | '.join(registry.names()) + ' | all (default), or a comma-separated list',
    )
    p.add_argument(
        '--pitch',
        type=float,
        help=f'known camera pitch, deg ({", ".join(registry.tilt_methods())} '
        'needs it; also used to resolve the least-squares sign)',
    )
    p.add_argument('--roll', type=float, help='known camera roll, deg')
    p.add_argument(
        '--stride', type=int, help="use every N-th sensor pixel (overrides each method's default)"
    )
    p.add_argument(
        '--prior-bearing',
        type=float,
        help='prior true bearing of camera +y, deg: resolves the '
        '180 deg ambiguity when nothing else does',
    )
    p.add_argument(
        '--knob',
        action='append',
        default=[],
        metavar='NAME=VALUE',
        help='estimator knob, e.g. --knob min_dop=0.1 (repeatable; applied to every method that '
        'has it)',
    )


def parse_knobs(items) -> dict:
    """
    Read ``--knob NAME=VALUE`` options (values as YAML scalars) into a dict.

    Shared by ``estimate`` and ``estimate-array``; the estimator validates names and ranges.

    Parameters
    ----------
    items : list of str
        The option values as given.

    Returns
    -------
    dict
        Knob name to value.

    Raises
    ------
    CompassError
        An item without ``=`` or a value YAML cannot read.

    """
    import yaml

    out = {}
    for it in items:
        if '=' not in it:
            raise CompassError(f'--knob must be NAME=VALUE, got {it!r}')
        k, v = it.split('=', 1)
        try:
            out[k.strip()] = yaml.safe_load(v)
        except yaml.YAMLError:
            raise CompassError(f'--knob {k}: cannot read value {v!r}') from None
    return out


def _ifov_k(args):
    """``--ifov-k`` validated (default ``demosaic.IFOV_K_DEFAULT``); CompassError if bad."""
    from ..demosaic import check_ifov_k, IFOV_K_DEFAULT

    k = getattr(args, 'ifov_k', None)
    if k is None:
        return IFOV_K_DEFAULT
    try:
        return check_ifov_k(k)
    except CompassError as exc:
        raise CompassError(f'--ifov-k: {exc}') from None


def run(args) -> int:
    from ..headings import estimate_file, EstimateOptions
    from ..pipeline.methods import method_list

    _check_ranges(args)
    options = EstimateOptions(
        methods=method_list(args.method),
        knobs=parse_knobs(args.knob),
        stride=args.stride,
        camera_yaml=args.camera,
        mask_path=args.mask,
        bits=args.bits,
        demosaic=args.demosaic,
        ifov_k=_ifov_k(args),
        sun_azimuth_deg=args.sun_azimuth,
        sun_altitude_deg=args.sun_altitude,
        lat_deg=args.lat,
        lon_deg=args.lon,
        time_utc=args.time,
        pitch_deg=args.pitch,
        roll_deg=args.roll,
        prior_bearing_deg=args.prior_bearing,
        sky_check=not args.no_sky_check,
        use_stored=args.use_stored,
    )
    seen = {} if args.plot else None
    out = estimate_file(args.frame, options, seen)
    if args.plot:
        write_plot(seen, args.plot, args.frame, options)
    json.dump(out, sys.stdout, indent=args.indent, default=_jsonable)
    sys.stdout.write('\n')
    return 0


def write_plot(seen: dict, out_path, input_path, options) -> None:
    """
    Write the diagnostic figure of what ``estimate_file`` saw.

    Parameters
    ----------
    seen : dict
        Filled by :func:`polarization_compass.headings.estimate_file`.
    out_path : str
        The PNG to write.
    input_path : str
        The input (its name titles the figure).
    options : EstimateOptions
        The options it was read with (demosaic, IFOV check).

    Raises
    ------
    CompassError
        The figure cannot be written there.

    """
    from pathlib import Path

    from ..diagnostic_figure import save_figure
    from ..sky_view import view_from_seen

    view = view_from_seen(seen, options.demosaic, options.ifov_k, label=Path(input_path).name)
    try:
        save_figure(view, out_path)
    except OSError as exc:
        raise CompassError(f'--plot: cannot write {out_path}: {exc.strerror or exc}') from None


def _check_ranges(args) -> None:
    """Check the options that are not estimator knobs (those check themselves)."""
    check_range('pitch', args.pitch, -89.999, 89.999)
    check_range('roll', args.roll, -180, 180)
    check_range('prior-bearing', args.prior_bearing, -360, 720)
    check_range('lat', args.lat, -90, 90)
    check_range('lon', args.lon, -180, 180)
    check_together('pitch', args.pitch, 'roll', args.roll)
    if args.sun_azimuth is not None or args.sun_altitude is not None:
        check_together('sun-azimuth', args.sun_azimuth, 'sun-altitude', args.sun_altitude)
        check_range('sun-azimuth', args.sun_azimuth, -360, 360)
        check_range('sun-altitude', args.sun_altitude, -90, 90)


def _jsonable(v):
    try:
        import numpy as np

        if isinstance(v, np.generic):
            return v.item()
        if isinstance(v, np.ndarray):
            return v.tolist()
    except ImportError:  # pragma: no cover
        pass
    return str(v)
