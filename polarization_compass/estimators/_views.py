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
The pixels an estimator reads: the view of an observation and its blocks, and input checks.

``stride`` is in *sensor pixels*: an observation whose pixels are already ``d`` sensor pixels apart
(a strided render, superpixels: ``d = 2``) is subsampled by ``max(1, round(stride / d))`` more, so
an observation rendered from :meth:`Estimator.pixels_needed` is used as is. ``region`` is ``(x0,
y0, width, height)`` in 1-based sensor pixels. Pixel lists (1-D observations) are never strided.
The least-squares methods thin a full-resolution grid by an even step *phase-balanced* (see
:func:`select_view`): the same number of pixels, a quarter on each phase of the 2 x 2 polarizer
mosaic.

"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math

import numpy as np

from .base import HeadingResult, Observation, Status
from ..camera import CameraModel
from ..camera_pixels import PixelSelection
from ..runtime import kernel_array

__all__ = [
    'Samples',
    'PixelView',
    'select_view',
    'samples_from_view',
    'view_segments',
    'view_grid_layout',
    'check_sun',
    'selection_for',
]


# --------------------------------------------------------------------------------------------
# Sampling
# --------------------------------------------------------------------------------------------
@dataclass
class Samples:
    """
    The usable pixels of an observation, flat.

    ``aop_rad``/``dop`` float64, ``rays`` (3, n) float64, ``x_px``/``y_px`` float64 1-based.
    ``grid_shape`` is the 2-D shape before masking (None for a list).
    """

    aop_rad: np.ndarray
    dop: np.ndarray
    rays: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    intensity: np.ndarray | None
    nonfinite: int
    considered: int

    @property
    def n(self) -> int:
        return int(self.aop_rad.size)


def _centred_indices(n: int, step: int) -> np.ndarray:
    """Return indices every ``step`` along an axis of length n, symmetric about its centre."""
    count = (n - 1) // step + 1
    start = (n - 1 - (count - 1) * step) // 2
    return start + step * np.arange(count)


def _phase_balanced_indices(n: int, step: int, first_px: float = 1.0) -> np.ndarray:
    """
    Return indices along an axis, about ``step`` apart, that alternate in parity.

    The axis has length n and ``step`` is the mean spacing. The indices are those whose sensor
    coordinate ``c`` (``first_px`` for index 0, 1-based) has ``(c - 1) mod 2 step`` in ``{0, step -
    1}`` (stride 2: c - 1 = 0, 1, 4, 5, 8, ...; stride 4: 0, 3, 8, 11, ...). For an even step half
    are even and half odd. Anchored to sensor coordinates, so the close pairs (1 px apart at stride
    2, whose bilinear neighbourhoods overlap) never straddle a block of ``block_px`` (a multiple of
    2 step).
    """
    m = (np.arange(n) + int(round(first_px)) - 1) % (2 * step)
    return np.nonzero((m == 0) | (m == step - 1))[0]


def _slice_of(idx: np.ndarray) -> slice:
    """Return an arithmetic progression of indices (at least one) as a slice."""
    return slice(int(idx[0]), int(idx[-1]) + 1, int(idx[1] - idx[0]) if idx.size > 1 else 1)


def grid_spacing_px(obs: Observation) -> float:
    """
    Return the spacing in sensor pixels between neighbouring columns of an observation.

    1 for a pixel list.
    """
    x = np.asarray(obs.x_px)
    if x.ndim != 2 or x.shape[1] < 2:
        return 1.0
    return float(abs(x[0, 1] - x[0, 0])) or 1.0


