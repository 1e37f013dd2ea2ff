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
The numba kernels of the cloud layer: seeded value noise, transmission and compositing.

The fBm value noise of the layer's density, :class:`CloudParams` (one frame's layer parameters as
the kernels read them), the transmission of a ray through the layer (per pixel, or on a grid
interpolated along a row) and the light through a cloud (:func:`cloud_light`,
:func:`cloud_over`). The one-pass render (:mod:`.sky_effects`) inlines the per-pixel steps; the
model and its references are in :mod:`.clouds`'s docstring.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange
import numpy as np

from .fastmath import exp_nonpos

# ----------------------------------------------------------------------------------------------
# noise
_OCTAVES = 4  # written out in _fbm


@njit(inline='always', cache=True)
def _hash01(ix, iy, seed):  # pragma: no cover - compiled
    """Hash (ix, iy, seed) on a lattice to [0, 1) (integer mixing, wraps mod 2^32)."""
    h = (ix * 374761393 + iy * 668265263 + seed * 1442695041) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h = h ^ (h >> 16)
    return (h & 0xFFFFFF) / 16777216.0


@njit(inline='always', cache=True)
def _value_noise(x, y, seed):  # pragma: no cover - compiled
    x0 = math.floor(x)
    y0 = math.floor(y)
    fx = x - x0
    fy = y - y0
    ix = np.int64(x0)
    iy = np.int64(y0)
    sx = fx * fx * (3.0 - 2.0 * fx)
    sy = fy * fy * (3.0 - 2.0 * fy)
    a = _hash01(ix, iy, seed)
    b = _hash01(ix + 1, iy, seed)
    c = _hash01(ix, iy + 1, seed)
    d = _hash01(ix + 1, iy + 1, seed)
    return (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy


@njit(inline='always', cache=True)
def _fbm(x, y, seed):  # pragma: no cover - compiled
    """
    Return the fBm of 4 octaves of value noise at (x, y): sum of 2^-(o+1) noise_o over 0.9375.

    Written out octave by octave (amplitudes 0.5, 0.25, 0.125, 0.0625, their sum 0.9375, all
    exact): as a loop over the octaves the caller's loop over points stayed scalar; unrolled it
    vectorises (6x faster, measured), with the same values bit for bit.
    """
    s = 0.5 * _value_noise(x, y, seed)
    x = 2.0 * x + 17.3
    y = 2.0 * y - 5.1
    s += 0.25 * _value_noise(x, y, seed + 7919)
    x = 2.0 * x + 17.3
    y = 2.0 * y - 5.1
    s += 0.125 * _value_noise(x, y, seed + 2 * 7919)
    x = 2.0 * x + 17.3
    y = 2.0 * y - 5.1
    s += 0.0625 * _value_noise(x, y, seed + 3 * 7919)
    return s / 0.9375


@njit(parallel=True, cache=True)
def _noise_at(x, y, seed, out):  # pragma: no cover - compiled
    for i in prange(x.size):
        out[i] = _fbm(x[i], y[i], seed)


class CloudParams(NamedTuple):
    """
    Hold the cloud layer's parameters for one frame, as the kernels read them.

    Built by :meth:`CloudLayer.frame_params`.

    Attributes
    ----------
    height_over_scale : float
        Cloud height over the feature size.
    off_x, off_y : float
        Wind offset east and north since the scene's time [feature sizes].
    seed : int
        Noise seed.
    threshold : float
        Noise threshold of a cloud.
    inv_softness : float
        1 / softness of the cloud edges.
    overcast : bool
        Whether the sky is covered everywhere (coverage 1).
    tau_max : float
        Optical thickness of a cloud.

    """

    height_over_scale: float
    off_x: float
    off_y: float
    seed: int
    threshold: float
    inv_softness: float
    overcast: bool
    tau_max: float


@njit(parallel=True, cache=True)
def _cloud_kernel(rays, R, cp, bright, aop, dop, inten, min_dop, valid):  # pragma: no cover
    """Composite the clouds over rays ``rays`` (any selection), ``cp`` a :class:`CloudParams`."""
    height_over_scale, off_x, off_y, seed = cp.height_over_scale, cp.off_x, cp.off_y, cp.seed
    thr, inv_soft, overcast, tau_max = cp.threshold, cp.inv_softness, cp.overcast, cp.tau_max
    n = rays.shape[1]
    for i in prange(n):
        px = rays[0, i]
        py = rays[1, i]
        pz = rays[2, i]
        e = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
        nn = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
        u = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
        if u <= 0.0:
            continue  # below the horizon: no cloud layer there
        k = height_over_scale / max(u, 0.02)
        if overcast:
            d = 1.0
        else:
            v = _fbm(e * k - off_x, nn * k - off_y, seed)
            d = min(max((v - thr) * inv_soft, 0.0), 1.0)
        if d <= 0.0:
            continue
        t = math.exp(-tau_max * d)
        i_clear = inten[i]
        i_tot = i_clear * t + bright * (1.0 - t)
        dop[i] = np.float32(dop[i] * i_clear * t / i_tot)
        inten[i] = np.float32(i_tot)
        if dop[i] < min_dop and valid[i]:
            valid[i] = False
            aop[i] = np.float32(0.0)
            dop[i] = np.float32(0.0)


@njit(inline='always', cache=True, error_model='numpy')
def cloud_transmission_at(px, py, pz, R, cp):  # pragma: no cover - compiled
    """
    Return T = exp(-tau) of the cloud layer along one ray (1 below the horizon or between clouds).

    The cases are selects (exp(-0) = 1 between clouds), with the branch-free
    :func:`~polarization_compass.fastmath.exp_nonpos`, so that a loop over rays vectorises (the
    nested branches and the libm exp of a first version ran it ~10x slower, measured). Compiled,
    inlined.

    Parameters
    ----------
    px, py, pz : float
        Unit viewing ray in the camera frame.
    R : numpy.ndarray, shape (3, 3), float64
        Rotation from the camera frame to ENU.
    cp : CloudParams
        The layer's parameters for the frame (:meth:`CloudLayer.frame_params`).

    Returns
    -------
    float
        T in (0, 1].

    """
    u = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
    e = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
    nn = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
    k = cp.height_over_scale / max(u, 0.02)
    v = _fbm(e * k - cp.off_x, nn * k - cp.off_y, cp.seed)
    d = 1.0 if cp.overcast else min(max((v - cp.threshold) * cp.inv_softness, 0.0), 1.0)
    t = exp_nonpos(-cp.tau_max * d)
    return t if u > 0.0 else 1.0


@njit(inline='always', cache=True, fastmath=True)
def grid_row_to_columns(tg, cols, cf, out):  # pragma: no cover - compiled
    """
    Interpolate one grid row of T linearly to every pixel column (compiled, inlined).

    ``out[j] = tg[g] (1 - cf[j]) + tg[g + 1] cf[j]`` for ``cols[g] <= j < cols[g + 1]``: the
    horizontal half of the bilinear interpolation, done once per grid row (8x fewer than per pixel
    row), so that a pixel row's T is a blend of two such rows (:func:`cloud_transmission`), a
    contiguous loop that vectorises. A segment of ``GRID_STEP`` pixels uses its fractions k / 8 as
    constants (exact in float32, the values of ``cf``): a fixed 8-wide loop, 2x faster than a
    gather per pixel (measured).

    Parameters
    ----------
    tg : numpy.ndarray, shape (Gx,), float32
        T at the grid row's points.
    cols : numpy.ndarray, shape (Gx,), int64
        The grid's pixel columns, increasing, the last one W - 1.
    cf : numpy.ndarray, shape (W,), float32
        Each pixel column's fraction between its two grid columns.
    out : numpy.ndarray, shape (W,), float32
        Output: T of the grid row at every pixel column.

    """
    one = np.float32(1.0)
    step = np.float32(1.0 / GRID_STEP)
    G = tg.size
    for g in range(G - 1):
        a = tg[g]
        b = tg[g + 1]
        c0 = cols[g]
        if cols[g + 1] - c0 == GRID_STEP:
            for k in range(GRID_STEP):
                f = np.float32(k) * step
                out[c0 + k] = a * (one - f) + b * f
        else:
            for j in range(c0, cols[g + 1]):
                out[j] = a * (one - cf[j]) + b * cf[j]
    out[out.size - 1] = tg[G - 1]


@njit(parallel=True, cache=True, error_model='numpy')
def _cloud_transmission_grid_kernel(grays, R, cp, cols, cf, out):  # pragma: no cover
    """T of the layer on each grid row, interpolated to every pixel column (out: (Gy, W))."""
    gx = grays.shape[1] // out.shape[0]
    for g in prange(out.shape[0]):
        tg = np.empty(gx, np.float32)
        for j in range(gx):
            i = g * gx + j
            tg[j] = cloud_transmission_at(grays[0, i], grays[1, i], grays[2, i], R, cp)
        grid_row_to_columns(tg, cols, cf, out[g])


@njit(inline='always', cache=True, fastmath=True)
def cloud_transmission(u0, u1, fy):  # pragma: no cover - compiled
    """
    Return a pixel's cloud transmission from the two grid rows around its row (float32).

    The vertical half of the bilinear interpolation of the layer's T from its grid
    (:meth:`CloudLayer.transmission_grid`): ``u0 (1 - fy) + u1 fy``, with ``u0``, ``u1`` the
    pixel's column of the grid rows below and above, already interpolated along the row, and ``fy``
    the row's fraction between them. Compiled, inlined into the composite loops.

    Parameters
    ----------
    u0, u1 : float32
        T of the grid rows below and above at the pixel's column.
    fy : float32
        Fraction of the way from the row below to the row above, [0, 1].

    Returns
    -------
    float32
        T at the pixel, (0, 1].

    """
    return u0 * (np.float32(1.0) - fy) + u1 * fy


@njit(inline='always', cache=True, fastmath=True)
def cloud_light(i_clear, t, bright):  # pragma: no cover - compiled
    """
    Return the transmitted clear-sky light and the total radiance under the cloud layer (float32).

    ``W = I_clear T`` (polarized as the clear sky) and ``I = W + B (1 - T)`` (the cloud's own light
    is unpolarized), so the DoP under the cloud is ``DoP_clear W / I`` (module docstring;
    :func:`cloud_over`). Compiled, inlined.

    Parameters
    ----------
    i_clear : float32
        Clear-sky radiance relative to the clear zenith.
    t : float32
        Transmission exp(-tau) of the layer along the ray, (0, 1].
    bright : float32
        The cloud's own radiance B relative to the clear zenith.

    Returns
    -------
    w : float32
        Transmitted clear-sky radiance.
    radiance : float32
        Radiance under the cloud.

    References
    ----------
    .. [1] I. Pomozi, G. Horvath and R. Wehner, "How the clear-sky angle of polarization pattern
       continues underneath clouds", J. Exp. Biol. 204:2933-2942, 2001.

    """
    w = i_clear * t
    return w, w + bright * (np.float32(1.0) - t)


@njit(inline='always', cache=True, fastmath=True)
def cloud_over(i_clear, t, dop, bright):  # pragma: no cover - compiled
    """
    Return the DoP and radiance of clear-sky light seen through the cloud layer (float32).

    ``I = I_clear T + B (1 - T)`` and ``DoP = DoP_clear I_clear T / I`` (:func:`cloud_light`).
    T = 1 leaves the pixel as it is. Compiled, inlined into the composite loops.

    Parameters
    ----------
    i_clear : float32
        Clear-sky radiance relative to the clear zenith.
    t : float32
        Transmission exp(-tau) of the layer along the ray, (0, 1].
    dop : float32
        Clear-sky DoP [0, 1].
    bright : float32
        The cloud's own radiance B relative to the clear zenith.

    Returns
    -------
    dop : float32
        DoP under the cloud.
    radiance : float32
        Radiance under the cloud.

    """
    w, i_tot = cloud_light(i_clear, t, bright)
    return dop * w / i_tot, i_tot


@njit(parallel=True, cache=True, fastmath=True)
def _cloud_composite_grid_kernel(
    tu, rk, rk1, rf, bright, aop, dop, inten, min_dop, valid
):  # pragma: no cover - compiled
    """
    Composite the clouds with the transmission interpolated bilinearly from the grid.

    Pixel row i lies between grid rows rk[i] and rk1[i] at fraction rf[i]; ``tu`` holds T of the
    grid rows at every pixel column (:meth:`CloudLayer.transmission_grid`).
    """
    H = rk.size
    W = tu.shape[1]
    zero = np.float32(0.0)
    for i in prange(H):
        # per-row slices: the composite is a plain loop that vectorises (a per-pixel gather and a
        # flat index i * W + j kept it scalar, measured)
        u0 = tu[rk[i]]
        u1 = tu[rk1[i]]
        fy = rf[i]
        o = i * W
        dp = dop[o : o + W]
        it = inten[o : o + W]
        if min_dop <= zero:
            # no pixel can fall below the minimum DoP: AoP and validity are not touched (a third
            # less memory traffic; the DoP of a valid pixel stays >= 0)
            for j in range(W):
                t = cloud_transmission(u0[j], u1[j], fy)
                dp[j], it[j] = cloud_over(it[j], t, dp[j], bright)
            continue
        ap = aop[o : o + W]
        vd = valid[o : o + W]
        for j in range(W):
            # branch-free (t = 1 leaves the pixel as it is); invalid pixels hold DoP 0, so "drop"
            # leaves them as they are; valid = valid and not drop as a comparison of bools (2x
            # faster than & and ~, measured)
            d, it[j] = cloud_over(it[j], cloud_transmission(u0[j], u1[j], fy), dp[j], bright)
            drop = d < min_dop
            dp[j] = zero if drop else d
            ap[j] = zero if drop else ap[j]
            vd[j] = vd[j] > drop


#: A contiguous block is clouded from T on every GRID_STEP-th pixel, interpolated (see
#: CloudLayer.apply).
GRID_STEP = 8
