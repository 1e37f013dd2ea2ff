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
Camera models and pixel selections; unit viewing rays in the camera optical frame, cached.

Pixel coordinates follow eq 20: ``x_px`` is the 1-based column, ``y_px`` the 1-based row; the
principal point defaults to the image centre ``((eta_x + 1) / 2, (eta_y + 1) / 2)``.

Models
------
``pinhole``              eq 20: ray ~ (Dx (x - cx), Dy (y - cy), f).
``fisheye_equidistant``  r = f * theta (theta the angle from the optical axis); pixels with
                         theta > ``max_field_angle_deg`` have no ray (marked invalid).

Lens distortion (a calibrated real lens) follows ROS ``camera_calibration`` /
``sensor_msgs/CameraInfo``: ``distortion_model`` ``plumb_bob`` (k1 k2 p1 p2 k3) or
``rational_polynomial`` (k1 k2 p1 p2 k3 k4 k5 k6) on the pinhole model, ``equidistant`` (k1..k4,
OpenCV's fisheye model theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8)) on the fisheye model.
Rays of a distorted lens come from OpenCV's undistortion (``cv2.undistortPoints``,
``cv2.fisheye.undistortPoints``), the inverse from ``cv2.projectPoints`` /
``cv2.fisheye.projectPoints``; all-zero coefficients are the ideal models above.
:func:`camera_from_intrinsics` builds a model from ROS K/D, :func:`load_camera_yaml` from a
``camera_calibration`` YAML file.

Rays are returned as a (3, N) float32 array (structure of arrays, what the render kernels want)
and cached per (camera, selection): a camera that does not change costs nothing per frame.

"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import hashlib
import math

import numpy as np

from .errors import CompassError

__all__ = [
    'CameraModel',
    'PixelSelection',
    'SelectedPixels',
    'select_pixels',
    'CameraError',
    'camera_from_intrinsics',
    'load_camera_yaml',
    'CameraFile',
    'READOUT_FLIPS',
    'unflip',
    'unflipped_camera',
    'DISTORTION_MODELS',
    'check_intrinsics',
    'MAX_PIXEL_ASPECT_DEVIATION',
    'MAX_PRINCIPAL_OFFSET_FRACTION',
]

# ROS distortion model -> (projection model, number of coefficients OpenCV wants)
DISTORTION_MODELS = {
    'plumb_bob': ('pinhole', 5),
    'rational_polynomial': ('pinhole', 8),
    'equidistant': ('fisheye_equidistant', 4),
}


class CameraError(CompassError):
    """Invalid camera intrinsics or pixel selection."""