@dataclass
class PixelView:
    """
    The pixels a method reads, flat (views where possible, else compact copies), before masking.

    ``grid`` = ((x0, dx, nx), (y0, dy, ny)) for a regular 2-D grid in row-major order (sensor
    pixels), else None. ``subgrids``: a tuple of such keys when the pixels are several regular
    grids one after the other, each row-major (the phase-balanced stride of :func:`select_view`),
    else None. Neither: a pixel list. ``rays`` is (3, n).

    ``rays``, ``x_px`` and ``y_px`` are held C-contiguous and read-only (:func:`kernel_array`: a
    free view, or a copy of another layout), the form of the camera's cached rays and
    coordinates, so that every path (full frame, stride, region, pixel list) hands the compiled
    kernels one argument type. ``aop``, ``dop`` and ``valid`` are computed per frame and arrive
    C-contiguous and writeable on every path; they are kept as they are.
    """

    aop: np.ndarray
    dop: np.ndarray
    valid: np.ndarray
    rays: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    intensity: np.ndarray | None
    grid: tuple | None
    subgrids: tuple | None = None

    def __post_init__(self):
        self.rays = kernel_array(self.rays)
        self.x_px = kernel_array(self.x_px)
        self.y_px = kernel_array(self.y_px)


def _check_shapes(obs: Observation):
    aop = np.asarray(obs.aop_rad)
    n_all = int(aop.size)
    for name in ('dop', 'valid', 'x_px', 'y_px'):
        a = np.asarray(getattr(obs, name))
        if a.size != n_all:
            raise _BadInput(f'{name} has {a.size} values, aop_rad has {n_all}')
    if obs.intensity is not None and np.asarray(obs.intensity).size != n_all:
        raise _BadInput(
            f'intensity has {np.asarray(obs.intensity).size} values, aop_rad has {n_all}'
        )
    rays = np.asarray(obs.rays_cam)
    if rays.ndim != 2 or rays.shape != (3, n_all):
        raise _BadInput(f'rays_cam must be (3, {n_all}), got {rays.shape}')
    if n_all == 0:
        raise _BadInput('the observation has no pixels')


def select_view(
    obs: Observation, knobs: dict, window=None, balance_phases: bool = False
) -> PixelView:
    """
    Apply ``stride``, ``region`` and ``window`` to a view without looking at the values.

    Apply ``stride`` and ``region`` (and a ``window`` (x_lo, x_hi, y_lo, y_hi), sensor pixels,
    inclusive) without looking at the values. Raises _BadInput for inconsistent arrays.

    ``balance_phases``: when a full-resolution grid (neighbours 1 sensor pixel apart) is thinned by
    an even step, every second kept row and column is moved on by one pixel, so that the four
    phases of a 2 x 2 polarizer mosaic are read equally often. A plain even stride reads one phase
    only; after a bilinear demosaic each phase has its own anisotropic Stokes noise and so its own
    O(sigma^2) AoP bias, which cancels over the four phases but not within one (the view then has
    ``subgrids``, not ``grid``).
    """
    _check_shapes(obs)
    shape = np.shape(obs.aop_rad)
    lims = _view_limits(knobs, window)
    if not (len(shape) == 2 and shape[0] >= 1 and shape[1] >= 1):
        return _list_view(obs, lims)
    rows, cols, balanced = _grid_axes(obs, knobs['stride'], lims, balance_phases)
    if rows.size == 0 or cols.size == 0:
        e = np.zeros(0)
        return PixelView(
            e,
            e,
            np.zeros(0, bool),
            np.zeros((3, 0)),
            e,
            e,
            None if obs.intensity is None else e,
            None,
        )
    if balanced:
        return _balanced_view(obs, rows, cols)
    return _strided_view(obs, rows, cols)


def _view_limits(knobs: dict, window) -> list:
    """
    Return the rectangles a pixel of the view must lie in.

    The rectangles (x_lo, x_hi, y_lo, y_hi) (sensor pixels, inclusive) a pixel of the view must lie
    in: the ``region`` knob's and the ``window``.
    """
    lims = []
    if knobs.get('region') is not None:
        x0, y0, w, h = knobs['region']
        lims.append((x0, x0 + w - 1, y0, y0 + h - 1))
    if window is not None:
        lims.append(window)
    return lims


