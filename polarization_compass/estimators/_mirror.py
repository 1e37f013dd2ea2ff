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
Mirror pairs for an incomplete sky disc (the fixed-point solver is :mod:`._axis_solve`).

Both belong to the axis fit that SM-ASM and Symmetry share (see :mod:`._disc` for the disc and
:mod:`._disc_estimator` for how the methods use it).

Incomplete sky (occluders, invalid pixels, a region that cuts the disc)
-----------------------------------------------------------------------
Both axis fits are unbiased only because the pixels they sum over form a set that is
mirror-symmetric about the true axis. Half a disc is not (unless the cut is perpendicular to the
meridian): the fits were off by 10-20 deg RMS with status ok. So when any pixel of the disc is
unusable (invalid or non-finite) or the view does not cover the disc, each pixel gets the pair
weight ``m_i = S(p_i) S(p_i')``, where ``p_i'`` is the pixel's mirror image about the trial axis
``theta`` (a reflection of its sensor-plane offset from the principal point, in millimetres: exact
for the radially symmetric camera models) and ``S`` is a smooth usability map: the indicator of
usable pixels (outside the view: usable beyond the disc, unusable inside it) blurred by a Gaussian
of ``MIRROR_BLUR_CELLS`` grid cells, then ``sin^2`` of its rise between the levels
``MIRROR_LEVELS`` (0.5, 0.9), times the indicator itself, bilinear between grid points. An occluded
region gets S = 0 with a smooth edge about 2.5 cells wide; an isolated unusable pixel (NaN, hot
pixel) only zeroes S at its own grid point, so it costs almost no coverage, and the bilinear S(p')
takes weight from the pixels paired with it (without that, 10 % of pixels invalid at random move a
noise-free sm_asm heading by 0.1 deg; with it, < 0.02 deg at stride 16). ``S(p) S(p')`` is exactly
mirror-symmetric about ``theta`` and smooth (no lattice aliasing at the occluder's edge, the same
reason as the disc taper), so the fit on the weighted pixels returns ``theta`` when ``theta`` is
the true axis: the axis is a fixed point ``theta = f(theta)`` of "fit the pixels paired about
theta". There can be several (the edge of the occluder is a degenerate one; a thin wedge of pairs
elsewhere can balance a fit): :func:`solve_axes` scans ``h = f(theta) - theta`` on 18 axes with a
subsample and refines every sign change by the secant method (the true axis may attract or repel a
plain iteration). Kept are axes with mirror coverage ``>= min_mirror_coverage``, ``|1 - f'| >=
MIN_CONDITIONING``, the method's own test (symmetry: the paired map is symmetric, ``F / sum |a_k|^2
>= 0.95``) and a level-Rayleigh residual at most ``MAX_MIRROR_RESIDUAL_RATIO`` times the plain
fit's; of these the one with the smallest residual wins.

Broken clouds (every disc, complete or not)
-------------------------------------------
Clouds keep the clear-sky AoP beneath them but lower the DoP unevenly, so weighting each pixel by
its own DoP^2 (a set of weights not symmetric about the meridian) pulled both fits off the meridian
by degrees. The weights are therefore pair weights ``Q(p) Q(p')`` with ``Q`` the DoP map (0 where
unusable or below ``min_dop``) times the smooth usability of the pixels at or above ``min_dop``:
one field at p and at p', symmetric about the trial axis by construction (``Q(p) Q(p') = DoP^2``
on a clear sky). The axis is the fixed point next to the plain fit (:func:`refine_axis`); for an
incomplete disc where that fails, the scan above runs on the occlusion-only weights ``DoP(p)^2
S(p) S(p')`` (kernels' ``own_dop2``; :meth:`MirrorMap.occlusion_at`) and each root is refined on
``Q(p) Q(p')``.

Uncertainty of the fixed point: ``d theta* = d f / (1 - f'(theta*))``: the statistical sigma of the
weighted fit is divided by ``|1 - f'|`` (``f'`` from the last secant step or a finite difference).
When the usable pairs form a thin wedge the fit follows the wedge (``f' -> 1``) and sigma grows
accordingly. Without an acceptable axis the status is ``insufficient_coverage`` with the measured
share or the failed test in the reason. A complete disc is never re-weighted: the plain fit, as
before.

"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math

from numba import njit
import numpy as np

from ._disc import disc_radius_mm
from ..camera import CameraModel

__all__ = [
    'MirrorMap',
    'mirror_map',
    'NO_MIRROR',
    'MP_SIZE',
    'view_covers_disc',
    'MIRROR_BLUR_CELLS',
    'MIRROR_LEVELS',
]

#: The smooth usability map S: the usable-pixel indicator blurred by a Gaussian of this sigma (grid
#: cells), then S = sin^2 of its rise between these two levels (0 below the first, 1 above the
#: second).
MIRROR_BLUR_CELLS = 2.0
MIRROR_LEVELS = (0.5, 0.9)
#: The reflection parameters ``mp`` (:attr:`MirrorMap.params`, float64 (MP_SIZE,)) the kernels
#: read, by index: the principal point (sensor px), the pixel pitch (mm), sin and cos of the trial
#: axis theta (from +y_cam towards +x_cam), the first grid point and the grid step (sensor px) of
#: the S and Q grids. The reflection acts on the offset from the principal point in millimetres.
MP_CX, MP_CY = 0, 1
MP_PITCH_X_MM, MP_PITCH_Y_MM = 2, 3
MP_SIN, MP_COS = 4, 5
MP_X0, MP_DX, MP_Y0, MP_DY = 6, 7, 8, 9
MP_SIZE = 10
#: No mirror weighting (m = 1, the pixel's own DoP^2): empty S and Q maps and unused parameters.
NO_MIRROR = (np.zeros((0, 0)), np.zeros((0, 0)), np.zeros(MP_SIZE))


# --------------------------------------------------------------------------------------------
# The smooth usability map S
# --------------------------------------------------------------------------------------------
@dataclass
class MirrorMap:
    """
    Smooth usability ``S`` on a regular grid of sensor positions, and the reflection parameters.

    ``grid`` (ny, nx) float64 in [0, 1]; grid point (r, c) is at sensor pixel (x0 + c dx, y0 + r
    dy).
    """

    grid: np.ndarray
    weight: np.ndarray  # Q = DoP * smooth usability (DoP >= min_dop), same grid: Q(p) Q(p')
    params: np.ndarray  # mp (MP_* indices) with sin theta = cos theta = 0
    lattice: tuple  # x0, dx, y0, dy of the view's own pixels
    camera: CameraModel

    def at(self, theta_rad: float) -> tuple:
        """
        Return the kernel arguments (mg, mq, mp) for the reflection about the axis ``theta``.

        Kernel arguments (S grid, Q grid, parameters) for the reflection about the axis ``theta``
        (from +y_cam towards +x_cam).
        """
        p = self.params.copy()
        p[MP_SIN] = math.sin(theta_rad)
        p[MP_COS] = math.cos(theta_rad)
        p.setflags(write=False)  # the kernels' one argument type: read-only like grid and weight
        return self.grid, self.weight, p

    def occlusion_at(self, theta_rad: float) -> tuple:
        """
        Return the kernel arguments (mg, mg, mp) of the occlusion-only pair weights S(p) S(p').

        For a gather with ``own_dop2`` (weights DoP(p)^2 S(p) S(p')): the global search for axes
        of an incomplete disc, whose roots are then refined on Q(p) Q(p').
        """
        mg, _, p = self.at(theta_rad)
        return mg, mg, p


def _usable_grid(view, camera: CameraModel, min_dop: float = 0.0):
    """
    Return the view's usable pixels and their DoP weights on a regular grid, with its geometry.

    (usable (ny, nx) bool, DoP (ny, nx) float64, x0, dx, y0, dy) of the view's pixels on a regular
    grid: the view's own grid, or a pixel list scattered onto the grid of its smallest coordinate
    steps (cells without a pixel are unusable). The DoP grid is 0 where a pixel is unusable or its
    DoP is below ``min_dop`` (the pixels the fits give no weight).
    """
    fin = np.isfinite(view.aop) & np.isfinite(view.dop) & np.isfinite(view.rays).all(axis=0)
    usable = np.asarray(view.valid, dtype=bool) & fin
    dop = np.where(usable, np.asarray(view.dop, dtype=np.float64), 0.0)
    dop = np.where(dop >= min_dop, dop, 0.0)
    if view.grid is not None:
        (x0, dx, nx), (y0, dy, ny) = view.grid
        return usable.reshape(ny, nx), dop.reshape(ny, nx), x0, dx, y0, dy
    x = np.asarray(view.x_px, dtype=float)
    y = np.asarray(view.y_px, dtype=float)

    def axis(c):
        u = np.unique(c)
        lo, hi = float(u[0]), float(u[-1])
        gaps = np.diff(u)
        step = float(gaps[gaps > 1e-6].min()) if (gaps > 1e-6).any() else 1.0
        step = max(step, (hi - lo) / 2047.0)  # at most 2048 cells a side
        return lo, step, int(round((hi - lo) / step)) + 1

    x0, dx, nx = axis(x)
    y0, dy, ny = axis(y)
    grid = np.zeros((ny, nx), dtype=bool)
    dgrid = np.zeros((ny, nx))
    col = np.clip(np.rint((x - x0) / dx).astype(np.int64), 0, nx - 1)
    row = np.clip(np.rint((y - y0) / dy).astype(np.int64), 0, ny - 1)
    grid[row[usable], col[usable]] = True
    dgrid[row[usable], col[usable]] = dop[usable]
    return grid, dgrid, x0, dx, y0, dy


@lru_cache(maxsize=16)
def _outside_disc(
    camera: CameraModel,
    x0: float,
    dx: float,
    nx: int,
    y0: float,
    dy: float,
    ny: int,
    rho_max: float,
) -> np.ndarray:
    """
    Return the grid positions beyond the disc's edge on the sensor.

    Grid positions (x0 + c dx, y0 + r dy) beyond the disc's edge on the sensor (read-only bool (ny,
    nx)).
    """
    r_mm = np.hypot(
        ((x0 + dx * np.arange(nx) - camera.cx_px) * camera.pixel_pitch_x_um * 1e-3)[None, :],
        ((y0 + dy * np.arange(ny) - camera.cy_px) * camera.pixel_pitch_y_um * 1e-3)[:, None],
    )
    out = r_mm > disc_radius_mm(camera, rho_max)
    out.setflags(write=False)
    return out


def mirror_map(view, camera: CameraModel, rho_max: float, min_dop: float = 0.0) -> MirrorMap:
    """
    Return the smooth usability map S and the pair-weight map Q of a view (see the module doc).

    Outside the view, positions beyond the disc count as usable (nothing is missing there) and
    positions inside it as unusable. ``Q`` is the pixels' DoP (0 where unusable or below
    ``min_dop``) times the smooth usability of the pixels at or above ``min_dop``: the pair weight
    is ``Q(p) Q(p')``.
    """
    usable, dgrid, x0, dx, y0, dy = _usable_grid(view, camera, min_dop)
    ny, nx = usable.shape
    S, params = _smooth_usability(
        camera,
        float(x0),
        float(dx),
        float(y0),
        float(dy),
        int(ny),
        int(nx),
        float(rho_max),
        np.packbits(usable).tobytes(),
    )
    # the weights' usability: also 0 below min_dop (those pixels get no weight, nor their pairs)
    weighted = dgrid > 0.0
    Sw = S
    if not np.array_equal(weighted, usable):
        Sw, _ = _smooth_usability(
            camera,
            float(x0),
            float(dx),
            float(y0),
            float(dy),
            int(ny),
            int(nx),
            float(rho_max),
            np.packbits(weighted).tobytes(),
        )
    pad = (S.shape[0] - ny) // 2
    Q = np.zeros(S.shape)
    Q[pad : pad + ny, pad : pad + nx] = dgrid
    Q *= Sw
    Q.setflags(write=False)  # read-only like S: one argument type of the kernels
    return MirrorMap(S, Q, params, (float(x0), float(dx), float(y0), float(dy)), camera)


@lru_cache(
    maxsize=4
)  # the last frame's S and S of the weights, for both disc methods (full resolution: tens of MB)
def _smooth_usability(
    camera: CameraModel,
    x0: float,
    dx: float,
    y0: float,
    dy: float,
    ny: int,
    nx: int,
    rho_max: float,
    usable_bits: bytes,
):
    """
    Return the smooth usability map and reflection parameters of a usable grid.

    (S, reflection parameters) of :func:`mirror_map` for a usable grid (packed bits): read-only,
    cached, so the two disc methods run on one frame (an error-map cell) blur it once.
    """
    usable = (
        np.unpackbits(np.frombuffer(usable_bits, np.uint8), count=ny * nx)
        .reshape(ny, nx)
        .astype(bool)
    )
    px, py = camera.pixel_pitch_x_um * 1e-3, camera.pixel_pitch_y_um * 1e-3
    pad = int(math.ceil(3.0 * MIRROR_BLUR_CELLS)) + 1
    full = _outside_disc(
        camera, x0 - pad * dx, dx, nx + 2 * pad, y0 - pad * dy, dy, ny + 2 * pad, float(rho_max)
    ).copy()
    full[pad : pad + ny, pad : pad + nx] = usable
    import cv2

    cell = math.sqrt(dx * px * dy * py)
    blur = cv2.GaussianBlur(
        full.astype(np.float32),
        (0, 0),
        sigmaX=MIRROR_BLUR_CELLS * cell / (dx * px),
        sigmaY=MIRROR_BLUR_CELLS * cell / (dy * py),
        borderType=cv2.BORDER_REPLICATE,
    )
    t = np.clip(
        (blur.astype(np.float64) - MIRROR_LEVELS[0]) / (MIRROR_LEVELS[1] - MIRROR_LEVELS[0]),
        0.0,
        1.0,
    )
    S = (t >= 1.0).astype(np.float64)  # sin^2 of the rise: 0 below it, 1 above, sin only on it
    rise = (t > 0.0) & (t < 1.0)
    S[rise] = np.sin(0.5 * math.pi * t[rise]) ** 2
    S *= full  # exactly 0 on every unusable grid point
    params = np.zeros(MP_SIZE)
    params[MP_CX], params[MP_CY] = camera.cx_px, camera.cy_px
    params[MP_PITCH_X_MM], params[MP_PITCH_Y_MM] = px, py
    params[MP_X0], params[MP_DX] = x0 - pad * dx, dx
    params[MP_Y0], params[MP_DY] = y0 - pad * dy, dy
    for a in (S, params):
        a.setflags(write=False)
    return S, params


@lru_cache(maxsize=64)
def _grid_covers_disc(camera: CameraModel, grid: tuple, rho_max: float) -> bool:
    (x0, dx, nx), (y0, dy, ny) = grid
    rr = disc_radius_mm(camera, rho_max)
    hx = rr / (camera.pixel_pitch_x_um * 1e-3)
    hy = rr / (camera.pixel_pitch_y_um * 1e-3)
    # the outermost grid lines lie within one grid step of the disc's edge or beyond it
    return (
        x0 <= camera.cx_px - hx + dx
        and x0 + dx * (nx - 1) >= camera.cx_px + hx - dx
        and y0 <= camera.cy_px - hy + dy
        and y0 + dy * (ny - 1) >= camera.cy_px + hy - dy
    )


def view_covers_disc(view, camera: CameraModel, rho_max: float) -> bool:
    """
    Tell whether a grid view reaches the disc's edge on every side.

    Always true for a pixel list (only its holes are seen).
    """
    if view.grid is None:
        return True
    return _grid_covers_disc(camera, view.grid, float(rho_max))


# --------------------------------------------------------------------------------------------
# Compiled: S(p) and S(p') per pixel
# --------------------------------------------------------------------------------------------
@njit(inline='always', cache=True)
def _bilinear0(g, r, c):  # pragma: no cover - compiled
    """G (2-D) at fractional (row r, column c), bilinear, 0 outside the grid."""
    ny, nx = g.shape
    if not (r > -1.0 and c > -1.0 and r < ny and c < nx):
        return 0.0
    i0 = int(math.floor(r))
    j0 = int(math.floor(c))
    fr = r - i0
    fc = c - j0
    if i0 >= 0 and j0 >= 0 and i0 + 1 < ny and j0 + 1 < nx:  # inside: no per-corner test
        return (1.0 - fr) * ((1.0 - fc) * g[i0, j0] + fc * g[i0, j0 + 1]) + fr * (
            (1.0 - fc) * g[i0 + 1, j0] + fc * g[i0 + 1, j0 + 1]
        )
    acc = 0.0
    for di in range(2):
        i = i0 + di
        if i < 0 or i >= ny:
            continue
        wr = fr if di else 1.0 - fr
        for dj in range(2):
            j = j0 + dj
            if j < 0 or j >= nx:
                continue
            acc += wr * (fc if dj else 1.0 - fc) * g[i, j]
    return acc


@njit(inline='always', cache=True)
def _bilinear0_pair(g, h, r, c):  # pragma: no cover - compiled
    """
    Return (G, H) at fractional (row r, column c): :func:`_bilinear0` of two grids of one shape.

    The position's floor and fractions are found once; each value is the same arithmetic as
    :func:`_bilinear0` (bit-identical).
    """
    ny, nx = g.shape
    if not (r > -1.0 and c > -1.0 and r < ny and c < nx):
        return 0.0, 0.0
    i0 = int(math.floor(r))
    j0 = int(math.floor(c))
    fr = r - i0
    fc = c - j0
    if i0 >= 0 and j0 >= 0 and i0 + 1 < ny and j0 + 1 < nx:  # inside: no per-corner test
        a = (1.0 - fr) * ((1.0 - fc) * g[i0, j0] + fc * g[i0, j0 + 1]) + fr * (
            (1.0 - fc) * g[i0 + 1, j0] + fc * g[i0 + 1, j0 + 1]
        )
        b = (1.0 - fr) * ((1.0 - fc) * h[i0, j0] + fc * h[i0, j0 + 1]) + fr * (
            (1.0 - fc) * h[i0 + 1, j0] + fc * h[i0 + 1, j0 + 1]
        )
        return a, b
    acc = 0.0
    acc2 = 0.0
    for di in range(2):
        i = i0 + di
        if i < 0 or i >= ny:
            continue
        wr = fr if di else 1.0 - fr
        for dj in range(2):
            j = j0 + dj
            if j < 0 or j >= nx:
                continue
            acc += wr * (fc if dj else 1.0 - fc) * g[i, j]
            acc2 += wr * (fc if dj else 1.0 - fc) * h[i, j]
    return acc, acc2


@njit(inline='always', cache=True)
def _mirror_consts(mp):  # pragma: no cover - compiled
    """
    Return the mirror constants of mp (angle, pixel scales, principal point).

    In order: sin theta, cos theta, grid columns per mm, grid rows per mm, and the grid column and
    row of the principal point.
    """
    return (
        mp[MP_SIN],
        mp[MP_COS],
        1.0 / (mp[MP_PITCH_X_MM] * mp[MP_DX]),
        1.0 / (mp[MP_PITCH_Y_MM] * mp[MP_DY]),
        (mp[MP_CX] - mp[MP_X0]) / mp[MP_DX],
        (mp[MP_CY] - mp[MP_Y0]) / mp[MP_DY],
    )


@njit(inline='always', cache=True)
def _grid_pos(mp, x, y):  # pragma: no cover - compiled
    """Return the grid position (row, column) of sensor pixel (x, y) in the S and Q grids."""
    return (y - mp[MP_Y0]) / mp[MP_DY], (x - mp[MP_X0]) / mp[MP_DX]


@njit(inline='always', cache=True)
def _offset_mm(mp, x, y):  # pragma: no cover - compiled
    """Return the sensor-plane offset (u, v) mm of sensor pixel (x, y) from the principal point."""
    return (x - mp[MP_CX]) * mp[MP_PITCH_X_MM], (y - mp[MP_CY]) * mp[MP_PITCH_Y_MM]


@njit(inline='always', cache=True)
def _mirror_pos(st, ct, kc, kr, c0, r0, u, v):  # pragma: no cover - compiled
    """
    Return the grid position (row, column) of the mirror image of the sensor offset (u, v) mm.

    The mirror image p' = 2 (p . a) a - p about the axis a = (sin theta, cos theta); constants
    from :func:`_mirror_consts`.
    """
    d = 2.0 * (u * st + v * ct)
    return r0 + (d * ct - v) * kr, c0 + (d * st - u) * kc


@njit(cache=True, nogil=True)
def _pair_weights(mg, mq, mp, xs, ys):  # pragma: no cover - compiled
    """
    Return the pair weights Q(p) Q(p') of every pixel, or ones without a mirror map.

    Q is bilinear at the pixel and at its mirror image (:func:`_mirror_pos`); without a mirror map
    (``mg`` empty) the passes weight a pixel by its own DoP^2.
    """
    out = np.ones(xs.size)
    if mg.shape[0]:
        st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
        for i in range(xs.size):
            r, c = _grid_pos(mp, xs[i], ys[i])
            own = _bilinear0(mq, r, c)
            u, v = _offset_mm(mp, xs[i], ys[i])
            r, c = _mirror_pos(st, ct, kc, kr, c0, r0, u, v)
            out[i] = own * _bilinear0(mq, r, c)
    return out


# --------------------------------------------------------------------------------------------