@dataclass(frozen=True)
class CameraModel:
    """
    Hold camera intrinsics; the defaults are the paper's imager (Table 1).

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

    model: str = 'pinhole'
    width_px: int = 2448  # eta_x, number of columns
    height_px: int = 2048  # eta_y, number of rows
    focal_length_mm: float = 4.0
    pixel_pitch_x_um: float = 3.45  # D_x
    pixel_pitch_y_um: float = 3.45  # D_y
    principal_x_px: float | None = None  # 1-based; None = image centre
    principal_y_px: float | None = None
    max_field_angle_deg: float = 90.0  # fisheye only
    distortion_model: str = ''  # "" (ideal) | plumb_bob | rational_polynomial | equidistant
    distortion: tuple = ()  # OpenCV/ROS coefficients D of that model

    def __post_init__(self):
        d = tuple(float(v) for v in (self.distortion or ()))
        object.__setattr__(self, 'distortion', d)
        if not all(math.isfinite(v) for v in d):
            raise CameraError(f'distortion coefficients must be finite, got {d}')
        if self.distortion_model:
            if self.distortion_model not in DISTORTION_MODELS:
                raise CameraError(
                    f'distortion_model must be one of {", ".join(DISTORTION_MODELS)}, '
                    f'got {self.distortion_model!r}'
                )
            want_model, n = DISTORTION_MODELS[self.distortion_model]
            if want_model != self.model:
                raise CameraError(
                    f'distortion_model {self.distortion_model!r} needs camera model '
                    f'{want_model!r}, '
                    f'got {self.model!r}'
                )
            if len(d) != n:
                raise CameraError(
                    f'distortion_model {self.distortion_model!r} takes {n} coefficients, got '
                    f'{len(d)}'
                )
        elif d:
            raise CameraError('distortion coefficients given without a distortion_model')
        if self.model not in ('pinhole', 'fisheye_equidistant'):
            raise CameraError(
                f"camera model must be 'pinhole' or 'fisheye_equidistant', got {self.model!r}"
            )
        for name in ('width_px', 'height_px'):
            v = getattr(self, name)
            if (
                isinstance(v, (bool, np.bool_))
                or not isinstance(v, (int, np.integer))
                or not (1 <= int(v) <= 20000)
            ):
                raise CameraError(f'{name} must be an integer in [1, 20000], got {v!r}')
        for name in ('focal_length_mm', 'pixel_pitch_x_um', 'pixel_pitch_y_um'):
            v = getattr(self, name)
            if isinstance(v, bool) or not (
                isinstance(v, (int, float)) and math.isfinite(v) and v > 0
            ):
                raise CameraError(f'{name} must be a positive finite number, got {v!r}')
        for name in ('principal_x_px', 'principal_y_px'):
            v = getattr(self, name)
            if v is not None and (
                isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            ):
                raise CameraError(f'{name} must be a finite number or None, got {v!r}')
        if not (0 < self.max_field_angle_deg <= 180):
            raise CameraError('max_field_angle_deg must be in (0, 180]')

    @property
    def cx_px(self) -> float:
        """Principal point column [px, 1-based]; the image centre by default."""
        return (
            (self.width_px + 1) / 2.0
            if self.principal_x_px is None
            else float(self.principal_x_px)
        )

    @property
    def cy_px(self) -> float:
        """Principal point row [px, 1-based]; the image centre by default."""
        return (
            (self.height_px + 1) / 2.0
            if self.principal_y_px is None
            else float(self.principal_y_px)
        )

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of a full image."""
        return (int(self.height_px), int(self.width_px))

    def field_of_view_deg(self) -> tuple[float, float, float]:
        """
        Compute the horizontal, vertical and diagonal full field of view.

        Returns
        -------
        tuple of float
            ``(horizontal, vertical, diagonal)`` [deg].

        """
        f = self.focal_length_mm * 1e3
        hw = self.width_px * self.pixel_pitch_x_um / 2
        hh = self.height_px * self.pixel_pitch_y_um / 2
        pinhole = self.model == 'pinhole'
        limit_deg = 2 * self.max_field_angle_deg

        def fov(r):
            if pinhole:
                return 2 * math.degrees(math.atan2(r, f))
            return min(2 * math.degrees(r / f), limit_deg)

        return fov(hw), fov(hh), fov(math.hypot(hw, hh))

    @property
    def distorted(self) -> bool:
        """Return True when the lens has non-zero distortion coefficients (OpenCV rays)."""
        return any(v != 0.0 for v in self.distortion)

    def K_matrix(self) -> np.ndarray:
        """
        Return the ROS/OpenCV camera matrix K.

        Returns
        -------
        numpy.ndarray
            ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels, 0-based principal point
            (OpenCV's).

        """
        fx = self.focal_length_mm / (self.pixel_pitch_x_um * 1e-3)
        fy = self.focal_length_mm / (self.pixel_pitch_y_um * 1e-3)
        return np.array(
            [[fx, 0.0, self.cx_px - 1.0], [0.0, fy, self.cy_px - 1.0], [0.0, 0.0, 1.0]]
        )

    def _rays_opencv(self, x, y):
        """
        Compute the rays of a distorted lens through OpenCV's undistortion.

        Pixels come in 1-based; OpenCV's are 0-based.
        """
        import cv2

        K = self.K_matrix()
        D = np.asarray(self.distortion, dtype=np.float64)
        pts = np.stack([x - 1.0, y - 1.0], axis=-1).reshape(-1, 1, 2).astype(np.float64)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        if self.model == 'pinhole':
            n = cv2.undistortPoints(pts, K, D, None, None, None, crit).reshape(-1, 2)
            r = np.stack([n[:, 0], n[:, 1], np.ones(n.shape[0])])
            r /= np.linalg.norm(r, axis=0, keepdims=True)
            ok = np.all(np.isfinite(r), axis=0)
            # undistortPoints inverts the polynomial iteratively: keep only pixels it maps back
            # onto themselves
            if ok.any():
                back, _ = cv2.projectPoints(
                    np.ascontiguousarray(r.T[ok]), np.zeros(3), np.zeros(3), K, D
                )
                ok[ok] = np.hypot(*(back.reshape(-1, 2) - pts.reshape(-1, 2)[ok]).T) < 0.05
            return np.where(ok, r, np.array([[0.0], [0.0], [1.0]])), ok
        n = cv2.fisheye.undistortPoints(pts, K, D, None, None, None, crit).reshape(-1, 2)
        # OpenCV returns tan(theta) along the pixel's direction; beyond 90 deg tan < 0 flips the
        # point through the centre, so theta comes from the length and the side, the direction from
        # the pixel. OpenCV clamps the distorted angle theta_d to 90 deg: pixels at or beyond it
        # get no ray.
        du = (pts[:, 0, 0] - K[0, 2]) / K[0, 0]
        dv = (pts[:, 0, 1] - K[1, 2]) / K[1, 1]
        rho_d = np.hypot(du, dv)
        rho_u = np.hypot(n[:, 0], n[:, 1])
        same_side = n[:, 0] * du + n[:, 1] * dv >= 0
        theta = np.where(same_side, np.arctan2(rho_u, 1.0), np.pi - np.arctan2(rho_u, 1.0))
        safe = np.where(rho_d > 0, rho_d, 1.0)
        st = np.sin(theta)
        r = np.stack([st * du / safe, st * dv / safe, np.cos(theta)])
        ok = (
            np.isfinite(theta)
            & (theta <= math.radians(self.max_field_angle_deg))
            & np.all(np.isfinite(n), axis=1)
        )
        ok &= rho_d < 0.5 * np.pi - 1e-9
        return np.where(ok, r, np.array([[0.0], [0.0], [1.0]])), ok

    def rays_from_pixels(self, x_px, y_px):
        """
        Compute unit viewing rays in the camera frame for 1-based pixel coordinates.

        Pinhole: eq 20, ``(D_x (x - c_x), D_y (y - c_y), f)`` normalised; fisheye: r = f * theta. A
        distorted lens (:attr:`distorted`) goes through OpenCV's undistortion
        (``cv2.undistortPoints``, ``cv2.fisheye.undistortPoints``); pixels the inverse does not
        reach have no ray.

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
            bool, shape (N,): False for fisheye pixels beyond ``max_field_angle_deg`` (or beyond
            OpenCV's 90 deg limit on the distorted angle), and for distorted pinhole pixels whose
            ray does not project back onto them.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eq 20 and Fig 4.

        """
        x = np.asarray(x_px, dtype=float).reshape(-1)
        y = np.asarray(y_px, dtype=float).reshape(-1)
        if self.distorted:
            return self._rays_opencv(x, y)
        u = (x - self.cx_px) * (self.pixel_pitch_x_um * 1e-3)  # mm on the sensor
        v = (y - self.cy_px) * (self.pixel_pitch_y_um * 1e-3)
        f = self.focal_length_mm
        if self.model == 'pinhole':
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
        """
        Project camera-frame rays back to 1-based pixel coordinates (the inverse of eq 20).

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
        if self.distorted:
            import cv2

            obj = np.ascontiguousarray(r.reshape(3, -1).T).reshape(-1, 1, 3)
            K, D = self.K_matrix(), np.asarray(self.distortion, dtype=np.float64)
            if self.model == 'pinhole':
                px, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K, D)
            else:
                px, _ = cv2.fisheye.projectPoints(obj, np.zeros(3), np.zeros(3), K, D)
            px = px.reshape(-1, 2)
            return px[:, 0] + 1.0, px[:, 1] + 1.0
        f = self.focal_length_mm
        if self.model == 'pinhole':
            u = f * r[0] / r[2]
            v = f * r[1] / r[2]
        else:
            theta = np.arctan2(np.hypot(r[0], r[1]), r[2])
            phi = np.arctan2(r[1], r[0])
            u, v = f * theta * np.cos(phi), f * theta * np.sin(phi)
        return (
            u / (self.pixel_pitch_x_um * 1e-3) + self.cx_px,
            v / (self.pixel_pitch_y_um * 1e-3) + self.cy_px,
        )


#: Largest relative difference of the focal lengths in x and y pixels (|fx / fy - 1|) accepted from
#: a calibration: square-pixel sensors calibrate to within a few 1e-3.
MAX_PIXEL_ASPECT_DEVIATION = 0.05
#: Largest distance of the principal point from the image centre, as a fraction of the width (x) or
#: the height (y). A lens is centred on its sensor to a few tenths of a millimetre (a few percent
#: of a 2/3" sensor's 8.4 x 7.1 mm; the real fisheye of ``test/data/real-sky``: 2.6 % and 1.1 %),
#: so 10 % leaves room for a decentred mount while refusing what the old 25 % let through: a K
#: calibrated 2x binned and used at full resolution puts the principal point 25 % off (24.96 % on
#: a 2448 x 2048 sensor: ``ok`` 23 deg off); 20-24 % offsets gave ``ok`` 14-45 deg off (issue 24).
MAX_PRINCIPAL_OFFSET_FRACTION = 0.10


def check_intrinsics(
    camera: 'CameraModel',
    image_size: tuple[int, int] | None = None,
    max_aspect_deviation: float = MAX_PIXEL_ASPECT_DEVIATION,
    max_principal_offset: float = MAX_PRINCIPAL_OFFSET_FRACTION,
) -> 'CameraModel':
    """
    Check that calibrated intrinsics (e.g. from a ROS camera_info) are plausible.

    A wrong calibration otherwise gives a confident, wrong heading (issue 18: the principal point
    at the corner of a 612 x 512 image moved a level camera's heading by 24 deg with status ok).

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
        The first problem: image size, focal length <= 0, fx/fy, principal point outside the image
        or too far from its centre.

    """
    W, H = int(camera.width_px), int(camera.height_px)
    if image_size is not None and (int(image_size[0]), int(image_size[1])) != (W, H):
        raise CameraError(
            f'image is {int(image_size[0])}x{int(image_size[1])} but the intrinsics are for '
            f'{W}x{H}'
        )
    if not camera.focal_length_mm > 0:
        raise CameraError(f'focal length must be positive, got {camera.focal_length_mm!r} mm')
    aspect = camera.pixel_pitch_y_um / camera.pixel_pitch_x_um  # = fx / fy in pixels
    if abs(aspect - 1.0) > max_aspect_deviation:
        raise CameraError(
            f'fx/fy = {aspect:.4g}: pixels this far from square (more than '
            f'{max_aspect_deviation:g}) mean a calibration of another camera or mode'
        )
    cx, cy = camera.cx_px, camera.cy_px
    if not (0.5 <= cx <= W + 0.5 and 0.5 <= cy <= H + 0.5):
        raise CameraError(
            f'principal point ({cx - 1:.6g}, {cy - 1:.6g}) (0-based) is outside the {W}x{H} image'
        )
    dx, dy = abs(cx - (W + 1) / 2.0) / W, abs(cy - (H + 1) / 2.0) / H
    if dx > max_principal_offset or dy > max_principal_offset:
        raise CameraError(
            f'principal point ({cx - 1:.6g}, {cy - 1:.6g}) (0-based) is {max(dx, dy):.0%} of the '
            f'image size from the centre of the {W}x{H} image (at most '
            f'{max_principal_offset:.0%}): '
            'a calibration from another resolution or binning?'
        )
    return camera


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


def camera_from_intrinsics(
    width_px: int,
    height_px: int,
    K,
    D=(),
    distortion_model: str = '',
    pixel_pitch_um: float = 3.45,
    max_field_angle_deg: float = 90.0,
) -> CameraModel:
    """
    Build a :class:`CameraModel` from ROS/OpenCV intrinsics.

    The intrinsics are those of a ROS ``CameraInfo`` or of ``camera_calibration``.

    Parameters
    ----------
    width_px, height_px : int
        Image size [px].
    K : array_like
        3 x 3 (or 9 values, row-major) ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` [px], 0-based
        principal point (the model is 1-based, eq 20: ``principal_x_px = cx + 1``).
    D : array_like, optional
        Distortion coefficients of ``distortion_model`` (``plumb_bob`` 5 or 4,
        ``rational_polynomial`` 8, ``equidistant`` 4); empty or all zero: the ideal pinhole /
        equidistant fisheye.
    distortion_model : str, optional
        ``plumb_bob`` | ``rational_polynomial`` | ``equidistant`` | "" (pinhole).
    pixel_pitch_um : float, default 3.45
        Only scales the focal length to mm (rays depend on fx, fy in pixels); the y pitch is scaled
        by fx / fy so non-square pixels keep their shape.
    max_field_angle_deg : float, default 90
        Fisheye pixels beyond this angle from the optical axis [deg] have no ray.

    Returns
    -------
    CameraModel
        The lens, distorted when D is non-zero (rays through OpenCV, see
        :meth:`CameraModel.rays_from_pixels`).

    Raises
    ------
    CameraError
        Non-finite or wrongly sized K or D, non-positive focal lengths, an unknown distortion
        model.

    """
    Km = np.asarray(K, dtype=float).reshape(-1)
    Dv = np.asarray(D if D is not None else (), dtype=float).reshape(-1)
    if Km.size != 9 or not np.all(np.isfinite(Km)):
        raise CameraError('camera matrix K must hold 9 finite numbers')
    if not np.all(np.isfinite(Dv)):
        raise CameraError('distortion coefficients must be finite')
    fx, fy, cx, cy = (float(Km[i]) for i in (0, 4, 2, 5))
    if not (fx > 0 and fy > 0):
        raise CameraError(f'focal lengths must be positive, got fx={fx}, fy={fy}')
    dm = str(distortion_model or '')
    if dm not in ('',) + tuple(DISTORTION_MODELS):
        raise CameraError(
            f'distortion model must be one of {", ".join(DISTORTION_MODELS)}, got {dm!r}'
        )
    model = DISTORTION_MODELS[dm][0] if dm else 'pinhole'
    if dm and Dv.size and np.any(Dv != 0):
        n = DISTORTION_MODELS[dm][1]
        if dm == 'plumb_bob' and Dv.size == 4:  # OpenCV accepts k1 k2 p1 p2: k3 = 0
            Dv = np.append(Dv, 0.0)
        if Dv.size != n:
            raise CameraError(f'distortion model {dm!r} takes {n} coefficients, got {Dv.size}')
        dist = (dm, tuple(float(v) for v in Dv))
    else:
        dist = ('', ())
    pitch = float(pixel_pitch_um)
    return CameraModel(
        model=model,
        width_px=int(width_px),
        height_px=int(height_px),
        focal_length_mm=fx * pitch * 1e-3,
        pixel_pitch_x_um=pitch,
        pixel_pitch_y_um=pitch * fx / fy,
        principal_x_px=cx + 1.0,
        principal_y_px=cy + 1.0,
        max_field_angle_deg=float(max_field_angle_deg),
        distortion_model=dist[0],
        distortion=dist[1],
    )


@dataclass(frozen=True)
class CameraFile:
    """
    What a ``CAMERA.yaml`` says: the lens and the polarizer layout.

    ``camera`` the :class:`CameraModel`; ``layout`` the 2 x 2 polarizer angles [deg] of the
    top-left block; ``pol45_toward`` the 45 deg polarizer's image direction; ``layout_given`` False
    when the file had no ``polarizer:`` section (the IMX250MZR defaults were used); ``mount`` the
    camera's tilt on the body (:class:`~.mount.Mount`, from a ``mount:`` section) or None;
    ``readout_flip`` the axes the camera mirrors on readout (:data:`READOUT_FLIPS`): then
    ``camera`` and the polarizer describe the *sensor* (the image after :func:`unflip`), the file's
    K having been calibrated on the delivered, mirrored images.
    """

    camera: CameraModel
    layout: tuple
    pol45_toward: str
    layout_given: bool
    mount: object = None
    readout_flip: str = ''


#: ``readout_flip`` values of a CAMERA.yaml: the image axes the camera mirrors on readout (GenICam
#: ``ReverseX`` = "x", ``ReverseY`` = "y", both = "xy", a 180 deg rotation)
READOUT_FLIPS = ('', 'x', 'y', 'xy')


def unflip(image, readout_flip: str):
    """
    Undo a camera's mirrored readout: the image as the sensor itself sees it.

    Parameters
    ----------
    image : numpy.ndarray
        A delivered image (raw mosaic, a Stokes plane or a mask), rows x columns.
    readout_flip : {"", "x", "y", "xy"}
        The axes the readout mirrors (:data:`READOUT_FLIPS`).

    Returns
    -------
    numpy.ndarray
        A view with the columns (x) and/or rows (y) reversed back.

    """
    a = image
    if 'x' in readout_flip:
        a = a[:, ::-1]
    if 'y' in readout_flip:
        a = a[::-1, :]
    return a


def unflipped_camera(cam: CameraModel, readout_flip: str) -> CameraModel:
    """
    Return the lens model of the unflipped image from a calibration of the delivered one.

    A mirror of the image axis maps pixel u to W + 1 - u (1-based), so the principal point
    mirrors too, and the tangential coefficient of that axis changes sign (p2 for x, p1 for y;
    radial terms are symmetric): the projection is the calibrated one with x -> -x (or y -> -y).

    Parameters
    ----------
    cam : CameraModel
        The intrinsics calibrated on the delivered (mirrored) images.
    readout_flip : {"", "x", "y", "xy"}
        The axes the readout mirrors (:data:`READOUT_FLIPS`).

    Returns
    -------
    CameraModel
        The intrinsics of the image after :func:`unflip` (``cam`` itself without a flip).

    """
    import dataclasses

    if not readout_flip:
        return cam
    cx, cy, d = cam.cx_px, cam.cy_px, list(cam.distortion)
    if 'x' in readout_flip:
        cx = cam.width_px + 1.0 - cx
        if cam.model == 'pinhole' and len(d) >= 4:
            d[3] = -d[3]
    if 'y' in readout_flip:
        cy = cam.height_px + 1.0 - cy
        if cam.model == 'pinhole' and len(d) >= 4:
            d[2] = -d[2]
    return dataclasses.replace(cam, principal_x_px=cx, principal_y_px=cy, distortion=tuple(d))


def _matrix_field(doc: dict, key: str, size: int | None, path: str):
    v = doc.get(key)
    if isinstance(v, dict):
        v = v.get('data')
    if v is None:
        return None
    try:
        a = np.asarray(v, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise CameraError(f'{path}: {key} must be a list of numbers') from None
    if size is not None and a.size != size:
        raise CameraError(f'{path}: {key} must hold {size} numbers, got {a.size}')
    return a


def load_camera_yaml(path) -> CameraFile:
    """
    Read a ROS ``camera_calibration`` YAML file plus the polarizer.

    The file is the one ``camera_info_url`` points at.

    Keys used: ``image_width``, ``image_height``, ``camera_matrix`` (``{rows, cols, data}`` or a
    list), ``distortion_model``, ``distortion_coefficients``; optional ``pixel_pitch_um`` (default
    3.45), ``max_field_angle_deg`` (fisheye, default 90), ``polarizer: {layout: [[90, 45], [135,
    0]], pol45_toward: "+x-y"}`` (default: the Sony IMX250MZR as delivered, see :mod:`demosaic`)
    and ``readout_flip`` (none | x | y | xy: the camera's ReverseX/ReverseY; the polarizer is then
    the sensor's own, and the images are read through :func:`unflip`).

    Parameters
    ----------
    path : str or path-like
        The YAML file (at most 1 MiB is read).

    Returns
    -------
    CameraFile
        The lens and the polarizer layout.

    Raises
    ------
    CameraError
        Unreadable file, not YAML, missing or unusable keys, implausible intrinsics
        (:func:`check_intrinsics`: principal point more than 10 % off the image centre, fx/fy
        beyond 5 %); one-line reason naming the file.

    """
    from .demosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45, parse_layout, SensorError
    from .safe_load import load_yaml, read_text

    p = str(path)
    # a regular file of at most 1 MiB (a FIFO or /dev/zero is refused), YAML nesting and bad dates
    # one line
    try:
        text = read_text(p, CameraError, 'camera file')
    except CameraError as exc:
        raise CameraError(f'{p}: cannot read camera file ({exc})') from None
    doc = load_yaml(text, p, CameraError)
    if not isinstance(doc, dict):
        raise CameraError(f'{p}: a camera file is a YAML mapping (ROS camera_calibration format)')
    try:
        w, h = int(doc['image_width']), int(doc['image_height'])
    except (KeyError, TypeError, ValueError):
        raise CameraError(f'{p}: needs integer image_width and image_height') from None
    K = _matrix_field(doc, 'camera_matrix', 9, p)
    if K is None:
        raise CameraError(f'{p}: needs camera_matrix (3 x 3, pixels)')
    D = _matrix_field(doc, 'distortion_coefficients', None, p)
    pol = doc.get('polarizer')
    if pol is not None and not isinstance(pol, dict):
        raise CameraError(f'{p}: polarizer must be a mapping with layout and pol45_toward')
    pol = pol or {}
    try:
        lay = parse_layout(
            pol.get('layout', IMX250MZR_LAYOUT), pol.get('pol45_toward', IMX250MZR_POL45)
        )
        cam = camera_from_intrinsics(
            w,
            h,
            K,
            D if D is not None else (),
            doc.get('distortion_model', '') or '',
            float(doc.get('pixel_pitch_um', 3.45)),
            float(doc.get('max_field_angle_deg', 90.0)),
        )
        check_intrinsics(cam)  # as for a camera_info: a K from another mode is refused
        flip = _readout_flip(doc.get('readout_flip', ''))
    except (SensorError, CameraError, TypeError, ValueError) as exc:
        raise CameraError(f'{p}: {exc}') from None
    cam = unflipped_camera(cam, flip)
    return CameraFile(
        cam, lay.angles_deg, lay.pol45_toward, bool(pol), _mount(doc, p), readout_flip=flip
    )


def _readout_flip(value) -> str:
    """Read ``readout_flip``: "", "none", "x", "y", "xy" (or "yx"); CameraError otherwise."""
    v = '' if value in (None, False, 'none') else value
    if isinstance(v, str) and ''.join(sorted(v.lower())) in READOUT_FLIPS:
        return ''.join(sorted(v.lower()))
    raise CameraError(f'readout_flip must be one of none, x, y, xy, got {value!r}')


def _mount(doc: dict, path: str):
    """Return the file's ``mount:`` section (:mod:`.mount`), or None without one."""
    from .mount import mount_from_dict, MountError

    try:
        return mount_from_dict(doc['mount'], f'{path}: mount') if 'mount' in doc else None
    except MountError as exc:
        raise CameraError(str(exc)) from None