def _grid_axes(obs: Observation, stride: int, lims: list, balance_phases: bool):
    """
    Return the indices a 2-D observation keeps along each axis at ``stride``.

    (rows, columns, balanced): the indices a 2-D observation keeps along each axis at ``stride``
    sensor pixels (centred, or phase-balanced: see :func:`select_view`) inside the rectangles
    ``lims``.
    """
    xs = np.asarray(obs.x_px)
    ys = np.asarray(obs.y_px)
    H, W = np.shape(obs.aop_rad)
    spacing = grid_spacing_px(obs)
    step = max(1, int(round(stride / spacing)))
    balanced = balance_phases and step % 2 == 0 and spacing == 1.0
    if balanced:
        rows = _phase_balanced_indices(H, step, float(ys[0, 0]))
        cols = _phase_balanced_indices(W, step, float(xs[0, 0]))
    else:
        rows = _centred_indices(H, step) if step > 1 else np.arange(H)
        cols = _centred_indices(W, step) if step > 1 else np.arange(W)
    xc = xs[0, cols]
    yr = ys[rows, 0]
    for xl, xh, yl, yh in lims:
        kc = (xc >= xl) & (xc <= xh)
        kr = (yr >= yl) & (yr <= yh)
        cols, xc = cols[kc], xc[kc]
        rows, yr = rows[kr], yr[kr]
    return rows, cols, balanced


def _balanced_view(obs: Observation, rows: np.ndarray, cols: np.ndarray) -> PixelView:
    """
    Return the phase-balanced view: four regular subgrids copied one after the other.

    The phase-balanced view: rows (and columns) alternate between two arithmetic progressions, so
    the pixels are four regular subgrids, copied one after the other (plain strided copies; the
    sums do not care about the order).
    """
    xs = np.asarray(obs.x_px)
    ys = np.asarray(obs.y_px)
    shape = np.shape(obs.aop_rad)
    parts = [
        (rr, cc)
        for rr in (rows[0::2], rows[1::2])
        for cc in (cols[0::2], cols[1::2])
        if rr.size and cc.size
    ]
    n_all = int(rows.size * cols.size)

    def take(a, lead=()):
        src = np.asarray(a).reshape(lead + shape)
        out = np.empty(lead + (n_all,), dtype=src.dtype)
        off = 0
        for rr, cc in parts:
            n = rr.size * cc.size
            dst = np.reshape(out[..., off : off + n], lead + (rr.size, cc.size), copy=False)
            dst[...] = src[..., _slice_of(rr), _slice_of(cc)]
            off += n
        return out

    keys, xg, yg = [], [], []
    for rr, cc in parts:
        xc_p, yr_p = xs[0, cc], ys[rr, 0]
        xg.append(np.tile(xc_p, yr_p.size))  # coordinates from the axes: no pass over x_px
        yg.append(np.repeat(yr_p, xc_p.size))
        keys.append(
            (
                (
                    float(xc_p[0]),
                    float(xc_p[1] - xc_p[0]) if xc_p.size > 1 else 1.0,
                    int(xc_p.size),
                ),
                (
                    float(yr_p[0]),
                    float(yr_p[1] - yr_p[0]) if yr_p.size > 1 else 1.0,
                    int(yr_p.size),
                ),
            )
        )
    return PixelView(
        take(obs.aop_rad),
        take(obs.dop),
        take(obs.valid),
        take(obs.rays_cam, (3,)),
        np.concatenate(xg),
        np.concatenate(yg),
        None if obs.intensity is None else take(obs.intensity),
        None,
        tuple(keys),
    )


def _strided_view(obs: Observation, rows: np.ndarray, cols: np.ndarray) -> PixelView:
    """
    Return the view of one regular grid.

    The grid's rows and columns are arithmetic progressions. The view holds the arrays themselves
    when every pixel is kept, else strided slices copied compactly once.
    """
    xs = np.asarray(obs.x_px)
    ys = np.asarray(obs.y_px)
    rays = np.asarray(obs.rays_cam)
    shape = np.shape(obs.aop_rad)
    H, W = shape
    if rows.size == H and cols.size == W:

        def take(a):
            return np.asarray(a).reshape(-1)

        r = rays
    else:
        rs = slice(int(rows[0]), int(rows[-1]) + 1, int(rows[1] - rows[0]) if rows.size > 1 else 1)
        cs = slice(int(cols[0]), int(cols[-1]) + 1, int(cols[1] - cols[0]) if cols.size > 1 else 1)

        def take(a):
            return np.ascontiguousarray(np.asarray(a).reshape(shape)[rs, cs]).reshape(-1)

        r = np.ascontiguousarray(rays.reshape(3, H, W)[:, rs, cs]).reshape(3, -1)
    xc = xs[0, cols]
    yr = ys[rows, 0]
    dx = float(xc[1] - xc[0]) if xc.size > 1 else 1.0
    dy = float(yr[1] - yr[0]) if yr.size > 1 else 1.0
    grid = ((float(xc[0]), dx, int(xc.size)), (float(yr[0]), dy, int(yr.size)))
    return PixelView(
        take(obs.aop_rad),
        take(obs.dop),
        take(obs.valid),
        r,
        take(xs),
        take(ys),
        None if obs.intensity is None else take(obs.intensity),
        grid,
    )


