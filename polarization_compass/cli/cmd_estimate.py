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
`polarization-compass estimate`: heading estimates from a frame or a real image.

`polarization-compass estimate`: heading estimates from a frame file or a real camera image, as
JSON.

Real images (:mod:`polarization_compass.real_input`: a raw mosaic PNG/TIFF/.npy, Stokes planes .npz
or 3-page TIFF) need ``--camera CAMERA.yaml`` (ROS camera_calibration plus ``polarizer:``) and the
sun (``--lat --lon --time`` or ``--sun-azimuth --sun-altitude``); ``--mask`` excludes obstructions.
Every usable result is then checked against the whole sky
(:func:`polarization_compass.skyfit.assess_result`: misfit sigma, 180 deg side, ``poor_fit``) and,
with several methods, against each other (``inconsistent``).

Reads a ``render`` output (.npz). When it holds the raw mosaic, the mosaic is demosaiced (the
scene's demosaic method and polarizer layout from the frame's meta, else superpixel and the
IMX250MZR layout, and the output says which) and each method reads only the pixels it needs;
otherwise the stored AoP/DoP are used. The sun comes from the frame's meta; without it, from
--lat/--lon/--time.
"""

from __future__ import annotations

import json
import math
import sys
import time

from ._checks import check_range, check_together
from ..headings import (  # noqa: F401  (moved to the core)
    _make_estimators,
    _methods,
    _sensor_meta,
    real_observation,
    REAL_SKY_OUTLIER_DEG,
)
from ..errors import CompassError


def register(sub):
    from ..estimators import registry

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
        '--sun-azimuth',
        type=float,
        help='given sun azimuth, deg clockwise from North (instead of --lat/--lon/--time)',
    )
    p.add_argument('--sun-altitude', type=float, help='given sun altitude, deg')
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
    p.add_argument(
        '--use-stored',
        action='store_true',
        help='use the stored AoP/DoP even when the frame holds a mosaic',
    )
    p.add_argument('--lat', type=float, help='site latitude, deg (only when the frame has no sun)')
    p.add_argument('--lon', type=float, help='site longitude, deg')
    p.add_argument('--time', help='UTC time, ISO 8601 (only when the frame has no sun)')
    p.add_argument('--indent', type=int, default=None, help='pretty-print the JSON')
    p.set_defaults(func=run)


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


def _sun(meta: dict, args):
    if args.sun_azimuth is not None or args.sun_altitude is not None:
        check_together('sun-azimuth', args.sun_azimuth, 'sun-altitude', args.sun_altitude)
        check_range('sun-azimuth', args.sun_azimuth, -360, 360)
        check_range('sun-altitude', args.sun_altitude, -90, 90)
        return (
            float(args.sun_azimuth),
            float(args.sun_altitude),
            'given (--sun-azimuth/--sun-altitude)',
        )
    az, alt = meta.get('sun_azimuth_deg'), meta.get('sun_altitude_deg')
    ok = all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        for v in (az, alt)
    )
    if ok:
        return float(az), float(alt), 'frame meta'
    if args.lat is None or args.lon is None or args.time is None:
        raise CompassError(
            'the input does not say where the sun was: give --lat, --lon and --time, or '
            '--sun-azimuth and --sun-altitude'
        )
    from ..solar import sun_position

    pos = sun_position(args.time, args.lat, args.lon, 0.0)
    return (
        float(pos.azimuth_deg),
        float(pos.altitude_deg),
        'ephemeris (SPA) for --lat/--lon/--time',
    )


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
    from ..conventions import fold_axial_deg, wrap_180_deg
    from ..estimators import Observation
    from ..frame_io import load_frame_npz

    check_range('pitch', args.pitch, -89.999, 89.999)
    check_range('roll', args.roll, -180, 180)
    check_range('prior-bearing', args.prior_bearing, -360, 720)
    check_range('lat', args.lat, -90, 90)
    check_range('lon', args.lon, -180, 180)
    check_together('pitch', args.pitch, 'roll', args.roll)
    if args.stride is not None and not (1 <= args.stride <= 1024):
        raise CompassError(f'--stride must be in [1, 1024], got {args.stride}')
    _ifov_k(args)
    methods = _methods(args.method)
    knobs = parse_knobs(args.knob)
    from ..real_input import load_polarization_input

    inp = load_polarization_input(args.frame, args.bits)
    if inp.kind != 'frame':
        return _run_real(args, inp, methods, knobs)
    if args.mask or args.camera:
        raise CompassError(
            '--camera and --mask apply to real images; a frame file carries its camera'
        )
    frame = load_frame_npz(args.frame)
    camera = frame.camera
    sun_az, sun_alt, sun_src = _sun(frame.meta, args)
    estimators = _make_estimators(methods, knobs, args.stride)

    source = {'sun': sun_src}
    use_mosaic = frame.mosaic is not None and not args.use_stored
    stored_obs = None
    if use_mosaic:
        sensor, mos, method, bits, full_well = _sensor_meta(frame.meta)
        layout = mos.get('layout')
        pol45 = mos.get('pol45_toward')
        assumed = []
        if layout is None:
            from ..demosaic import IMX250MZR_LAYOUT

            layout = [list(r) for r in IMX250MZR_LAYOUT]
            assumed.append('layout')
        if pol45 is None:
            from ..demosaic import IMX250MZR_POL45

            pol45 = IMX250MZR_POL45
            assumed.append('pol45_toward')
        shp, mshp = frame.aop_rad.shape, frame.mosaic.shape
        if method is None:
            method = 'bilinear' if mshp == shp else 'superpixel'
            assumed.append('demosaic')
        if method == 'bilinear' and mshp == shp:
            origin = (frame.x_px.flat[0], frame.y_px.flat[0])
        elif method == 'superpixel' and len(shp) == 2 and mshp == (2 * shp[0], 2 * shp[1]):
            origin = (frame.x_px.flat[0] - 0.5, frame.y_px.flat[0] - 0.5)
        else:
            raise CompassError(
                f"the frame's mosaic {mshp} does not match its {shp} AoP image for a {method} "
                'demosaic; use --use-stored'
            )
        sat = float((1 << bits) - 1) if bits else full_well
        source['input'] = {
            'mosaic': list(mshp),
            'demosaic': method,
            'layout': layout,
            'pol45_toward': pol45,
            'assumed': assumed,
            'saturation_level': sat,
        }
        origin = (int(round(origin[0])), int(round(origin[1])))
    else:
        source['input'] = 'stored AoP/DoP' + (
            ' (--use-stored)' if frame.mosaic is not None else ''
        )

    out = []
    for name, est, kn in estimators:
        t0 = time.perf_counter()
        if use_mosaic:
            from ..estimators.mosaic_input import observation_from_mosaic

            obs = observation_from_mosaic(
                frame.mosaic,
                camera,
                sun_az,
                sun_alt,
                origin_px=origin,
                method=method,
                layout=layout,
                pol45_toward=pol45,
                saturation_level=sat,
                selection=est.pixels_needed(camera),
                with_intensity=frame.intensity is not None,
                pitch_deg=args.pitch,
                roll_deg=args.roll,
                prior_bearing_deg=args.prior_bearing,
                ifov_k=_ifov_k(args),
            )
        else:
            if stored_obs is None:
                stored_obs = Observation(
                    frame.aop_rad,
                    frame.dop,
                    frame.valid,
                    frame.rays_cam(),
                    frame.x_px,
                    frame.y_px,
                    camera,
                    sun_az,
                    sun_alt,
                    frame.intensity,
                    args.pitch,
                    args.roll,
                    args.prior_bearing,
                )
            obs = stored_obs
        res = est.estimate(obs)
        dt = (time.perf_counter() - t0) * 1e3
        d = res.to_json_dict()
        d['time_ms'] = round(dt, 3)
        d['knobs'] = kn
        truth = frame.meta.get('psi_deg')
        if res.psi_deg is not None and isinstance(truth, (int, float)) and math.isfinite(truth):
            err = res.psi_deg - float(truth)
            d['truth_psi_deg'] = float(truth)
            d['error_deg'] = float(fold_axial_deg(err) if res.axial else wrap_180_deg(err))
        d['source'] = source
        out.append(d)
    json.dump(out, sys.stdout, indent=args.indent, default=_jsonable)
    sys.stdout.write('\n')
    return 0


def _run_real(args, inp, methods, knobs) -> int:
    from ..camera import load_camera_yaml
    from ..real_input import load_mask
    from ..skyfit import assess_result, mark_inconsistent, sample_sky

    if not args.camera:
        raise CompassError(
            f'{args.frame}: a real image needs --camera CAMERA.yaml (ROS camera_calibration '
            'format)'
        )
    if args.use_stored:
        raise CompassError('--use-stored applies to frame files')
    cam_file = load_camera_yaml(args.camera)
    sun_az, sun_alt, sun_src = _sun({}, args)
    # real skies: least_squares/tilt_aware refit robustly (consensus, outliers beyond 15 deg
    # dropped) unless the user set outlier_deg
    estimators = _make_estimators(
        methods,
        knobs,
        args.stride,
        {'outlier_deg': REAL_SKY_OUTLIER_DEG, 'max_aop_noise_deg': 90.0},
    )
    shape = inp.stokes[0].shape if inp.kind == 'stokes' else inp.mosaic.shape
    mask = load_mask(args.mask, shape, cam_file.camera.shape) if args.mask else None
    obs, _ = real_observation(
        inp,
        cam_file,
        sun_az,
        sun_alt,
        mask,
        args.demosaic,
        args.pitch,
        args.roll,
        args.prior_bearing,
        _ifov_k(args),
    )
    sample = (
        None
        if args.no_sky_check
        else sample_sky(obs.aop_rad, obs.dop, obs.valid, obs.rays_cam, obs.intensity)
    )
    source = {
        'sun': sun_src,
        'input': {
            'kind': inp.kind,
            'path': inp.path,
            'layout': [list(r) for r in cam_file.layout],
            'pol45_toward': cam_file.pol45_toward,
            'assumed': [] if cam_file.layout_given else ['layout', 'pol45_toward'],
            'usable_pixels': int(obs.valid.sum()),
        },
    }
    results, times = [], []
    for name, est, kn in estimators:
        t0 = time.perf_counter()
        res = est.estimate(obs)
        if not args.no_sky_check:
            res = assess_result(res, sample, sun_alt, args.pitch, args.roll, args.prior_bearing)
        times.append((time.perf_counter() - t0) * 1e3)
        results.append((res, kn))
    final = [r for r, _ in results]
    if not args.no_sky_check and len(final) > 1:
        final = mark_inconsistent(final)
    out = []
    for res, (_, kn), dt in zip(final, results, times):
        d = res.to_json_dict()
        d['time_ms'] = round(dt, 3)
        d['knobs'] = kn
        d['source'] = source
        out.append(d)
    json.dump(out, sys.stdout, indent=args.indent, default=_jsonable)
    sys.stdout.write('\n')
    return 0


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
