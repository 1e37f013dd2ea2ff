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
Frame files (``.npz``) written by ``polarization-compass render`` and read by ``estimate``.

Contents (all plain arrays; loading never unpickles: ``allow_pickle=False``):

``aop_rad``   float32, eq 28 convention, folded to [-pi/2, pi/2)
``dop``       float32 in [0, 1]
``valid``     bool
``x_px``      float64, 1-based column of each pixel (eq 20), same shape as ``aop_rad``
``y_px``      float64, 1-based row
``meta``      0-d unicode array holding a JSON object: sun azimuth/altitude and how they were
              obtained (``sun_source`` ephemeris/scene/given, ``sun_fixed``; ``time_utc`` only for
              an ephemeris sun), attitude, camera, effects and sensor parameters
optional: ``intensity`` (float32), ``mosaic`` (uint8/uint16 raw DoFP image), ``aop_ideal_rad``,
``dop_ideal``
"""

from __future__ import annotations

from dataclasses import dataclass
import json
import math
from pathlib import Path

import numpy as np

from .camera import CameraModel
from .errors import CompassError
from .safe_load import load_json, open_npz

__all__ = ['save_frame_npz', 'load_frame_npz', 'FrameFile', 'FrameFileError', 'MAX_FRAME_PIXELS']

REQUIRED = ('aop_rad', 'dop', 'valid', 'x_px', 'y_px', 'meta')
OPTIONAL = ('intensity', 'mosaic', 'aop_ideal_rad', 'dop_ideal')
#: Largest frame read: 2^25 pixels (e.g. 8192 x 4096; the paper's sensor has 5.0e6), its mosaic 4x
#: that.
MAX_FRAME_PIXELS = 1 << 25
#: Largest meta JSON text: 1 MiB (a real one is about 2 kB).
MAX_META_CHARS = 1 << 20


class FrameFileError(CompassError):
    """A frame file that is missing, corrupt or inconsistent."""


@dataclass
class FrameFile:
    """
    Hold the arrays of a frame file (see the module docstring for their meaning).

    Parameters
    ----------
    aop_rad : numpy.ndarray
        AoP [rad], eq 28 convention, folded to [-pi/2, pi/2).
    dop : numpy.ndarray
        Degree of polarization in [0, 1], same shape.
    valid : numpy.ndarray
        bool, same shape.
    x_px, y_px : numpy.ndarray
        1-based column and row of each pixel (eq 20), same shape.
    meta : dict
        Sun, attitude, camera, effects and sensor parameters.
    intensity, mosaic, aop_ideal_rad, dop_ideal : numpy.ndarray, optional
        Intensity, the raw DoFP mosaic, and the noise-free AoP [rad] and DoP.

    """

    aop_rad: np.ndarray
    dop: np.ndarray
    valid: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    meta: dict
    intensity: np.ndarray | None = None
    mosaic: np.ndarray | None = None
    aop_ideal_rad: np.ndarray | None = None
    dop_ideal: np.ndarray | None = None

    @property
    def camera(self) -> CameraModel:
        """Return the stored :class:`CameraModel` (:class:`FrameFileError` when unusable)."""
        cam = self.meta.get('camera') or {}
        try:
            return CameraModel(**cam)
        except (TypeError, ValueError) as exc:
            raise FrameFileError(f'frame meta has an unusable camera description: {exc}') from None

    def rays_cam(self) -> np.ndarray:
        """
        Compute the unit viewing rays of the stored pixels from the stored camera model.

        Returns
        -------
        numpy.ndarray
            float32, shape (3, N), camera frame (x right, y down, z the optical axis; eq 20), in
            the order of ``aop_rad.reshape(-1)``.

        Raises
        ------
        FrameFileError
            The stored camera description is unusable.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eq 20.

        """
        rays, _ = self.camera.rays_from_pixels(self.x_px, self.y_px)
        return rays.astype(np.float32)


def save_frame_npz(path, frame) -> Path:
    """
    Write a rendered frame as a compressed ``.npz`` frame file.

    Parameters
    ----------
    path : str or os.PathLike
        Destination, ending in ``.npz``; parent directories are created.
    frame : polarization_compass.render.Frame
        The frame (AoP [rad], DoP, valid mask, pixel coordinates, meta and optional arrays).

    Returns
    -------
    pathlib.Path
        The written path.

    Raises
    ------
    FrameFileError
        ``path`` does not end in ``.npz``.

    """
    p = Path(path)
    if p.suffix != '.npz':
        raise FrameFileError(f'frame files end in .npz, got {p.name!r}')
    arrays = {
        'aop_rad': frame.aop_rad,
        'dop': frame.dop,
        'valid': frame.valid,
        'x_px': np.asarray(frame.x_px),
        'y_px': np.asarray(frame.y_px),
        'meta': np.array(json.dumps(frame.meta, sort_keys=True, default=str)),
    }
    for k in OPTIONAL:
        v = getattr(frame, k, None)
        if v is not None:
            arrays[k] = v
    if p.parent and not p.parent.exists():
        p.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(p, **arrays)
    return p


def _check_declared_shapes(name: str, headers: dict) -> None:
    """
    Check the shapes a frame file declares before anything is decompressed.

    The required arrays must be present, the per-pixel arrays of one 2-D (or 1-D pixel list) shape
    of at most :data:`MAX_FRAME_PIXELS`, the mosaic at most 4x that, meta a 0-d string of at most
    :data:`MAX_META_CHARS`.
    """
    missing = [k for k in REQUIRED if k not in headers]
    if missing:
        raise FrameFileError(f"{name}: missing array(s) {missing}; is it a 'render' output?")
    shape = headers['aop_rad'].shape
    n = math.prod(shape)
    if len(shape) not in (1, 2) or n > MAX_FRAME_PIXELS:
        raise FrameFileError(
            f'{name}: aop_rad declares shape {shape}; a frame is a 1-D or 2-D array of at most '
            f'{MAX_FRAME_PIXELS} pixels (refused before decompressing)'
        )
    for k in ('dop', 'valid', 'x_px', 'y_px', 'intensity', 'aop_ideal_rad', 'dop_ideal'):
        if k in headers and headers[k].shape != shape:
            raise FrameFileError(f'{name}: {k} has shape {headers[k].shape}, aop_rad has {shape}')
    if 'mosaic' in headers:
        ms = headers['mosaic'].shape
        if len(ms) != 2 or math.prod(ms) > 4 * MAX_FRAME_PIXELS:
            raise FrameFileError(
                f'{name}: mosaic declares shape {ms}; at most {4 * MAX_FRAME_PIXELS} pixels '
                'in 2-D (refused before decompressing)'
            )
    m = headers['meta']
    if m.shape != () or m.dtype.kind != 'U' or m.dtype.itemsize // 4 > MAX_META_CHARS:
        raise FrameFileError(
            f'{name}: meta must be one JSON string of at most {MAX_META_CHARS} characters, '
            f'got {m.dtype} of shape {m.shape}'
        )


def load_frame_npz(path) -> FrameFile:
    """
    Read and validate a frame file (never unpickles).

    The declared shapes are checked before any array is decompressed
    (:func:`_check_declared_shapes`).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.npz`` written by :func:`save_frame_npz`.

    Returns
    -------
    FrameFile
        The arrays and the meta dict.

    Raises
    ------
    FrameFileError
        The file is missing or corrupt, lacks an array, has inconsistent shapes or dtypes,
        non-finite AoP/DoP at valid pixels, DoP outside [0, 1], or meta that is not a JSON object.

    """
    p = Path(path)
    with open_npz(
        p, FrameFileError, 'frame file', check=lambda h: _check_declared_shapes(p.name, h)
    ) as z:
        data = {k: z[k] for k in z.files if k in REQUIRED + OPTIONAL}
    meta = load_json(str(data.pop('meta')), f'{p.name}: meta', FrameFileError)
    if not isinstance(meta, dict):
        raise FrameFileError(f'{p.name}: meta is not a JSON object')
    shape = data['aop_rad'].shape
    for k in ('dop', 'valid', 'x_px', 'y_px'):
        if data[k].shape != shape:
            raise FrameFileError(f'{p.name}: {k} has shape {data[k].shape}, aop_rad has {shape}')
    if data['valid'].dtype != np.bool_:
        raise FrameFileError(f'{p.name}: valid must be bool, got {data["valid"].dtype}')
    for k in ('aop_rad', 'dop'):
        if not np.issubdtype(data[k].dtype, np.floating):
            raise FrameFileError(f'{p.name}: {k} must be floating point, got {data[k].dtype}')
        bad = ~np.isfinite(data[k]) & data['valid']
        if bad.any():
            raise FrameFileError(f'{p.name}: {int(bad.sum())} valid pixel(s) have non-finite {k}')
    for k in ('x_px', 'y_px'):
        if not np.issubdtype(data[k].dtype, np.number) or not np.all(np.isfinite(data[k])):
            raise FrameFileError(f'{p.name}: {k} must hold finite pixel coordinates')
    d = data['dop'][data['valid']]
    if d.size and (d.min() < 0.0 or d.max() > 1.0):
        raise FrameFileError(
            f'{p.name}: dop must lie in [0, 1] at valid pixels, found [{d.min():.3g}, '
            f'{d.max():.3g}]'
        )
    return FrameFile(meta=meta, **data)