def _list_view(obs: Observation, lims: list) -> PixelView:
    """
    Return the view of a pixel list: the pixels inside the rectangles ``lims``.

    Also used for a 2-D observation that is not a grid; the view is flat.
    """
    aop = np.asarray(obs.aop_rad)
    rays = np.asarray(obs.rays_cam)
    inten = None if obs.intensity is None else np.asarray(obs.intensity)
    flat_x = np.asarray(obs.x_px).reshape(-1)
    flat_y = np.asarray(obs.y_px).reshape(-1)
    if lims:
        m = np.ones(flat_x.size, dtype=bool)
        for xl, xh, yl, yh in lims:
            m &= (flat_x >= xl) & (flat_x <= xh) & (flat_y >= yl) & (flat_y <= yh)
        idx = np.nonzero(m)[0]
        return PixelView(
            aop.reshape(-1)[idx],
            np.asarray(obs.dop).reshape(-1)[idx],
            np.asarray(obs.valid).reshape(-1)[idx],
            rays[:, idx],
            flat_x[idx],
            flat_y[idx],
            None if inten is None else inten.reshape(-1)[idx],
            None,
        )
    return PixelView(
        aop.reshape(-1),
        np.asarray(obs.dop).reshape(-1),
        np.asarray(obs.valid).reshape(-1),
        rays,
        flat_x,
        flat_y,
        None if inten is None else inten.reshape(-1),
        None,
    )


def samples_from_view(view: PixelView, min_dop: float, radius_limit=None) -> Samples:
    """
    Mask a view to its usable pixels and return float64 copies of them.

    Mask a view: valid, finite, DoP >= min_dop (and ray radius in ``radius_limit`` = (lo, hi) of
    hypot(r_x, r_y)); float64 copies of the usable pixels.
    """
    a = view.aop
    d = view.dop
    v = np.asarray(view.valid, dtype=bool)
    r = view.rays
    considered = int(v.sum())
    finite = np.isfinite(a) & np.isfinite(d) & np.isfinite(r).all(axis=0)
    nonfinite = int((v & ~finite).sum())
    keep = v & finite
    keep &= np.where(keep, d, 0.0) >= min_dop
    if radius_limit is not None:
        rho = np.hypot(
            np.where(keep, r[0], 0.0).astype(np.float64),
            np.where(keep, r[1], 0.0).astype(np.float64),
        )
        keep &= (rho >= radius_limit[0]) & (rho <= radius_limit[1])
    idx = np.nonzero(keep)[0]
    inten = None
    if view.intensity is not None:
        inten = view.intensity[idx].astype(np.float64)
        if not np.all(np.isfinite(inten)):
            inten = None
    return Samples(
        a[idx].astype(np.float64),
        d[idx].astype(np.float64),
        r[:, idx].astype(np.float64),
        view.x_px[idx].astype(np.float64),
        view.y_px[idx].astype(np.float64),
        inten,
        nonfinite,
        considered,
    )


def view_segments(view: PixelView, block_px: int):
    """
    Return a view's flat arrays in block order and their segments.

    Flat arrays of a view in block order and their segments (runs of one block each), for the
    compiled passes: ((aop, dop, valid, rays, x_px, y_px, intensity), (start, end, block,
    n_blocks)).
    """
    from ._block_layout import grid_segments, list_segments

    if view.grid is not None:
        return (
            (view.aop, view.dop, view.valid, view.rays, view.x_px, view.y_px, view.intensity),
            grid_segments(view.grid[0], view.grid[1], int(block_px)),
        )
    if view.subgrids is not None:
        return (
            (view.aop, view.dop, view.valid, view.rays, view.x_px, view.y_px, view.intensity),
            subgrid_segments(view.subgrids, int(block_px)),
        )
    order, segs = list_segments(view.x_px, view.y_px, int(block_px))
    return (
        (
            view.aop[order],
            view.dop[order],
            view.valid[order],
            kernel_array(view.rays[:, order]),
            kernel_array(view.x_px[order]),
            kernel_array(view.y_px[order]),
            None if view.intensity is None else view.intensity[order],
        ),
        segs,
    )


