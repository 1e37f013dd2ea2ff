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
The numba kernels of the light a lens adds: sun disk and glare, flare ghosts, vignetting.

:class:`LensParams` and :class:`Ghosts` carry one frame's lens parameters into the kernels;
:func:`lens_over` and :func:`lens_light` are the per-pixel steps that the one-pass render
(:mod:`.sky_effects`) inlines; the block and per-pixel kernels serve the stage-by-stage render of
:class:`.optics.Optics`. The models and their references are in :mod:`.optics`'s docstring.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange
import numpy as np


@njit(inline='always', fastmath=True, cache=True)
def _glare_angle_sq_f32(px, py, pz, sx, sy, sz):  # pragma: no cover - compiled
    """
    Return the squared angle (rad^2, float32) between the unit ray p and the sun s, one sqrt.

    Branch-free, without acos, in three ranges of the angle gamma, each through the Cephes
    ``asinf`` polynomial ``asin(x) = x (1 + z P(z))``, z = x^2, |x| <= 1/2 (relative error
    ~2.5e-7):

    - gamma <= 60 deg: gamma = 2 asin(|p - s| / 2) (the chord form: exact for unit vectors and,
      unlike acos(p.s), not losing the small angles near the sun to float32 rounding of a cosine
      near 1); squared directly from z = |p - s|^2 / 4, no sqrt;
    - 60 < gamma < 120 deg: gamma = pi/2 - asin(p.s), no sqrt;
    - gamma >= 120 deg: gamma = pi - 2 asin(|p + s| / 2), one sqrt.

    The exponent-2 glare needs only gamma^2: one sqrt per pixel instead of two (the division-free
    asin of a first version took the chord's length, then sqrt((1 - a) / 2) beyond 60 deg).
    """
    quarter = np.float32(0.25)
    one = np.float32(1.0)
    dx = px - sx
    dy = py - sy
    dz = pz - sz
    a2 = quarter * (dx * dx + dy * dy + dz * dz)  # sin^2(gamma / 2)
    ex = px + sx
    ey = py + sy
    ez = pz + sz
    b2 = quarter * (ex * ex + ey * ey + ez * ez)  # cos^2(gamma / 2)
    c = px * sx + py * sy + pz * sz  # cos(gamma)
    near = a2 <= quarter
    far = b2 <= quarter
    z = a2 if near else (b2 if far else c * c)
    poly = (
        (
            (np.float32(4.2163199048e-2) * z + np.float32(2.4181311049e-2)) * z
            + np.float32(4.5470025998e-2)
        )
        * z
        + np.float32(7.4953002686e-2)
    ) * z + np.float32(1.6666752422e-1)
    f = one + z * poly  # asin(x) / x
    g_far = np.float32(math.pi) - np.float32(2.0) * math.sqrt(b2) * f
    g_mid = np.float32(math.pi / 2) - c * f
    g = g_far if far else g_mid
    return np.float32(4.0) * a2 * f * f if near else g * g


class LensParams(NamedTuple):
    """
    One frame's lens parameters, as the compiled kernels read them (:meth:`Optics.frame_params`).

    A named tuple of float32 numbers, an int and a bool (numba compiles attribute access to a
    field read). The glare's exponent-2 flag is not a field: the block kernel specialises on it.

    Attributes
    ----------
    vig_mode : int
        0 no vignetting, 1 cos^4, 2 radial polynomial.
    cx, cy : numpy.float32
        Principal point [px, 1-based].
    inv_hd2 : numpy.float32
        1 / half-diagonal^2 [px^-2].
    k1, k2, k3 : numpy.float32
        Coefficients of the radial polynomial (0 when unused).
    do_sun : bool
        Whether the sun is declared.
    sx, sy, sz : numpy.float32
        Unit sun vector in the camera frame.
    disk_rad2 : numpy.float32
        Squared solar disk radius [rad^2].
    disk : numpy.float32
        Radiance of the solar disk, relative to the clear zenith.
    g1 : numpy.float32
        Glare factor: ``glare_at_1deg``, times (1 deg in rad)^2 when the exponent is 2.
    expo : numpy.float32
        Glare exponent.

    """

    vig_mode: int
    cx: np.float32
    cy: np.float32
    inv_hd2: np.float32
    k1: np.float32
    k2: np.float32
    k3: np.float32
    do_sun: bool
    sx: np.float32
    sy: np.float32
    sz: np.float32
    disk_rad2: np.float32
    disk: np.float32
    g1: np.float32
    expo: np.float32


class Ghosts(NamedTuple):
    """
    One frame's lens-flare ghosts, as the compiled kernels read them (:meth:`Optics.frame_params`).

    Attributes
    ----------
    gx, gy : numpy.ndarray, shape (k,), float32
        Ghost centres [px, 1-based]; empty without flare or when the sun does not project.
    r2 : numpy.float32
        Squared ghost radius [px^2].
    radiance : numpy.float32
        Radiance of a ghost, relative to the clear zenith.

    """

    gx: np.ndarray
    gy: np.ndarray
    r2: np.float32
    radiance: np.float32


