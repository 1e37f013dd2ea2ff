"""Camera models and pixel selections; unit viewing rays in the camera optical frame, cached.

Pixel coordinates follow eq 20: ``x_px`` is the 1-based column, ``y_px`` the 1-based row; the
principal point defaults to the image centre ``((eta_x + 1) / 2, (eta_y + 1) / 2)``.

Models
------
``pinhole``              eq 20: ray ~ (Dx (x - cx), Dy (y - cy), f).
``fisheye_equidistant``  r = f * theta (theta the angle from the optical axis); pixels with
                         theta > ``max_field_angle_deg`` have no ray (marked invalid).

Rays are returned as a (3, N) float32 array (structure of arrays, what the render kernels want)
and cached per (camera, selection): a camera that does not change costs nothing per frame.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from functools import lru_cache

from .errors import CompassError

import numpy as np

__all__ = ["CameraModel", "PixelSelection", "SelectedPixels", "select_pixels", "CameraError", "check_intrinsics",
           "MAX_PIXEL_ASPECT_DEVIATION", "MAX_PRINCIPAL_OFFSET_FRACTION"]


class CameraError(CompassError):
    """Invalid camera intrinsics or pixel selection."""


@dataclass(frozen=True)
class CameraModel:
    """Hold camera intrinsics; the defaults are the paper's imager (Table 1).

    Sony IMX250MZR: 2448 x 2048 pixels of 3.45 um, f = 4 mm. Invalid values raise
    :class:`CameraError` on construction.

    Parameters
    ----------
    model : {"pinhole", "fisheye_equidistant"}, default "pinhole"
        Projection: eq 20, or r = f * theta (theta the angle from the optical axis).
    width_px : int, default 2448
        Number of columns eta_x, in [1, 20000].
    height_px : int, default 2048
        Number of rows eta_y, in [1, 20000].
    focal_length_mm : float, default 4
        Focal length f [mm].
    pixel_pitch_x_um, pixel_pitch_y_um : float, default 3.45
        Pixel sizes D_x (columns) and D_y (rows) [um].
    principal_x_px, principal_y_px : float, optional
        Principal point, 1-based pixel coordinates; default the image centre ``(eta + 1) / 2``.
    max_field_angle_deg : float, default 90
        Fisheye only: pixels further from the optical axis [deg] have no ray.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 20 and Table 1.
    """

    model: str = "pinhole"
    width_px: int = 2448            # eta_x, number of columns
    height_px: int = 2048           # eta_y, number of rows
    focal_length_mm: float = 4.0
    pixel_pitch_x_um: float = 3.45  # D_x
    pixel_pitch_y_um: float = 3.45  # D_y
    principal_x_px: float | None = None   # 1-based; None = image centre
    principal_y_px: float | None = None
    max_field_angle_deg: float = 90.0     # fisheye only

    def __post_init__(self):
        if self.model not in ("pinhole", "fisheye_equidistant"):
            raise CameraError(f"camera model must be 'pinhole' or 'fisheye_equidistant', got {self.model!r}")
        for name in ("width_px", "height_px"):
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not (1 <= int(v) <= 20000):
                raise CameraError(f"{name} must be an integer in [1, 20000], got {v!r}")
        for name in ("focal_length_mm", "pixel_pitch_x_um", "pixel_pitch_y_um"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise CameraError(f"{name} must be a positive finite number, got {v!r}")
        for name in ("principal_x_px", "principal_y_px"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)):
                raise CameraError(f"{name} must be a finite number or None, got {v!r}")
        if not (0 < self.max_field_angle_deg <= 180):
            raise CameraError("max_field_angle_deg must be in (0, 180]")

    @property
    def cx_px(self) -> float:
        """Principal point column [px, 1-based]; the image centre by default."""
        return (self.width_px + 1) / 2.0 if self.principal_x_px is None else float(self.principal_x_px)

    @property
    def cy_px(self) -> float:
        """Principal point row [px, 1-based]; the image centre by default."""
        return (self.height_px + 1) / 2.0 if self.principal_y_px is None else float(self.principal_y_px)

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of a full image."""
        return (int(self.height_px), int(self.width_px))

    def field_of_view_deg(self) -> tuple[float, float, float]:
        """Compute the horizontal, vertical and diagonal full field of view.

        Returns
        -------
        tuple of float
            ``(horizontal, vertical, diagonal)`` [deg].
        """
        f = self.focal_length_mm * 1e3
        hw = self.width_px * self.pixel_pitch_x_um / 2
        hh = self.height_px * self.pixel_pitch_y_um / 2
        if self.model == "pinhole":
            fov = lambda r: 2 * math.degrees(math.atan2(r, f))  # noqa: E731
        else:
            fov = lambda r: min(2 * math.degrees(r / f), 2 * self.max_field_angle_deg)  # noqa: E731
        return fov(hw), fov(hh), fov(math.hypot(hw, hh))

    def rays_from_pixels(self, x_px, y_px):
        """Compute unit viewing rays in the camera frame for 1-based pixel coordinates.

        Pinhole: eq 20, ``(D_x (x - c_x), D_y (y - c_y), f)`` normalised; fisheye: r = f * theta.

        Parameters
        ----------
        x_px, y_px : array_like
            1-based column and row [px] (eq 20), any shape (flattened).

        Returns
        -------
        rays : numpy.ndarray
            float64, shape (3, N), camera frame (x along columns, y along rows, z the optical
            axis).
        has_ray : numpy.ndarray
            bool, shape (N,): False for fisheye pixels beyond ``max_field_angle_deg``.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eq 20 and Fig 4.
        """
        x = np.asarray(x_px, dtype=float).reshape(-1)
        y = np.asarray(y_px, dtype=float).reshape(-1)
        u = (x - self.cx_px) * (self.pixel_pitch_x_um * 1e-3)   # mm on the sensor
        v = (y - self.cy_px) * (self.pixel_pitch_y_um * 1e-3)
        f = self.focal_length_mm
        if self.model == "pinhole":
            r = np.stack([u, v, np.full_like(u, f)])
            r /= np.linalg.norm(r, axis=0, keepdims=True)
            ok = np.ones(x.shape, dtype=bool)
        else:
            rho = np.hypot(u, v)
            theta = rho / f
            ok = theta <= math.radians(self.max_field_angle_deg)
            st = np.sin(theta)
            safe = np.where(rho > 0, rho, 1.0)
            r = np.stack([st * u / safe, st * v / safe, np.cos(theta)])
        return r, ok

    def pixels_from_rays(self, rays_cam):
        """Project camera-frame rays back to 1-based pixel coordinates (the inverse of eq 20).

        Used by tests and sparse renders.

        Parameters
        ----------
        rays_cam : array_like
            Rays in the camera frame, shape (3, N) (unit length for the fisheye model).

        Returns
        -------
        x_px : numpy.ndarray
            1-based column [px], shape (N,).
        y_px : numpy.ndarray
            1-based row [px], shape (N,).

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eq 20.
        """
        r = np.asarray(rays_cam, dtype=float)
        f = self.focal_length_mm
        if self.model == "pinhole":
            u = f * r[0] / r[2]
            v = f * r[1] / r[2]
        else:
            theta = np.arctan2(np.hypot(r[0], r[1]), r[2])
            phi = np.arctan2(r[1], r[0])
            u, v = f * theta * np.cos(phi), f * theta * np.sin(phi)
        return (u / (self.pixel_pitch_x_um * 1e-3) + self.cx_px,
                v / (self.pixel_pitch_y_um * 1e-3) + self.cy_px)