def view_grid_layout(view: PixelView, block_px: int):
    """
    Return the view's pixels as regular grids for the row-wise compiled pass.

    :func:`polarization_compass.estimators._block_layout.grid_layout` of the view, or None for a
    pixel list.
    """
    from ._block_layout import grid_layout

    keys = (view.grid,) if view.grid is not None else view.subgrids
    return None if keys is None else grid_layout(tuple(keys), int(block_px))


@lru_cache(maxsize=64)
def subgrid_segments(keys: tuple, block_px: int):
    """
    Return the segments of regular grids stored one after the other.

    Segments (start, end, block, n_blocks) of regular grids stored one after the other, each
    row-major with key ((x0, dx, nx), (y0, dy, ny)) (sensor pixels): one run per (grid, row, block
    column), blocks of ``block_px`` sensor pixels numbered alike in every grid. Cached.
    """
    from ._block_layout import block_indices

    bcs, brs, K, R = block_indices(keys, block_px)
    starts, ends, blks = [], [], []
    off = 0
    for bc, br in zip(bcs, brs):
        nx, ny = bc.size, br.size
        change = np.nonzero(np.diff(bc))[0] + 1
        cs = np.concatenate([[0], change])
        ce = np.concatenate([change, [nx]])
        rows = np.arange(ny)[:, None] * nx + off
        starts.append((rows + cs[None, :]).reshape(-1))
        ends.append((rows + ce[None, :]).reshape(-1))
        blks.append((br[:, None] * K + bc[cs][None, :]).reshape(-1))
        off += nx * ny
    out = (
        np.concatenate(starts).astype(np.int64),
        np.concatenate(ends).astype(np.int64),
        np.concatenate(blks).astype(np.int64),
        int(R * K),
    )
    for a in out[:3]:
        a.setflags(write=False)
    return out


class _BadInput(Exception):
    """Internal: turns into Status.BAD_INPUT."""


def check_sun(name: str, obs: Observation, knobs: dict) -> HeadingResult | None:
    """Ephemeris checks shared by all methods; a failed result or None."""
    try:
        alt = float(obs.sun_altitude_deg)
        az = float(obs.sun_azimuth_deg)
    except (TypeError, ValueError):
        return HeadingResult.failed(name, Status.BAD_INPUT, 'sun azimuth/altitude are not numbers')
    if not (math.isfinite(alt) and math.isfinite(az)) or abs(alt) > 90.0:
        return HeadingResult.failed(
            name,
            Status.BAD_INPUT,
            f'sun azimuth/altitude must be finite with |altitude| <= 90, got {az}, {alt}',
        )
    if alt > knobs['max_sun_altitude_deg']:
        return HeadingResult.failed(
            name,
            Status.SUN_NEAR_ZENITH,
            f'sun altitude {alt:.3f} deg > {knobs["max_sun_altitude_deg"]:g}: '
            'the solar meridian is undefined',
        )
    if alt < knobs['min_sun_altitude_deg']:
        return HeadingResult.failed(
            name,
            Status.SUN_BELOW_HORIZON,
            f'sun altitude {alt:.3f} deg < {knobs["min_sun_altitude_deg"]:g}',
        )
    return None


def selection_for(knobs: dict, camera: CameraModel) -> PixelSelection:
    """Return the PixelSelection a method with these stride/region knobs reads."""
    if knobs.get('region') is not None:
        x0, y0, w, h = knobs['region']
        return PixelSelection.rect(x0, y0, w, h, knobs['stride'])
    if knobs['stride'] > 1:
        return PixelSelection.strided(knobs['stride'])
    return PixelSelection.full()
