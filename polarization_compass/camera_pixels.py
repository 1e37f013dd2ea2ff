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
Pixel selections: which pixels of a camera a consumer wants, and their coordinates and rays.

:class:`PixelSelection` names the pixels (all, strided, a region, a grid or a list);
:func:`select_pixels` turns a (camera, selection) into 1-based coordinates (eq 20) and unit rays in
the camera optical frame, cached and read-only (:class:`SelectedPixels`). The camera models are in
:mod:`.camera`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import hashlib

import numpy as np

from .camera import CameraError, CameraModel


@dataclass(frozen=True)
class PixelSelection:
    """
    Which pixels a consumer wants rendered.

    ``mode``: ``full`` | ``stride`` (every ``stride``-th row and column, centred) | ``region``
    (a rectangle ``x0, y0, width, height`` in 1-based pixels, optionally strided) | ``grid``
    (``nx`` x ``ny`` evenly spread pixels) | ``list`` (explicit 1-based ``x_px``/``y_px``).
    """

    mode: str = 'full'
    stride: int = 1
    region: tuple[int, int, int, int] | None = None  # x0, y0, width, height (1-based x0, y0)
    nx: int = 0
    ny: int = 0
    x_list: bytes = b''  # int32 bytes of explicit columns (hashable)
    y_list: bytes = b''
    _digest: str = field(default='', compare=False)

    @staticmethod
    def full() -> 'PixelSelection':
        """
        Select every pixel.

        Returns
        -------
        PixelSelection
            Mode ``full``.

        """
        return PixelSelection('full')

    @staticmethod
    def strided(stride: int) -> 'PixelSelection':
        """
        Select every ``stride``-th row and column, centred on the image.

        Parameters
        ----------
        stride : int
            Step [px].

        Returns
        -------
        PixelSelection
            Mode ``stride``.

        """
        return PixelSelection('stride', stride=int(stride))

    @staticmethod
    def grid(nx: int, ny: int) -> 'PixelSelection':
        """
        Select ``nx`` x ``ny`` evenly spread pixels (centres of equal blocks).

        Parameters
        ----------
        nx, ny : int
            Number of columns and rows.

        Returns
        -------
        PixelSelection
            Mode ``grid``.

        """
        return PixelSelection('grid', nx=int(nx), ny=int(ny))

    @staticmethod
    def rect(x0: int, y0: int, width: int, height: int, stride: int = 1) -> 'PixelSelection':
        """
        Select a rectangle of pixels, optionally strided.

        Parameters
        ----------
        x0, y0 : int
            1-based column and row of its first pixel.
        width, height : int
            Size [px].
        stride : int, default 1
            Step [px] within it, centred.

        Returns
        -------
        PixelSelection
            Mode ``region``.

        """
        return PixelSelection(
            'region', stride=int(stride), region=(int(x0), int(y0), int(width), int(height))
        )

    @staticmethod
    def explicit(x_px, y_px) -> 'PixelSelection':
        """
        Select an explicit list of pixels.

        Parameters
        ----------
        x_px, y_px : array_like of int
            1-based columns and rows, the same length.

        Returns
        -------
        PixelSelection
            Mode ``list`` (hashable: the coordinates are stored as bytes with their digest).

        Raises
        ------
        CameraError
            ``x_px`` and ``y_px`` differ in length.

        """
        x = np.asarray(x_px, dtype=np.int32).reshape(-1)
        y = np.asarray(y_px, dtype=np.int32).reshape(-1)
        if x.shape != y.shape:
            raise CameraError('x_px and y_px must have the same length')
        return PixelSelection(
            'list',
            x_list=x.tobytes(),
            y_list=y.tobytes(),
            _digest=hashlib.sha1(x.tobytes() + y.tobytes()).hexdigest(),
        )

    def describe(self) -> str:
        """
        Describe the selection in a few words (logs, tables).

        Returns
        -------
        str
            E.g. ``"stride 8"`` or ``"grid 96x80"``.

        """
        if self.mode == 'full':
            return 'full'
        if self.mode == 'stride':
            return f'stride {self.stride}'
        if self.mode == 'grid':
            return f'grid {self.nx}x{self.ny}'
        if self.mode == 'region':
            return f'region {self.region} stride {self.stride}'
        return f'list of {len(self.x_list) // 4} pixels'