@njit(inline='always', fastmath=True, cache=True)
def _lens_pixel(px, py, pz, xi, yi, i_sky, lens):  # pragma: no cover - compiled
    """
    Return the vignetted sky radiance and the squared angle from the sun at one pixel.

    Vignetting by ``lens.vig_mode`` (0 none, 1 cos^4, 2 radial polynomial); the angle in rad^2;
    float32. Every term is computed and selected: branches, even loop-invariant ones, kept these
    loops scalar (measured).
    """
    one = np.float32(1.0)
    z = max(pz, np.float32(0.0))
    q = ((xi - lens.cx) * (xi - lens.cx) + (yi - lens.cy) * (yi - lens.cy)) * lens.inv_hd2
    v = z * z * z * z if lens.vig_mode == 1 else one + q * (lens.k1 + q * (lens.k2 + q * lens.k3))
    v = v if lens.vig_mode != 0 else one
    return i_sky * v, _glare_angle_sq_f32(px, py, pz, lens.sx, lens.sy, lens.sz)


@njit(inline='always', fastmath=True, cache=True)
def _sun_light(gam2, lens, square):  # pragma: no cover - compiled
    """
    Return the sun's light (disk or glare) at squared angle ``gam2`` (rad^2) as a ratio (num, den).

    The sun's light at angle gamma from it is ``num / den``: ``lens.disk`` inside the disk (gamma^2
    <= ``lens.disk_rad2``), else the glare ``glare_at_1deg (1 deg / gamma)^expo``; 0 without the
    sun (den > 0 always). ``square`` (exponent 2): ``lens.g1`` holds ``glare_at_1deg (1 deg)^2``
    and the glare is ``g1 / gamma^2``, no libm call; the callers keep that case in its own loop,
    which vectorises (exp/log are libm calls). The ratio lets the fused pass fold this division
    into its DoP division.
    """
    one = np.float32(1.0)
    ga2 = max(gam2, lens.disk_rad2)
    if square:
        num = lens.g1
        den = ga2
    else:
        num = lens.g1 * math.exp(
            np.float32(0.5) * lens.expo * math.log(np.float32((math.pi / 180.0) ** 2) / ga2)
        )
        den = one
    inside = gam2 <= lens.disk_rad2
    num = lens.disk if inside else num
    den = one if inside else den
    return (num if lens.do_sun else np.float32(0.0)), den


@njit(inline='always', fastmath=True, cache=True, error_model='numpy')
def lens_over(i_sky, dop, px, py, pz, xi, yi, lens, square):  # pragma: no cover - compiled
    """
    Return the DoP and radiance of one pixel after vignetting and the sun's light (float32).

    The vignetted sky radiance ``I V`` plus the sun's unpolarized light G (disk or glare), and the
    DoP ``DoP I V / (I V + G)`` (module docstring). The per-pixel body of the block kernel;
    compiled, inlined. ``square`` should be a constant at the call site (the exponent-2 glare is
    divisions only and vectorises; see :func:`_sun_light`).

    Parameters
    ----------
    i_sky : float32
        Radiance of the sky at the pixel, relative to the clear zenith.
    dop : float32
        DoP of the sky at the pixel.
    px, py, pz : float32
        Unit viewing ray in the camera frame.
    xi, yi : float32
        Pixel column and row [px, 1-based].
    lens : LensParams
        The frame's lens parameters.
    square : bool
        Whether the glare exponent is 2.

    Returns
    -------
    dop : float32
        DoP after the lens.
    radiance : float32
        Radiance after the lens, relative to the clear zenith.

    References
    ----------
    .. [1] CIE 135/1-1999 (Stiles-Holladay disability glare; Vos and van den Berg).
    .. [2] D. B. Goldman, "Vignette and exposure calibration and compensation", IEEE TPAMI 32,
       2010.

    """
    v, g_num, g_den = lens_light(px, py, pz, xi, yi, lens, square)
    g = g_num / g_den
    base = i_sky * v
    tot = base + g
    return (dop * (base / tot) if g > np.float32(0.0) else dop), tot


@njit(inline='always', fastmath=True, cache=True, error_model='numpy')
def lens_light(px, py, pz, xi, yi, lens, square):  # pragma: no cover - compiled
    """
    Return a pixel's vignetting factor V and the sun's light G there as a ratio (float32).

    The lens turns sky radiance I into ``I V + G`` (module docstring); :func:`lens_over` applies it
    to a pixel, the fused pass (:mod:`polarization_compass.sky_effects`) combines it with the cloud
    composite into one division. Compiled, inlined.

    Parameters
    ----------
    px, py, pz : float32
        Unit viewing ray in the camera frame.
    xi, yi : float32
        Pixel column and row [px, 1-based].
    lens : LensParams
        The frame's lens parameters.
    square : bool
        Whether the glare exponent is 2 (best a constant at the call site).

    Returns
    -------
    v : float32
        Vignetting factor (1 without vignetting).
    g_num, g_den : float32
        The sun's disk or glare radiance, relative to the clear zenith, is ``g_num / g_den`` (0
        without the sun; ``g_den`` > 0).

    """
    v, gam2 = _lens_pixel(px, py, pz, xi, yi, np.float32(1.0), lens)
    g_num, g_den = _sun_light(gam2, lens, square)
    return v, g_num, g_den


