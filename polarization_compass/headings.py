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
The one road from an image to headings: a frame file, Stokes planes or a raw mosaic in, results out.

Moved from ``cli/cmd_estimate.py`` so that the command line, the bench and the tests share it.
"""

from __future__ import annotations

import math

from .errors import CompassError


def _sensor_meta(meta: dict):
    """
    Read the sensor settings from a frame's meta, types checked.

    (sensor, mosaic, demosaic, quantization_bits, full_well_e) from a frame's meta, types checked:
    a frame file is user input, so a wrong type is a :class:`FrameFileError` (one line, exit 2),
    not a crash.
    """
    from .frame_io import FrameFileError

    def section(d, key):
        v = d.get(key)
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise FrameFileError(f'frame meta: {key} must be a mapping, got {type(v).__name__}')
        return v

    sensor = section(meta, 'sensor')
    mos = section(sensor, 'mosaic')
    method = sensor.get('demosaic')
    if method is not None and method not in ('superpixel', 'bilinear'):
        raise FrameFileError(
            f'frame meta: sensor.demosaic must be superpixel or bilinear, got {method!r}'
        )
    bits = sensor.get('quantization_bits')
    if bits is not None and (
        isinstance(bits, bool) or not isinstance(bits, int) or not 1 <= bits <= 32
    ):
        raise FrameFileError(
            f'frame meta: sensor.quantization_bits must be an integer in [1, 32], got {bits!r}'
        )
    full_well = section(sensor, 'exposure').get('full_well_e')
    if full_well is not None and (
        isinstance(full_well, bool)
        or not isinstance(full_well, (int, float))
        or not math.isfinite(full_well)
        or full_well <= 0
    ):
        raise FrameFileError(
            f'frame meta: sensor.exposure.full_well_e must be a positive number, got {full_well!r}'
        )
    return sensor, mos, method, bits, None if full_well is None else float(full_well)


def _methods(text: str) -> list[str]:
    from .estimators import estimator_names

    names = estimator_names()
    if text == 'all':
        return names
    wanted = [t.strip() for t in text.split(',') if t.strip()]
    bad = [w for w in wanted if w not in names]
    if bad or not wanted:
        raise CompassError(
            f'--method: unknown {", ".join(bad) or repr(text)}; known: {", ".join(names)} or all'
        )
    return wanted


#: real images: the robust refit's outlier threshold for the methods that have the knob
#: (``outlier_deg``)
REAL_SKY_OUTLIER_DEG = 15.0


def _make_estimators(methods, knobs, stride, defaults=None):
    from .estimators import make_estimator, registry

    estimators, used = [], set()
    for name in methods:
        specs = registry.get(name).knob_specs()
        kn = {k: v for k, v in knobs.items() if k in specs}
        if defaults and 'outlier_deg' in specs and 'outlier_deg' not in knobs:
            for k, v in defaults.items():
                if k in specs and k not in knobs:
                    kn[k] = v
        used.update(kn)
        if stride is not None and 'stride' in specs:
            kn['stride'] = stride
        estimators.append((name, make_estimator(name, **kn), kn))
    unused = sorted(set(knobs) - used)
    if unused:
        raise CompassError(f'--knob {", ".join(unused)}: no selected method has that knob')
    return estimators


def real_observation(
    inp,
    cam_file,
    sun_az,
    sun_alt,
    mask=None,
    demosaic='superpixel',
    pitch=None,
    roll=None,
    prior=None,
    ifov_k=None,
):
    """
    Build the observation of a whole real image and its data mask.

    Build (Observation of the whole image, data mask) from a real input: Stokes planes turned into
    camera-frame Stokes (S2 changes sign when the 45 deg polarizer points towards +x-y, see
    ``demosaic``), or a raw mosaic demosaiced with the camera file's layout. Invalid: outside the
    lens, saturated (+ glare), masked, and for a raw mosaic the IFOV check's rejections (``ifov_k``
    sigmas, default ``demosaic.IFOV_K_DEFAULT``; 0 = off).
    """
    import numpy as np

    from .camera import PixelSelection, select_pixels
    from .demosaic import aop_dop_from_stokes, IFOV_K_DEFAULT, stokes_from_mosaic
    from .estimators import Observation
    from .estimators.mosaic_input import _grid_rays
    from .skyfit import data_mask

    cam = cam_file.camera
    H, W = cam.shape
    sat = None
    if inp.kind == 'stokes':
        s0, s1, s2 = inp.stokes
        if cam_file.pol45_toward == '+x-y':
            s2 = -s2
        shp = s0.shape
    else:
        if inp.mosaic.shape != (H, W):
            raise CompassError(
                f'the mosaic is {inp.mosaic.shape[1]} x {inp.mosaic.shape[0]} but the camera file '
                'says '
                f'{W} x {H}'
            )
        s0, s1, s2 = stokes_from_mosaic(
            inp.mosaic,
            cam_file.layout,
            cam_file.pol45_toward,
            demosaic,
            inp.saturation_level,
            IFOV_K_DEFAULT if ifov_k is None else ifov_k,
        )
        shp = s0.shape
        from .polarizer_check import saturated_blocks

        sat = saturated_blocks(inp.mosaic, inp.saturation_level, shp)
    if shp == (H, W):
        sp = select_pixels(cam, PixelSelection.full())
        xg, yg, rays, has_ray = sp.x_px, sp.y_px, sp.rays_cam, sp.has_ray
    elif shp == (H // 2, W // 2):
        xg, yg, rays, has_ray = _grid_rays(cam, (1.5, 2.0, W // 2), (1.5, 2.0, H // 2))
    else:
        raise CompassError(
            f"the input planes are {shp[1]} x {shp[0]}; the camera file's {W} x {H} sensor needs "
            f'{W} x {H} or {W // 2} x {H // 2} (superpixel)'
        )
    aop, dop, valid = aop_dop_from_stokes(s0, s1, s2)
    if sat is None:
        keep = data_mask(s0, has_ray)
    else:  # saturated raw samples: grow those into the glare mask
        keep = data_mask(np.where(sat, np.float32(np.inf), s0), has_ray, float('inf'))
    if mask is not None:
        if mask.shape == shp:
            keep &= mask
        elif mask.shape == (H, W):
            keep &= mask[
                np.clip(np.rint(yg).astype(int) - 1, 0, H - 1),
                np.clip(np.rint(xg).astype(int) - 1, 0, W - 1),
            ]
        else:
            raise CompassError(
                f'--mask is {mask.shape[1]} x {mask.shape[0]}; the input is {shp[1]} x {shp[0]}'
            )
    valid = valid & keep
    obs = Observation(aop, dop, valid, rays, xg, yg, cam, sun_az, sun_alt, s0, pitch, roll, prior)
    return obs, keep
