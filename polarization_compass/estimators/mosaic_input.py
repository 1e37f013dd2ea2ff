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
From a raw division-of-focal-plane mosaic to an :class:`Observation`.

Only what a method reads is demosaiced: an estimator's :meth:`pixels_needed` says which sensor
pixels it uses; here that becomes the part of the mosaic to demosaic (with
:mod:`polarization_compass.demosaic`, never a private demosaic):

- ``superpixel``: one output per 2 x 2 block, at the block centre (``x = x0 + 2 l + 0.5``). A
  strided selection keeps every ``max(1, stride // 2)``-th block row and column (block-aligned, so
  the polarizer layout is unchanged; the kept blocks are centred on the image); a region keeps the
  blocks inside it. The zenith method's 32 px window is 16 x 16 blocks: nothing else is demosaiced.
- ``bilinear``: the region (plus a 2-pixel margin, so interpolation sees real neighbours) at full
resolution, then the stride.
- a ``list`` or ``grid`` selection (the zenith window plus its whole-sky side grid: ~2000 pixels
  spread over the sensor) is demosaiced sparsely (:func:`_sparse_plan`): along each axis, the
  outputs of the full-frame demosaic nearest each wanted coordinate on either side (the superpixel
  centres, or the bilinear pixels themselves); the observation is their rows x columns. Only the
  mosaic samples those outputs read are gathered (whole 2 x 2 blocks; for bilinear also the
  neighbours of the 3 x 3 stencil, in even-aligned pairs so the polarizer phase and the frame-edge
  mirroring are the full frame's) and go through the same demosaic kernels. Each output is
  therefore the full-frame demosaic's value at the same pixel, bit for bit (one exception, as for a
  region crop: the bilinear DoP of a float, non-integer mosaic may differ by a few float32 ulp,
  since the fused kernel's vectorised body and scalar remainder round differently), and any
  nearest-output lookup on the axes finds the pixel it would find in the full-frame observation,
  so an estimator gives the full frame's answer (``test/test_mosaic_sparse.py``). The cost scales
  with the pixels read, not with the frame (zenith's front end on a 2448 x 2048 superpixel frame:
  1.47 -> 0.08 ms, 2 x 2 blocks 1.25 M -> 6.7 k).

Rays come from the camera model and are cached per (camera, pixel grid). The result has 2-D arrays
on a grid, as the estimators' compiled passes want: a regular grid, except for a sparse ``list``
/ ``grid`` selection, whose rows and columns are not evenly spaced (the regular parts, e.g. the
zenith window, stay regular).
"""

from __future__ import annotations

from functools import lru_cache
import math

import numpy as np

from .base import Observation
from ..camera import CameraError, CameraModel
from ..camera_pixels import PixelSelection, select_pixels
from ..demosaic import (
    aop_dop_from_stokes,
    check_ifov_k,
    IFOV_K_DEFAULT,
    polarization_from_mosaic,
    redundancy_noise,
    stokes_from_mosaic,
)
from ..errors import CompassError
from ..mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45, parse_layout, SensorError

__all__ = ['observation_from_mosaic', 'MosaicInputError']


class MosaicInputError(CompassError):
    """A mosaic that does not fit the camera or the requested pixels."""


@lru_cache(maxsize=64)
def _grid_rays(camera: CameraModel, x_key: tuple, y_key: tuple):
    """
    Return pixel coordinates, rays and ray mask of a regular grid.

    (x_px, y_px, rays (3, N) float32, has_ray) of the grid x0 + dx * arange(nx), y0 + dy *
    arange(ny).
    """
    xs = x_key[0] + x_key[1] * np.arange(x_key[2])
    ys = y_key[0] + y_key[1] * np.arange(y_key[2])
    xg, yg = np.meshgrid(xs, ys)
    rays, ok = camera.rays_from_pixels(xg, yg)
    out = (xg, yg, np.ascontiguousarray(rays.astype(np.float32)), ok.reshape(xg.shape))
    for a in out:
        a.setflags(write=False)
    return out


def _centred(n: int, step: int) -> np.ndarray:
    count = (n - 1) // step + 1
    start = (n - 1 - (count - 1) * step) // 2
    return start + step * np.arange(count)


def _wanted_rect(selection: PixelSelection | None, x0: int, y0: int, H: int, W: int):
    """
    Return the sensor rectangle and stride wanted, clipped to the mosaic.

    (x_lo, y_lo, x_hi, y_hi) sensor pixels (inclusive) and stride wanted, clipped to the mosaic.
    """
    xl, yl, xh, yh, stride = x0, y0, x0 + W - 1, y0 + H - 1, 1
    if selection is not None:
        if selection.mode == 'region':
            rx, ry, rw, rh = selection.region
            xl, yl, xh, yh = max(xl, rx), max(yl, ry), min(xh, rx + rw - 1), min(yh, ry + rh - 1)
            stride = max(1, selection.stride)
        elif selection.mode == 'stride':
            stride = max(1, selection.stride)
    if xl > xh or yl > yh:
        raise MosaicInputError(
            f'the pixels wanted ({selection.describe()}) are outside the mosaic '
            f'({W} x {H} at ({x0}, {y0}))'
        )
    return xl, yl, xh, yh, stride


def _sparse_axis(wanted: np.ndarray, start: int, n_samples: int, method: str):
    """
    Plan one axis of a sparse demosaic.

    ``wanted``: sensor coordinates (1-based) along the axis; ``start``: the sensor coordinate of
    the mosaic's first sample; ``n_samples``: the mosaic's length along the axis. Returns
    (samples: the sample indices to gather, sorted; pick: where the kept outputs sit in the
    demosaic of the gathered samples, or None for all; coords: the kept outputs' sensor
    coordinates).

    Kept: for each wanted coordinate, the full-frame demosaic's outputs nearest it on either side
    (clipped to the mosaic). Superpixel: output ``l`` is samples ``2l, 2l + 1`` at ``start + 2l
    + 0.5``. Bilinear: output ``i`` is at ``start + i`` and reads samples ``i - 1 .. i + 1``
    (mirrored at the edges); they are gathered as whole even-aligned pairs, so that in the
    gathered mosaic every kept output has its full-frame neighbours, the parity of every sample is
    its full-frame parity, and a kept output at the frame's edge is at the gathered mosaic's edge.
    """
    superpixel = method == 'superpixel'
    n_out = n_samples // 2 if superpixel else n_samples
    first, step = (start + 0.5, 2.0) if superpixel else (float(start), 1.0)
    u = (np.asarray(wanted, dtype=float) - first) / step
    out = np.unique(
        np.clip(np.concatenate([np.floor(u), np.ceil(u)]), 0, n_out - 1).astype(np.int64)
    )
    coords = first + step * out
    if superpixel:
        return (2 * out[:, None] + np.arange(2)).reshape(-1), None, coords
    pairs = np.unique(np.clip(np.concatenate([out - 1, out, out + 1]), 0, n_samples - 1) // 2)
    samples = (2 * pairs[:, None] + np.arange(2)).reshape(-1)
    samples = samples[samples < n_samples]
    return samples, np.searchsorted(samples, out), coords


def _wanted_axes(selection: PixelSelection, camera: CameraModel):
    """Return the sorted distinct sensor columns and rows of a ``list`` or ``grid`` selection."""
    px = select_pixels(camera, selection)
    return np.unique(px.x_px), np.unique(px.y_px)


@lru_cache(maxsize=16)
def _sparse_plan(
    camera: CameraModel, selection: PixelSelection, x0: int, y0: int, H: int, W: int, method: str
):
    """
    Plan the sparse demosaic of a ``list``/``grid`` selection (cached per camera and mosaic).

    (rows, cols: sample indices to gather; pick: (row, column) indices of the kept outputs in the
    demosaic of the gathered samples, or None for all; x_px, y_px, rays, has_ray of the kept
    outputs' grid). See :func:`_sparse_axis`.
    """
    xs, ys = _wanted_axes(selection, camera)
    cols, pick_c, gx = _sparse_axis(xs, x0, W, method)
    rows, pick_r, gy = _sparse_axis(ys, y0, H, method)
    xg, yg = np.meshgrid(gx, gy)
    rays, ok = camera.rays_from_pixels(xg, yg)
    pick = None if pick_r is None else np.ix_(pick_r, pick_c)
    out = (
        rows,
        cols,
        pick,
        xg,
        yg,
        np.ascontiguousarray(rays.astype(np.float32)),
        ok.reshape(xg.shape),
    )
    for a in (rows, cols, xg, yg, out[5], out[6]):
        a.setflags(write=False)
    return out


def _gather(m: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """
    Copy the samples ``rows`` x ``cols`` of mosaic ``m`` into one contiguous mosaic.

    ``cols`` come in even-aligned pairs (except perhaps a last odd column): each pair is copied as
    one wide element when the dtype allows.
    """
    pair = _PAIR.get(m.dtype.itemsize)
    W = m.shape[1]
    if pair is not None and W % 2 == 0 and cols.size % 2 == 0 and m.flags.c_contiguous:
        wide = m.view(pair)  # (H, W // 2)
        return np.ascontiguousarray(wide[np.ix_(rows, cols[0::2] // 2)]).view(m.dtype)
    return np.ascontiguousarray(m[np.ix_(rows, cols)])


_PAIR = {
    1: np.uint16,
    2: np.uint32,
    4: np.uint64,
    8: np.complex128,
}  # a dtype as wide as two samples


def _superpixel_blocks(m: np.ndarray, rows: np.ndarray, cols: np.ndarray, k: int) -> np.ndarray:
    """
    Copy the wanted 2 x 2 blocks of mosaic ``m`` into one contiguous mosaic.

    The 2 x 2 blocks ``rows[0]::k`` x ``cols[0]::k`` (block indices) of mosaic ``m`` as one
    contiguous mosaic. Each horizontal sample pair is copied as one wide element: numpy's strided
    copy with an inner axis of 2 samples cost 4.8 ms for a stride-4 selection of a 2448 x 2048
    frame, 0.27 ms this way.
    """
    H, W = m.shape
    r = slice(int(rows[0]), int(rows[-1]) + 1, k)
    c = slice(int(cols[0]), int(cols[-1]) + 1, k)
    even = m[: 2 * (H // 2), : 2 * (W // 2)]
    pair = _PAIR.get(m.dtype.itemsize)
    if k > 1 and pair is not None and even.flags.c_contiguous:
        pairs = even.view(pair).reshape(H // 2, 2, W // 2)
        return (
            np.ascontiguousarray(pairs[r, :, c])
            .view(m.dtype)
            .reshape(2 * rows.size, 2 * cols.size)
        )
    blocks = even.reshape(H // 2, 2, W // 2, 2)
    return np.ascontiguousarray(blocks[r, :, c, :]).reshape(2 * rows.size, 2 * cols.size)


def observation_from_mosaic(
    mosaic,
    camera: CameraModel,
    sun_azimuth_deg: float,
    sun_altitude_deg: float,
    *,
    origin_px=(1, 1),
    method: str = 'superpixel',
    layout=IMX250MZR_LAYOUT,
    pol45_toward: str = IMX250MZR_POL45,
    saturation_level=None,
    selection: PixelSelection | None = None,
    with_intensity: bool = False,
    pitch_deg=None,
    roll_deg=None,
    prior_bearing_deg=None,
    ifov_k: float = IFOV_K_DEFAULT,
) -> Observation:
    """
    Demosaic the pixels a selection needs from a raw mosaic into an :class:`Observation`.

    ``layout`` is the full sensor's (pixel (1, 1) first), so the mosaic's top-left polarizer is
    ``layout[(y-1) % 2][(x-1) % 2]`` for ``origin_px = (x, y)``. Grid and list selections are
    demosaiced sparsely: the full-frame demosaic's outputs nearest each wanted column and row, on a
    grid that is not evenly spaced (see the module docstring); each value equals the full-frame
    demosaic's at that pixel.

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw DoFP image (uint8, uint16 or float), 2-D, at least 2 x 2.
    camera : CameraModel
        The camera whose sensor the mosaic is (part of).
    sun_azimuth_deg : float
        Sun azimuth [deg], clockwise from North.
    sun_altitude_deg : float
        Sun altitude [deg].
    origin_px : tuple of int, default (1, 1)
        1-based sensor (x, y) of the mosaic's top-left sample (eq 20 coordinates).
    method : {"superpixel", "bilinear"}, default "superpixel"
        Demosaicing.
    layout : str or sequence, default IMX250MZR_LAYOUT
        The sensor's 2 x 2 polarizer angles [deg]
        (:func:`~polarization_compass.mosaic.parse_layout`).
    pol45_toward : str, default "+x+y"
        Image direction of the 45 deg polarizer.
    saturation_level : float, optional
        Samples at or above this are saturated; default the dtype's maximum.
    selection : PixelSelection, optional
        The pixels the estimator reads (its ``pixels_needed``); all by default.
    with_intensity : bool, default False
        Also return S0 as the intensity (costs the Stokes path instead of the fused AoP kernel).
    pitch_deg, roll_deg : float, optional
        Known camera pitch and roll [deg] (eq 21).
    prior_bearing_deg : float, optional
        Prior bearing of camera +y [deg, clockwise from North].
    ifov_k : float, default IFOV_K_DEFAULT (4)
        IFOV check (:mod:`polarization_compass.demosaic`, "IFOV check"): a pixel whose DoFP
        redundancy ``(I0 + I90) - (I45 + I135)`` exceeds ``ifov_k`` noise sigmas is invalid; the
        noise is estimated once from the whole mosaic (:func:`~polarization_compass.demosaic.
        redundancy_noise`), so every selection judges a pixel as the full frame does. 0 = off.

    Returns
    -------
    Observation
        AoP [rad, eq 28], DoP, valid mask, pixel coordinates, unit rays (camera frame) and the sun,
        tilt and prior.

    Raises
    ------
    MosaicInputError
        A mosaic that is not 2-D or does not fit the camera, wanted pixels outside it or holding no
        complete superpixel, an unknown demosaic method or a bad ``ifov_k``.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 20 and 28.

    """
    m, x0, y0 = _placed_mosaic(mosaic, camera, origin_px)
    lay = parse_layout(layout, pol45_toward).shifted(
        (y0 - 1) % 2, (x0 - 1) % 2
    )  # the mosaic's own phase
    if method not in ('superpixel', 'bilinear'):
        raise MosaicInputError(f'demosaic method must be superpixel or bilinear, got {method!r}')
    check = _ifov_check(m, lay, method, saturation_level, ifov_k)
    how = (method, saturation_level, with_intensity, check)  # the arguments of _demosaic
    if selection is not None and selection.mode in ('list', 'grid'):
        planes, xg, yg, rays, has_ray = _sparse_planes(m, camera, selection, x0, y0, lay, how)
    else:
        rect = _wanted_rect(selection, x0, y0, *m.shape)
        if method == 'superpixel':
            planes, gx, gy = _superpixel_planes(m, x0, y0, rect, lay, how)
        else:
            planes, gx, gy = _bilinear_planes(m, x0, y0, rect, lay, how)
        xg, yg, rays, has_ray = _grid_rays(camera, gx, gy)
    return _observation(
        planes,
        xg,
        yg,
        rays,
        has_ray,
        camera,
        sun_azimuth_deg,
        sun_altitude_deg,
        pitch_deg,
        roll_deg,
        prior_bearing_deg,
    )


def _placed_mosaic(mosaic, camera: CameraModel, origin_px):
    """Return the mosaic as an array and its 1-based sensor origin (x0, y0), checked to fit."""
    m = np.asarray(mosaic)
    if m.ndim != 2 or m.shape[0] < 2 or m.shape[1] < 2:
        raise MosaicInputError(
            f'a mosaic must be a 2-D image of at least 2 x 2 pixels, got shape {m.shape}'
        )
    x0, y0 = int(origin_px[0]), int(origin_px[1])
    H, W = m.shape
    if x0 < 1 or y0 < 1 or x0 + W - 1 > camera.width_px or y0 + H - 1 > camera.height_px:
        raise MosaicInputError(
            f'a {W} x {H} mosaic at ({x0}, {y0}) does not fit the {camera.width_px} x '
            f'{camera.height_px} camera'
        )
    return m, x0, y0


def _ifov_check(m, lay, method: str, saturation_level, ifov_k):
    """
    Return the IFOV check (ifov_k, the whole frame's redundancy noise or None) of a mosaic.

    One noise model for the whole frame, whatever part of it is demosaiced.
    """
    try:
        ifov_k = check_ifov_k(ifov_k)
        noise = (
            redundancy_noise(m, lay, lay.pol45_toward, method, saturation_level)
            if ifov_k > 0.0
            else None
        )
    except SensorError as exc:
        raise MosaicInputError(str(exc)) from None
    return ifov_k, noise


def _sparse_planes(m, camera: CameraModel, selection: PixelSelection, x0, y0, lay, how):
    """
    Demosaic the outputs nearest a grid or list selection's pixels (module doc).

    Returns (planes, x, y, rays, has_ray) for :func:`_observation`; ``how``: the arguments of
    :func:`_demosaic` after the layout.
    """
    H, W = m.shape
    try:
        rows, cols, pick, xg, yg, rays, has_ray = _sparse_plan(
            camera, selection, x0, y0, H, W, how[0]
        )
    except CameraError as exc:
        raise MosaicInputError(f'the pixels wanted: {exc}') from None
    out = _demosaic(_gather(m, rows, cols), lay, *how)
    if pick is not None:
        out = tuple(None if a is None else a[pick] for a in out)
    return out, xg, yg, rays, has_ray


def _superpixel_planes(m, x0, y0, rect, lay, how):
    """
    Superpixel-demosaic the whole 2 x 2 blocks inside the wanted rectangle, strided.

    ``rect``: :func:`_wanted_rect`. Returns (planes, x grid key, y grid key); ``how``: the
    arguments of :func:`_demosaic` after the layout.
    """
    xl, yl, xh, yh, stride = rect
    # whole blocks of the mosaic's own 2 x 2 lattice inside the wanted rectangle
    bx0 = math.ceil((xl - x0) / 2)
    by0 = math.ceil((yl - y0) / 2)
    bx1 = (xh - x0 + 1) // 2  # exclusive
    by1 = (yh - y0 + 1) // 2
    if bx1 <= bx0 or by1 <= by0:
        raise MosaicInputError('the pixels wanted hold no complete 2 x 2 superpixel')
    k = max(1, stride // 2)
    cols = bx0 + _centred(bx1 - bx0, k)
    rows = by0 + _centred(by1 - by0, k)
    sub = _superpixel_blocks(m, rows, cols, k)
    gx = (x0 + 2.0 * cols[0] + 0.5, 2.0 * k, int(cols.size))
    gy = (y0 + 2.0 * rows[0] + 0.5, 2.0 * k, int(rows.size))
    return _demosaic(sub, lay, *how), gx, gy  # block-aligned: same phase as the mosaic


def _bilinear_planes(m, x0, y0, rect, lay, how):
    """
    Bilinear-demosaic the wanted rectangle (with a margin), then keep every ``stride``-th pixel.

    ``rect``: :func:`_wanted_rect`. Returns (planes, x grid key, y grid key); ``how``: the
    arguments of :func:`_demosaic` after the layout.
    """
    xl, yl, xh, yh, stride = rect
    H, W = m.shape
    margin = 2
    cx0 = max(x0, xl - margin)
    cy0 = max(y0, yl - margin)
    cx1 = min(x0 + W - 1, xh + margin)
    cy1 = min(y0 + H - 1, yh + margin)
    sub = m[cy0 - y0 : cy1 - y0 + 1, cx0 - x0 : cx1 - x0 + 1]
    lay_sub = lay.shifted((cy0 - y0) % 2, (cx0 - x0) % 2)
    aop, dop, valid, inten = _demosaic(sub, lay_sub, *how)
    ys = np.arange(cy0, cy1 + 1)
    xs = np.arange(cx0, cx1 + 1)
    ri = np.nonzero((ys >= yl) & (ys <= yh))[0]
    ci = np.nonzero((xs >= xl) & (xs <= xh))[0]
    ri = ri[_centred(ri.size, stride)]
    ci = ci[_centred(ci.size, stride)]
    sl = (slice(ri[0], ri[-1] + 1, stride), slice(ci[0], ci[-1] + 1, stride))
    aop, dop, valid = aop[sl], dop[sl], valid[sl]
    inten = None if inten is None else inten[sl]
    gx = (float(xs[ci[0]]), float(stride), int(ci.size))
    gy = (float(ys[ri[0]]), float(stride), int(ri.size))
    return (aop, dop, valid, inten), gx, gy


def _demosaic(sub, lay, method, saturation_level, with_intensity, check):
    """
    Demosaic a (sub-)mosaic whose top-left sample has the polarizer phase of ``lay``.

    (aop, dop, valid, intensity or None) by :mod:`polarization_compass.demosaic`; ``check``:
    (ifov_k, the whole frame's redundancy noise).
    """
    if with_intensity:
        s0, s1, s2 = stokes_from_mosaic(
            sub, lay, lay.pol45_toward, method, saturation_level, *check
        )
        aop, dop, valid = aop_dop_from_stokes(s0, s1, s2)
        return aop, dop, valid, s0
    aop, dop, valid = polarization_from_mosaic(
        sub, lay, lay.pol45_toward, method, saturation_level, *check
    )
    return aop, dop, valid, None


def _observation(
    planes, xg, yg, rays, has_ray, camera, sun_az, sun_alt, pitch_deg, roll_deg, prior_bearing_deg
) -> Observation:
    """Return the :class:`Observation` of demosaiced planes on the grid ``xg``, ``yg``."""
    aop, dop, valid, inten = planes
    return Observation(
        np.ascontiguousarray(aop),
        np.ascontiguousarray(dop),
        np.ascontiguousarray(valid) & has_ray,
        rays,
        xg,
        yg,
        camera,
        float(sun_az),
        float(sun_alt),
        None if inten is None else np.ascontiguousarray(inten),
        pitch_deg,
        roll_deg,
        prior_bearing_deg,
    )