@njit(inline='always', cache=True, fastmath=True, error_model='numpy')
def _optics_block(rays, xcol, yrow, lens, square, dop, inten):  # pragma: no cover - compiled
    """
    Apply vignetting and the sun over a block of pixels given by its columns and rows.

    The block's pixel coordinates are the product of the columns ``xcol`` and the rows ``yrow``
    (full frame, region, stride, grid): no per-pixel coordinate arrays. ``square`` is a constant:
    each of :data:`_OPTICS_BLOCK_KERNELS` inlines this body with its own value.
    """
    W = xcol.size
    for r in prange(yrow.size):
        # per-row slices: with a flat index r * W + c LLVM kept this loop scalar (14x slower,
        # measured)
        o = r * W
        rx = rays[0, o : o + W]
        ry = rays[1, o : o + W]
        rz = rays[2, o : o + W]
        dp = dop[o : o + W]
        it = inten[o : o + W]
        yi = yrow[r]
        for c in range(W):
            dp[c], it[c] = lens_over(it[c], dp[c], rx[c], ry[c], rz[c], xcol[c], yi, lens, square)


# One kernel per glare law: numba.literally would specialise one kernel on ``square`` but
# re-dispatches every call (~0.1 s, measured); a run-time flag changed the other law's float32
# results (the constant lets LLVM vectorise exp/log) and ran a toy exponent-2 loop 2x slower.
@njit(parallel=True, cache=True, fastmath=True, error_model='numpy')
def _optics_block_square_kernel(rays, xcol, yrow, lens, dop, inten):  # pragma: no cover
    """Run :func:`_optics_block` for the exponent-2 glare (divisions only: vectorises)."""
    _optics_block(rays, xcol, yrow, lens, True, dop, inten)


@njit(parallel=True, cache=True, fastmath=True, error_model='numpy')
def _optics_block_power_kernel(rays, xcol, yrow, lens, dop, inten):  # pragma: no cover
    """Run :func:`_optics_block` for another glare exponent (exp and log per pixel)."""
    _optics_block(rays, xcol, yrow, lens, False, dop, inten)


#: The block kernel by "the glare exponent is 2".
_OPTICS_BLOCK_KERNELS = {True: _optics_block_square_kernel, False: _optics_block_power_kernel}


@njit(cache=True)
def _flare_box_kernel(boxes, xcol, yrow, ghosts, dop, inten):  # pragma: no cover - compiled
    """
    Add each lens-flare ghost inside its disk, visiting only its bounding box.

    A ghost is unpolarized light of ``ghosts.radiance``; its box is ``boxes[k] = (row0, row1, col0,
    col1)`` (half-open) of the block; DoP scaled by I / (I + radiance), which composes with the
    sun's light added before to the one-step ``DoP I_sky / (I_sky + G_sun + G_ghosts)``.
    """
    W = xcol.size
    gx, gy, r2, grad = ghosts.gx, ghosts.gy, ghosts.r2, ghosts.radiance
    for k in range(gx.size):
        for r in range(boxes[k, 0], boxes[k, 1]):
            dy = yrow[r] - gy[k]
            for c in range(boxes[k, 2], boxes[k, 3]):
                dx = xcol[c] - gx[k]
                if dx * dx + dy * dy <= r2:
                    i = r * W + c
                    tot = inten[i] + grad
                    dop[i] = dop[i] * (inten[i] / tot) if grad > 0 else dop[i]
                    inten[i] = tot


@njit(parallel=True, cache=True, fastmath=True, error_model='numpy')
def _optics_kernel(rays, x, y, lens, square, ghosts, dop, inten):  # pragma: no cover - compiled
    """
    Apply all declared lens effects in one pass over scattered pixels (float32, flat x/y).

    Vignetting, the sun disk and glare, the ghosts.
    """
    zero = np.float32(0.0)
    gx, gy, r2, grad = ghosts.gx, ghosts.gy, ghosts.r2, ghosts.radiance
    for i in prange(rays.shape[1]):
        xi = x[i]
        yi = y[i]
        base, gam2 = _lens_pixel(rays[0, i], rays[1, i], rays[2, i], xi, yi, inten[i], lens)
        g_num, g_den = _sun_light(gam2, lens, square)
        g = g_num / g_den
        for k in range(gx.size):
            dx = xi - gx[k]
            dy = yi - gy[k]
            g += grad if dx * dx + dy * dy <= r2 else zero
        tot = base + g
        dop[i] = dop[i] * (base / tot) if g > zero else dop[i]
        inten[i] = tot