#: Largest relative difference of the focal lengths in x and y pixels (|fx / fy - 1|) accepted from a
#: calibration: square-pixel sensors calibrate to within a few 1e-3.
MAX_PIXEL_ASPECT_DEVIATION = 0.05
#: Largest distance of the principal point from the image centre, as a fraction of the width (x) or the
#: height (y): calibrated lenses sit within a few percent; a K from another resolution or binning puts it
#: near a corner (2x: exactly at the far edge).
MAX_PRINCIPAL_OFFSET_FRACTION = 0.25


def check_intrinsics(camera: "CameraModel", image_size: tuple[int, int] | None = None,
                     max_aspect_deviation: float = MAX_PIXEL_ASPECT_DEVIATION,
                     max_principal_offset: float = MAX_PRINCIPAL_OFFSET_FRACTION) -> "CameraModel":
    """Check that calibrated intrinsics (e.g. from a ROS camera_info) are plausible.

    A wrong calibration otherwise gives a confident, wrong heading (issue 18: the principal point at
    the corner of a 612 x 512 image moved a level camera's heading by 24 deg with status ok).

    Parameters
    ----------
    camera : CameraModel
        The intrinsics; fx = f / D_x and fy = f / D_y in pixels, principal point 1-based (eq 20).
    image_size : tuple of int, optional
        (width, height) [px] of the images the camera is used with; must equal the camera's.
    max_aspect_deviation : float, default MAX_PIXEL_ASPECT_DEVIATION
        Largest ``|fx / fy - 1|`` (square pixels calibrate to a few 1e-3).
    max_principal_offset : float, default MAX_PRINCIPAL_OFFSET_FRACTION
        Largest distance of the principal point from the image centre ((eta + 1) / 2, eq 20), as a
        fraction of the width (x) or height (y).

    Returns
    -------
    CameraModel
        ``camera`` itself when plausible.

    Raises
    ------
    CameraError
        The first problem: image size, focal length <= 0, fx/fy, principal point outside the image or
        too far from its centre.
    """
    W, H = int(camera.width_px), int(camera.height_px)
    if image_size is not None and (int(image_size[0]), int(image_size[1])) != (W, H):
        raise CameraError(f"image is {int(image_size[0])}x{int(image_size[1])} but the intrinsics are for {W}x{H}")
    if not camera.focal_length_mm > 0:
        raise CameraError(f"focal length must be positive, got {camera.focal_length_mm!r} mm")
    aspect = camera.pixel_pitch_y_um / camera.pixel_pitch_x_um          # = fx / fy in pixels
    if abs(aspect - 1.0) > max_aspect_deviation:
        raise CameraError(f"fx/fy = {aspect:.4g}: pixels this far from square (more than "
                          f"{max_aspect_deviation:g}) mean a calibration of another camera or mode")
    cx, cy = camera.cx_px, camera.cy_px
    if not (0.5 <= cx <= W + 0.5 and 0.5 <= cy <= H + 0.5):
        raise CameraError(f"principal point ({cx - 1:.6g}, {cy - 1:.6g}) (0-based) is outside the {W}x{H} image")
    dx, dy = abs(cx - (W + 1) / 2.0) / W, abs(cy - (H + 1) / 2.0) / H
    if dx > max_principal_offset or dy > max_principal_offset:
        raise CameraError(f"principal point ({cx - 1:.6g}, {cy - 1:.6g}) (0-based) is {max(dx, dy):.0%} of the "
                          f"image size from the centre of the {W}x{H} image (at most {max_principal_offset:.0%}): "
                          "a calibration from another resolution or binning?")
    return camera


