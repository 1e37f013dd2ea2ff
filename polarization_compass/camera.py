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
Camera models: unit viewing rays in the camera optical frame, from ROS intrinsics.

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
:func:`camera_from_intrinsics` builds a model from ROS K/D, :func:`.camera_file.load_camera_yaml`
from a ``camera_calibration`` YAML file.

Rays are returned as a (3, N) float32 array (structure of arrays, what the render kernels want);
:func:`.camera_pixels.select_pixels` caches them per (camera, selection): a camera that does not
change costs nothing per frame.

"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .errors import CompassError

__all__ = [
    'CameraModel',
    'CameraError',
    'camera_from_intrinsics',
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