def _centred_axis(n_pixels: int, stride: int) -> np.ndarray:
    """1-based indices every ``stride`` pixels, placed symmetrically about the centre."""
    count = (n_pixels - 1) // stride + 1
    span = (count - 1) * stride
    start = 1 + (n_pixels - 1 - span) // 2
    return start + stride * np.arange(count)


@dataclass(frozen=True)
class SelectedPixels:
    """
    Pixel coordinates and unit rays for a (camera, selection). Arrays are read-only (cached).

    ``shape`` is the output image shape (2-D for full/stride/region/grid, 1-D for a list);
    ``x_px``/``y_px`` are float64 1-based coordinates of that shape; ``rays_cam`` is (3, N)
    float32; ``has_ray`` is False for fisheye pixels outside the lens' field.
    """

    shape: tuple
    x_px: np.ndarray
    y_px: np.ndarray
    rays_cam: np.ndarray
    has_ray: np.ndarray

    @property
    def count(self) -> int:
        """Return the number of selected pixels."""
        return int(self.x_px.size)


@lru_cache(maxsize=32)
def select_pixels(
    camera: CameraModel, selection: PixelSelection = PixelSelection()
) -> SelectedPixels:
    """
    Compute the coordinates and rays of the selected pixels, once per (camera, selection).

    The result is cached and its arrays are read-only.

    Parameters
    ----------
    camera : CameraModel
        The camera.
    selection : PixelSelection, default all pixels
        Which pixels.

    Returns
    -------
    SelectedPixels
        Output shape (2-D, or 1-D for a list), 1-based ``x_px``/``y_px`` [px] (eq 20), unit rays
        (3, N) float32 in the camera frame, and ``has_ray``.

    Raises
    ------
    CameraError
        A stride, grid, region or list outside the image, an empty list, or an unknown mode.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 20.

    """
    W, H = int(camera.width_px), int(camera.height_px)
    m = selection.mode
    if m == 'full':
        xs, ys = np.arange(1, W + 1), np.arange(1, H + 1)
    elif m == 'stride':
        if not (1 <= selection.stride <= min(W, H)):
            raise CameraError(f'stride must be in [1, {min(W, H)}], got {selection.stride}')
        xs, ys = _centred_axis(W, selection.stride), _centred_axis(H, selection.stride)
    elif m == 'grid':
        if not (1 <= selection.nx <= W and 1 <= selection.ny <= H):
            raise CameraError(
                f'grid must be between 1x1 and {W}x{H}, got {selection.nx}x{selection.ny}'
            )
        # centres of nx x ny equal blocks, rounded to the nearest pixel
        xs = np.rint(0.5 + (np.arange(selection.nx) + 0.5) * W / selection.nx).astype(int)
        ys = np.rint(0.5 + (np.arange(selection.ny) + 0.5) * H / selection.ny).astype(int)
    elif m == 'region':
        x0, y0, w, h = selection.region
        if not (1 <= x0 and 1 <= y0 and w >= 1 and h >= 1 and x0 + w - 1 <= W and y0 + h - 1 <= H):
            raise CameraError(f'region {selection.region} is not inside the {W}x{H} image')
        s = max(1, selection.stride)
        xs = x0 - 1 + _centred_axis(w, s)
        ys = y0 - 1 + _centred_axis(h, s)
    elif m == 'list':
        x = np.frombuffer(selection.x_list, dtype=np.int32)
        y = np.frombuffer(selection.y_list, dtype=np.int32)
        if x.size == 0:
            raise CameraError('explicit pixel list is empty')
        if x.min() < 1 or y.min() < 1 or x.max() > W or y.max() > H:
            raise CameraError(f'explicit pixels must lie in [1, {W}] x [1, {H}]')
        xg, yg = x.astype(float), y.astype(float)
        rays, ok = camera.rays_from_pixels(xg, yg)
        return _freeze(SelectedPixels((x.size,), xg, yg, rays.astype(np.float32), ok))
    else:
        raise CameraError(f'pixel selection mode must be full|stride|region|grid|list, got {m!r}')
    xg, yg = np.meshgrid(xs.astype(float), ys.astype(float))
    rays, ok = camera.rays_from_pixels(xg, yg)
    shape = xg.shape
    return _freeze(
        SelectedPixels(
            shape, xg, yg, np.ascontiguousarray(rays.astype(np.float32)), ok.reshape(shape)
        )
    )


def _freeze(p: SelectedPixels) -> SelectedPixels:
    for a in (p.x_px, p.y_px, p.rays_cam, p.has_ray):
        a.setflags(write=False)
    return p