@dataclass(frozen=True)
class PixelSelection:
    """Which pixels a consumer wants rendered.

    ``mode``: ``full`` | ``stride`` (every ``stride``-th row and column, centred) | ``region``
    (a rectangle ``x0, y0, width, height`` in 1-based pixels, optionally strided) | ``grid``
    (``nx`` x ``ny`` evenly spread pixels) | ``list`` (explicit 1-based ``x_px``/``y_px``).
    """

    mode: str = "full"
    stride: int = 1
    region: tuple[int, int, int, int] | None = None   # x0, y0, width, height (1-based x0, y0)
    nx: int = 0
    ny: int = 0
    x_list: bytes = b""            # int32 bytes of explicit columns (hashable)
    y_list: bytes = b""
    _digest: str = field(default="", compare=False)

    @staticmethod
    def full() -> "PixelSelection":
        """Select every pixel.

        Returns
        -------
        PixelSelection
            Mode ``full``.
        """
        return PixelSelection("full")

    @staticmethod
    def strided(stride: int) -> "PixelSelection":
        """Select every ``stride``-th row and column, centred on the image.

        Parameters
        ----------
        stride : int
            Step [px].

        Returns
        -------
        PixelSelection
            Mode ``stride``.
        """
        return PixelSelection("stride", stride=int(stride))

    @staticmethod
    def grid(nx: int, ny: int) -> "PixelSelection":
        """Select ``nx`` x ``ny`` evenly spread pixels (centres of equal blocks).

        Parameters
        ----------
        nx, ny : int
            Number of columns and rows.

        Returns
        -------
        PixelSelection
            Mode ``grid``.
        """
        return PixelSelection("grid", nx=int(nx), ny=int(ny))

    @staticmethod
    def rect(x0: int, y0: int, width: int, height: int, stride: int = 1) -> "PixelSelection":
        """Select a rectangle of pixels, optionally strided.

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
        return PixelSelection("region", stride=int(stride), region=(int(x0), int(y0), int(width), int(height)))

    @staticmethod
    def explicit(x_px, y_px) -> "PixelSelection":
        """Select an explicit list of pixels.

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
            raise CameraError("x_px and y_px must have the same length")
        return PixelSelection("list", x_list=x.tobytes(), y_list=y.tobytes(),
                              _digest=hashlib.sha1(x.tobytes() + y.tobytes()).hexdigest())

    def describe(self) -> str:
        """Describe the selection in a few words (logs, tables).

        Returns
        -------
        str
            E.g. ``"stride 8"`` or ``"grid 96x80"``.
        """
        if self.mode == "full":
            return "full"
        if self.mode == "stride":
            return f"stride {self.stride}"
        if self.mode == "grid":
            return f"grid {self.nx}x{self.ny}"
        if self.mode == "region":
            return f"region {self.region} stride {self.stride}"
        return f"list of {len(self.x_list) // 4} pixels"


