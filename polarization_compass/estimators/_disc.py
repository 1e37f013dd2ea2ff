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
The sky disc both disc methods (SM-ASM, Symmetry) fit on.

The AoP relative to the local meridian (AOPLM, eqs 29-30) on a disc of sky centred on the zenith
pixel, with a smooth radial taper: its geometry (:func:`disc_radius`, :func:`disc_selection`,
:func:`taper`, :func:`disc_cells`) and the compiled per-pixel steps the methods' passes share
(:mod:`._sm_asm_kernels`, :mod:`._symmetry_kernels`). Mirror pairs for an incomplete disc:
:mod:`._mirror`; the estimator skeleton: :mod:`._disc_estimator`.

``xi`` (eq 30, the angle between +y_cam and the local meridian at a pixel) is computed from the
pixel's ray, ``xi = atan2(r_x, r_y)``: for the paper's pinhole with square pixels this is eq 30
exactly (``atan2(x - cx, y - cy)``, tested), and it stays right for a fisheye or non-square pixels.
Both methods assume a level camera (the paper's premise); under tilt they show the paper's tilt
errors.

Why a disc with a smooth edge: both methods find an axis of mirror symmetry of the AOPLM pattern.
The image rectangle is not mirror-symmetric about an arbitrary line through its centre, so its
corners would bias the axis; a disc is symmetric about every such line, and a taper that goes
smoothly to zero keeps the pixel lattice from aliasing at the edge.
"""

from __future__ import annotations

from functools import lru_cache
import math
from typing import NamedTuple

from numba import njit
import numpy as np

from ._common import axial_residual_rad
from ._kernels import acc_brightness
from ..camera import CameraModel
from ..camera_pixels import PixelSelection
from ..fastmath import atan2, sincos_folded
from ..fastmath import FM as _FMV

__all__ = [
    'disc_radius',
    'disc_radius_mm',
    'disc_selection',
    'taper',
    'aoplm_rad',
    'disc_cells',
    'DiscRing',
    'level_rss_many',
]


@lru_cache(maxsize=32)
def disc_radius(camera: CameraModel) -> float:
    """hypot(r_x, r_y) of the largest ray circle about the optical axis inside the image."""
    cx, cy = camera.cx_px, camera.cy_px
    xs = np.array([1.0, float(camera.width_px), cx, cx])
    ys = np.array([cy, cy, 1.0, float(camera.height_px)])
    r, ok = camera.rays_from_pixels(xs, ys)
    rho = np.hypot(r[0], r[1])
    return float(rho[ok].min()) if ok.any() else 1.0


def disc_radius_mm(camera: CameraModel, rho_max: float) -> float:
    """
    Return the disc radius on the sensor (mm from the principal point).

    Radius on the sensor (mm from the principal point) of the ray circle hypot(r_x, r_y) = rho_max.
    """
    f = camera.focal_length_mm
    if camera.model == 'pinhole':
        return f * math.tan(math.asin(min(rho_max, 1.0)))
    return f * math.asin(min(rho_max, 1.0))


def disc_selection(camera: CameraModel, fraction: float, stride: int) -> PixelSelection:
    """Return the square of sensor pixels holding the disc (and the stride)."""
    rr = disc_radius_mm(camera, disc_radius(camera) * fraction)
    hx = rr / (camera.pixel_pitch_x_um * 1e-3) + 1.0
    hy = rr / (camera.pixel_pitch_y_um * 1e-3) + 1.0
    x0 = max(1, int(math.floor(camera.cx_px - hx)))
    x1 = min(int(camera.width_px), int(math.ceil(camera.cx_px + hx)))
    y0 = max(1, int(math.floor(camera.cy_px - hy)))
    y1 = min(int(camera.height_px), int(math.ceil(camera.cy_px + hy)))
    # keep the block symmetric about the principal point
    dx = min(camera.cx_px - x0, x1 - camera.cx_px)
    dy = min(camera.cy_px - y0, y1 - camera.cy_px)
    x0, x1 = int(math.ceil(camera.cx_px - dx)), int(math.floor(camera.cx_px + dx))
    y0, y1 = int(math.ceil(camera.cy_px - dy)), int(math.floor(camera.cy_px + dy))
    return PixelSelection.rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1, stride)


def taper(rho, rho_max: float, fraction: float) -> np.ndarray:
    """1 inside ``(1 - fraction) rho_max``, then a cos^2 fall to 0 at ``rho_max`` (C1-smooth)."""
    rho = np.asarray(rho, dtype=float)
    if fraction <= 0.0:
        return (rho <= rho_max).astype(float)
    t = np.clip((rho / rho_max - (1.0 - fraction)) / fraction, 0.0, 1.0)
    return np.cos(0.5 * np.pi * t) ** 2


def aoplm_rad(aop_rad, rays):
    """Eq 29: AoP - xi, folded to [-pi/2, pi/2), with xi = atan2(r_x, r_y) (eq 30 from the ray)."""
    xi = np.arctan2(rays[0], rays[1])
    return axial_residual_rad(aop_rad, xi), xi


@lru_cache(maxsize=32)
def disc_cells(
    camera: CameraModel,
    x0: float,
    dx: float,
    y0: float,
    dy: float,
    rho_lo: float,
    rho_max: float,
    taper_frac: float,
) -> float:
    """
    Return the taper sum over the lattice points inside the disc ring.

    Sum of the taper over the points of the lattice (x0 + k dx, y0 + l dy), extended over the whole
    image, whose ray lies in the disc ring [rho_lo, rho_max]: the denominator of the mirror
    coverage (a view that does not cover the disc counts what it misses).
    """
    xs = x0 + dx * np.arange(math.ceil((1 - x0) / dx), math.floor((camera.width_px - x0) / dx) + 1)
    ys = y0 + dy * np.arange(
        math.ceil((1 - y0) / dy), math.floor((camera.height_px - y0) / dy) + 1
    )
    X, Y = np.meshgrid(xs, ys)
    r, ok = camera.rays_from_pixels(X.reshape(-1), Y.reshape(-1))
    rho = np.hypot(r[0], r[1])
    inr = ok & (rho >= rho_lo) & (rho <= rho_max) & (rho > 0.0)
    return float(taper(rho[inr], rho_max, taper_frac).sum())


class DiscRing(NamedTuple):
    """The pixels a disc pass reads: DoP at least ``min_dop``, ray radius in [rho_lo, rho_max]."""

    min_dop: float
    rho_lo: float  # hypot(r_x, r_y) of the ring's inner edge (0: the whole disc)
    rho_max: float  # ... of its outer edge, where the taper reaches 0
    taper_frac: float  # outer part of the disc over which the taper falls to 0


# --------------------------------------------------------------------------------------------
# Compiled per-pixel steps (one loop over the view's pixels per pass; blocks via segments, see
# _views.view_segments)
#
# Pass 1 (the plain fit) also counts: cnt = (usable, valid, valid non-finite, unusable pixels
# inside the disc). With unusable pixels, a gather pass compacts the invariant per-pixel terms of
# the usable pixels (times S(p)) once, and each trial axis of the mirror iteration is then a short
# fit over them with the weight S(p'); pass 2 takes the final pair weights (none: ``mg`` of shape
# (0, 0), bit-identical sums).
# --------------------------------------------------------------------------------------------
@njit(inline='always', cache=True, error_model='numpy')
def _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi):  # pragma: no cover - compiled
    """
    Load pixel i for the disc passes (branch-free).

    Load pixel i: (usable, all values finite, ray inside the disc ring [rho_lo, rho_hi], a, p, rx,
    ry, rz, rho, cos 2a, sin 2a). The ring test needs only a finite ray (it holds for invalid
    pixels too). Branch-free (``&`` and selects, not ``and``), so that loops over it can vectorise
    (:func:`_lane_pixel`).
    """
    a = np.float64(aop[i])
    p = np.float64(dop[i])
    rx = np.float64(rays[0, i])
    ry = np.float64(rays[1, i])
    rz = np.float64(rays[2, i])
    rfin = (abs(rx) < 1e6) & (abs(ry) < 1e6) & (abs(rz) < 1e6)
    fin = rfin & (abs(a) < 1e6) & (abs(p) < 1e6)
    rho = math.sqrt(rx * rx + ry * ry)
    rho = rho if rfin else 0.0
    inr = rfin & (rho >= rho_lo) & (rho <= rho_hi) & (rho > 0.0)
    ok = valid[i] & fin & (p >= min_dop) & inr
    sa, ca = sincos_folded(a if fin else 0.0)
    return ok, fin, inr, a, p, rx, ry, rz, rho, ca * ca - sa * sa, 2.0 * sa * ca


@njit(inline='always', cache=True, error_model='numpy')
def _lane_pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi):  # pragma: no cover - compiled
    """
    Load pixel i for a vectorised pass; an unusable pixel reads as zeros.

    The values are (usable, valid, valid but non-finite, unusable inside the disc ring, p, rx, ry,
    rz, rho, cos 2a, sin 2a) from :func:`_pixel`; an unusable pixel has p = 0 on the ray (1, 0, 0),
    so that every value stays finite and its weight is 0 without a branch.
    """
    ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(
        aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi
    )
    v = valid[i]
    p = p if ok else 0.0
    rx = rx if ok else 1.0
    ry = ry if ok else 0.0
    rz = rz if ok else 0.0
    rho = rho if ok else 1.0
    return ok, v, v & ~fin, inr & ~(v & fin), p, rx, ry, rz, rho, c2a, s2a


@njit(inline='always', cache=True, error_model='numpy')
def _taper1(rho, rho_max, frac):  # pragma: no cover - compiled
    """Return the taper (:func:`taper`) at rho, branch-free (vectorises)."""
    t = min(max((rho / rho_max - (1.0 - frac)) / frac, 0.0), 1.0)
    c = sincos_folded(0.5 * math.pi * t)[1]
    hard = 1.0 if rho <= rho_max else 0.0
    return c * c if frac > 0.0 else hard


@njit(inline='always', cache=True, error_model='numpy')
def _level_resid(c2a, s2a, rx, ry, rz, s0, s1, s2):  # pragma: no cover - compiled
    """
    Return the axial AoP residual (rad) against the Rayleigh E-vector of the sun s.

    AoP residual (rad, axial) against the Rayleigh E-vector s x r of the sun s = (s0, s1, s2): 0.5
    arg(exp(2ia) conj(u)^2), u = ey + i ex (branch-free atan2).
    """
    ex = s1 * rz - s2 * ry
    ey = s2 * rx - s0 * rz
    ur = ey * ey - ex * ex  # u^2 = (ey + i ex)^2
    ui = 2.0 * ex * ey
    qr = c2a * ur + s2a * ui  # exp(2ia) * conj(u^2)
    qi = s2a * ur - c2a * ui
    return 0.5 * atan2(qi, qr)


@njit(inline='always', cache=True)
def _exp2i_aoplm(c2a, s2a, rx, ry, rho):  # pragma: no cover - compiled
    """(Re, Im) of exp(2i AOPLM) = exp(2ia) x^2 with x = (r_y - i r_x) / rho = exp(-i xi)."""
    er = ry / rho
    ei = -rx / rho
    x2r = er * er - ei * ei
    x2i = 2.0 * er * ei
    return c2a * x2r - s2a * x2i, c2a * x2i + s2a * x2r


#: Pixels per chunk of the gathers' vectorised first step (:func:`_gather_lanes`).
GATHER_CHUNK = 256


@njit(cache=True, nogil=True, error_model='numpy')
def _gather_lanes(
    aop, dop, valid, rays, o, n, min_dop, rho_lo, rho_hi, taper_frac, fl, tp, px
):  # pragma: no cover - compiled
    """
    Load pixels o..o+n for a gather (a loop LLVM vectorises: no branch, no fast-math).

    fl[q] = 1 if the pixel is valid, finite and in the disc ring, + 2 if usable (:func:`_pixel`);
    tp[q] its taper (0 unless fl & 1); px[:, q] = (p, rx, ry, rho, cos 2a, sin 2a) as
    :func:`_pixel` gives them (the same values a scalar loop computes).
    """
    for q in range(n):
        ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(
            aop, dop, valid, rays, o + q, min_dop, rho_lo, rho_hi
        )
        use = inr & valid[o + q] & fin
        fl[q] = np.int8(use) + np.int8(2) * np.int8(ok)
        t = _taper1(rho, rho_hi, taper_frac)
        tp[q] = t if use else 0.0
        px[0, q] = p
        px[1, q] = rx
        px[2, q] = ry
        px[3, q] = rho
        px[4, q] = c2a
        px[5, q] = s2a


@njit(cache=True, nogil=True)
def _brightness_pass(
    aop, dop, valid, rays, inten, min_dop, rho_lo, rho_max, stats
):  # pragma: no cover - compiled
    """
    Accumulate the brightness statistics of every usable pixel with a finite intensity.

    Brightness statistics (:func:`acc_brightness`) of every usable pixel with a finite intensity.
    """
    for i in range(aop.size):
        ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(
            aop, dop, valid, rays, i, min_dop, rho_lo, rho_max
        )
        ival = np.float64(inten[i])
        if ok and abs(ival) < 1e30:
            acc_brightness(stats, 0, ival, rx, ry, rz)


@njit(cache=True, nogil=True)
def _block_sums(t0, t1, seg_start, seg_end, seg_block, block_sum):  # pragma: no cover - compiled
    """block_sum[0|1, block] += the sums of t0|t1 over each segment."""
    for k in range(seg_start.size):
        u = v = 0.0
        for i in range(seg_start[k], seg_end[k]):
            u += t0[i]
            v += t1[i]
        block_sum[0, seg_block[k]] += u
        block_sum[1, seg_block[k]] += v


@njit(cache=True, nogil=True, fastmath=_FMV, error_model='numpy')
def _level_rss2(
    aop, dop, valid, rays, min_dop, rho_lo, rho_max, a0, a1, a2, b0, b1, b2, step, out
):  # pragma: no cover - compiled
    """
    Accumulate the squared AoP residuals against the level Rayleigh patterns of two suns a, b.

    out[0|1] += squared AoP residual (:func:`_level_resid`) against sun a|b, out[2] += 1, over
    every ``step``-th usable pixel; vectorised (fast-math sums), an unusable pixel adds zero.
    """
    q0 = q1 = cnt = 0.0
    for i in range(0, aop.size, step):
        ok, _, _, _, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(
            aop, dop, valid, rays, i, min_dop, rho_lo, rho_max
        )
        r1 = _level_resid(c2a, s2a, rx, ry, rz, a0, a1, a2)
        r2 = _level_resid(c2a, s2a, rx, ry, rz, b0, b1, b2)
        r1 = r1 if ok else 0.0
        r2 = r2 if ok else 0.0
        q0 += r1 * r1
        q1 += r2 * r2
        cnt += 1.0 if ok else 0.0
    out[0] += q0
    out[1] += q1
    out[2] += cnt


@njit(cache=True, nogil=True)
def level_rss_many(
    aop, dop, valid, rays, min_dop, rho_lo, rho_max, suns, step, rss
):  # pragma: no cover - compiled
    """
    Accumulate the squared AoP residuals against several level Rayleigh patterns.

    For ``suns`` (m, 3), m even: rss[j] += squared AoP residual against sun j over every
    ``step``-th usable pixel, rss[m] += 1 for each; one vectorised pass per pair of suns
    (:func:`_level_rss2`).
    """
    m = suns.shape[0]
    out = np.zeros(3)
    for j in range(0, m, 2):
        out[:] = 0.0
        _level_rss2(
            aop,
            dop,
            valid,
            rays,
            min_dop,
            rho_lo,
            rho_max,
            suns[j, 0],
            suns[j, 1],
            suns[j, 2],
            suns[j + 1, 0],
            suns[j + 1, 1],
            suns[j + 1, 2],
            step,
            out,
        )
        rss[j] += out[0]
        rss[j + 1] += out[1]
        if j == 0:
            rss[m] += out[2]
