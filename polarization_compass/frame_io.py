"""Frame files (``.npz``) written by ``polarization-compass render`` and read by ``estimate``.

Contents (all plain arrays; loading never unpickles: ``allow_pickle=False``):

``aop_rad``   float32, eq 28 convention, folded to [-pi/2, pi/2)
``dop``       float32 in [0, 1]
``valid``     bool
``x_px``      float64, 1-based column of each pixel (eq 20), same shape as ``aop_rad``
``y_px``      float64, 1-based row
``meta``      0-d unicode array holding a JSON object: sun azimuth/altitude and how they were obtained
              (``sun_source`` ephemeris/scene/given, ``sun_fixed``; ``time_utc`` only for an ephemeris sun),
              attitude, camera, effects and sensor parameters
optional: ``intensity`` (float32), ``mosaic`` (uint8/uint16 raw DoFP image), ``aop_ideal_rad``, ``dop_ideal``
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .camera import CameraModel
from .errors import CompassError
from .safe_load import open_npz

__all__ = ["save_frame_npz", "load_frame_npz", "FrameFile", "FrameFileError"]

REQUIRED = ("aop_rad", "dop", "valid", "x_px", "y_px", "meta")
OPTIONAL = ("intensity", "mosaic", "aop_ideal_rad", "dop_ideal")


class FrameFileError(CompassError):
    """A frame file that is missing, corrupt or inconsistent."""


@dataclass
class FrameFile:
    """Hold the arrays of a frame file (see the module docstring for their meaning).

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
        cam = self.meta.get("camera") or {}
        try:
            return CameraModel(**cam)
        except (TypeError, ValueError) as exc:
            raise FrameFileError(f"frame meta has an unusable camera description: {exc}") from None

    def rays_cam(self) -> np.ndarray:
        """Compute the unit viewing rays of the stored pixels from the stored camera model.

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
    """Write a rendered frame as a compressed ``.npz`` frame file.

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
    if p.suffix != ".npz":
        raise FrameFileError(f"frame files end in .npz, got {p.name!r}")
    arrays = {"aop_rad": frame.aop_rad, "dop": frame.dop, "valid": frame.valid,
              "x_px": np.asarray(frame.x_px), "y_px": np.asarray(frame.y_px),
              "meta": np.array(json.dumps(frame.meta, sort_keys=True, default=str))}
    for k in OPTIONAL:
        v = getattr(frame, k, None)
        if v is not None:
            arrays[k] = v
    if p.parent and not p.parent.exists():
        p.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(p, **arrays)
    return p


def load_frame_npz(path) -> FrameFile:
    """Read and validate a frame file (never unpickles).

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
    with open_npz(p, FrameFileError, "frame file") as z:
        missing = [k for k in REQUIRED if k not in z.files]
        if missing:
            raise FrameFileError(f"{p.name}: missing array(s) {missing}; is it a 'render' output?")
        data = {k: z[k] for k in z.files if k in REQUIRED + OPTIONAL}
    try:
        meta = json.loads(str(data.pop("meta")))
        if not isinstance(meta, dict):
            raise ValueError("not an object")
    except (ValueError, TypeError) as exc:
        raise FrameFileError(f"{p.name}: meta is not a JSON object ({exc})") from None
    shape = data["aop_rad"].shape
    for k in ("dop", "valid", "x_px", "y_px"):
        if data[k].shape != shape:
            raise FrameFileError(f"{p.name}: {k} has shape {data[k].shape}, aop_rad has {shape}")
    if data["valid"].dtype != np.bool_:
        raise FrameFileError(f"{p.name}: valid must be bool, got {data['valid'].dtype}")
    for k in ("aop_rad", "dop"):
        if not np.issubdtype(data[k].dtype, np.floating):
            raise FrameFileError(f"{p.name}: {k} must be floating point, got {data[k].dtype}")
        bad = ~np.isfinite(data[k]) & data["valid"]
        if bad.any():
            raise FrameFileError(f"{p.name}: {int(bad.sum())} valid pixel(s) have non-finite {k}")
    for k in ("x_px", "y_px"):
        if not np.issubdtype(data[k].dtype, np.number) or not np.all(np.isfinite(data[k])):
            raise FrameFileError(f"{p.name}: {k} must hold finite pixel coordinates")
    d = data["dop"][data["valid"]]
    if d.size and (d.min() < 0.0 or d.max() > 1.0):
        raise FrameFileError(f"{p.name}: dop must lie in [0, 1] at valid pixels, found [{d.min():.3g}, {d.max():.3g}]")
    return FrameFile(meta=meta, **data)