def _centred_axis(n_pixels: int, stride: int) -> np.ndarray:
    """1-based indices every ``stride`` pixels, placed symmetrically about the centre."""
    count = (n_pixels - 1) // stride + 1
    span = (count - 1) * stride
    start = 1 + (n_pixels - 1 - span) // 2
    return start + stride * np.arange(count)


@dataclass(frozen=True)
class SelectedPixels:
    """Pixel coordinates and unit rays for a (camera, selection). Arrays are read-only (cached).

    ``shape`` is the output image shape (2-D for full/stride/region/grid, 1-D for a list);
    ``x_px``/``y_px`` are float64 1-based coordinates of that shape; ``rays_cam`` is (3, N) float32;
    ``has_ray`` is False for fisheye pixels outside the lens' field.
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
def select_pixels(camera: CameraModel, selection: PixelSelection = PixelSelection()) -> SelectedPixels:
    """Compute the coordinates and rays of the selected pixels, once per (camera, selection).

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
    if m == "full":
        xs, ys = np.arange(1, W + 1), np.arange(1, H + 1)
    elif m == "stride":
        if not (1 <= selection.stride <= min(W, H)):
            raise CameraError(f"stride must be in [1, {min(W, H)}], got {selection.stride}")
        xs, ys = _centred_axis(W, selection.stride), _centred_axis(H, selection.stride)
    elif m == "grid":
        if not (1 <= selection.nx <= W and 1 <= selection.ny <= H):
            raise CameraError(f"grid must be between 1x1 and {W}x{H}, got {selection.nx}x{selection.ny}")
        # centres of nx x ny equal blocks, rounded to the nearest pixel
        xs = np.rint(0.5 + (np.arange(selection.nx) + 0.5) * W / selection.nx).astype(int)
        ys = np.rint(0.5 + (np.arange(selection.ny) + 0.5) * H / selection.ny).astype(int)
    elif m == "region":
        x0, y0, w, h = selection.region
        if not (1 <= x0 and 1 <= y0 and w >= 1 and h >= 1 and x0 + w - 1 <= W and y0 + h - 1 <= H):
            raise CameraError(f"region {selection.region} is not inside the {W}x{H} image")
        s = max(1, selection.stride)
        xs = x0 - 1 + _centred_axis(w, s)
        ys = y0 - 1 + _centred_axis(h, s)
    elif m == "list":
        x = np.frombuffer(selection.x_list, dtype=np.int32)
        y = np.frombuffer(selection.y_list, dtype=np.int32)
        if x.size == 0:
            raise CameraError("explicit pixel list is empty")
        if x.min() < 1 or y.min() < 1 or x.max() > W or y.max() > H:
            raise CameraError(f"explicit pixels must lie in [1, {W}] x [1, {H}]")
        xg, yg = x.astype(float), y.astype(float)
        rays, ok = camera.rays_from_pixels(xg, yg)
        return _freeze(SelectedPixels((x.size,), xg, yg, rays.astype(np.float32), ok))
    else:
        raise CameraError(f"pixel selection mode must be full|stride|region|grid|list, got {m!r}")
    xg, yg = np.meshgrid(xs.astype(float), ys.astype(float))
    rays, ok = camera.rays_from_pixels(xg, yg)
    shape = xg.shape
    return _freeze(SelectedPixels(shape, xg, yg, np.ascontiguousarray(rays.astype(np.float32)),
                                  ok.reshape(shape)))


def _freeze(p: SelectedPixels) -> SelectedPixels:
    for a in (p.x_px, p.y_px, p.rays_cam, p.has_ray):
        a.setflags(write=False)
    return p
