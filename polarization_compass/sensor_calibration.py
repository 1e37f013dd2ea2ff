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
The fixed pattern of a division-of-focal-plane sensor's calibration errors.

Per-pixel polarizer angle error, extinction ratio spread and gain (photo-response non-uniformity),
drawn once per 64 x 64 tile of the sensor from ``calibration.seed`` (so a region sees the same
pixels' errors as a full frame); :func:`calibration_maps` gives the maps of a pixel block. The
model and its references are in :mod:`.sensor`'s docstring (``calibration``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .mosaic import MosaicLayout
from .sensor_config import SensorConfig

_CAL_TILE = 64


@lru_cache(maxsize=4)
def _calibration_pattern(
    seed: int,
    row0: int,
    col0: int,
    height: int,
    width: int,
    angle_sd_deg: float,
    er_spread: float,
    gain_rms: float,
):
    """
    Return the fixed calibration pattern of a sensor block.

    For the block (row0, col0, height, width): angle error (rad), ER factor and gain maps
    (float32/float64), or None for a component of zero spread. Drawn per 64 x
    64 tile of the sensor keyed by (seed, tile row, tile column), so a pixel's errors do not depend
    on the block that contains it. Cached per block.
    """
    shape = (height, width)
    ang = np.zeros(shape, np.float32) if angle_sd_deg > 0 else None
    erf = np.ones(shape) if er_spread > 0 else None
    g = np.ones(shape, np.float32) if gain_rms > 0 else None
    T = _CAL_TILE
    for tr in range(row0 // T, (row0 + height - 1) // T + 1):
        for tc in range(col0 // T, (col0 + width - 1) // T + 1):
            z = np.random.default_rng([int(seed), 0xCA1, tr, tc]).standard_normal((3, T, T))
            r0, r1 = max(row0, tr * T), min(row0 + height, (tr + 1) * T)
            c0, c1 = max(col0, tc * T), min(col0 + width, (tc + 1) * T)
            src = (slice(None), slice(r0 - tr * T, r1 - tr * T), slice(c0 - tc * T, c1 - tc * T))
            dst = (slice(r0 - row0, r1 - row0), slice(c0 - col0, c1 - col0))
            zz = z[src]
            if ang is not None:
                ang[dst] = np.radians(angle_sd_deg) * zz[0]
            if erf is not None:
                erf[dst] = np.exp(er_spread * zz[1])
            if g is not None:
                g[dst] = np.maximum(1.0 + gain_rms * zz[2], 0.0)
    for a in (ang, erf, g):
        if a is not None:
            a.setflags(write=False)
    return ang, erf, g


def calibration_maps(
    cfg: 'SensorConfig', layout: MosaicLayout, shape, row0: int = 0, col0: int = 0
):
    """
    Return per-pixel polarizer angle, efficiency and gain maps of a sensor block.

    float32 maps of the block of ``shape`` whose top-left pixel is (row0, col0) (0-based) of the
    full sensor, for ``cfg.calibration``; ``layout`` is the block's (already shifted) layout.

    Parameters
    ----------
    cfg : SensorConfig
        Parameters with a declared ``calibration`` (and the mean extinction ratio when its
        spread is not zero).
    layout : MosaicLayout
        Layout shifted to the block's top-left pixel (its nominal polarizer angles).
    shape : tuple of int
        (rows, cols) of the block.
    row0, col0 : int, default 0
        0-based row and column of the block's top-left pixel on the full sensor.

    Returns
    -------
    phi : numpy.ndarray
        float32 polarizer angle per pixel [rad, camera frame, from +x towards +y]: the nominal
        angle plus its error.
    d : numpy.ndarray
        float32 polarizer efficiency (ER - 1) / (ER + 1) per pixel.
    gain : numpy.ndarray
        float32 relative gain per pixel (1 + gain_rms z).

    References
    ----------
    .. [1] S. B. Powell and V. Gruev, "Calibration methods for division-of-focal-plane
       polarimeters", Opt. Express 21: 21039, 2013.

    """
    c = cfg.calibration
    H, W = shape
    ang, erf, g = _calibration_pattern(
        c['seed'],
        int(row0),
        int(col0),
        H,
        W,
        c['angle_error_deg'],
        c['extinction_ratio_spread'],
        c['gain_rms'],
    )
    nominal = np.radians(np.asarray(layout.camera_angles_deg, dtype=float)).reshape(2, 2)
    phi = np.tile(nominal, (H // 2 + 1, W // 2 + 1))[:H, :W].astype(np.float32)
    if ang is not None:
        phi = phi + ang
    if erf is not None:
        er = cfg.extinction_ratio * erf
        dmap = ((er - 1.0) / (er + 1.0)).astype(np.float32)
    else:
        dmap = np.full(shape, cfg.d, np.float32)
    gain = g if g is not None else np.ones(shape, np.float32)
    return np.ascontiguousarray(phi), np.ascontiguousarray(dmap), np.ascontiguousarray(gain)
