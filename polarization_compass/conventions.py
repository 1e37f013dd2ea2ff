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
Frames and angle conventions. This is the only module that defines them; everything else imports.

Frames
------
``enu``      World frame East-North-Up (REP-103 ``map``/``odom`` style, z up).
``sun``      The paper's Sun-azimuth frame ``a`` (eq 1): ENU rotated about Up so that +y points at
             the sun's azimuth. A world azimuth A becomes ``A - A_sun`` there.
``cam``      Camera optical frame (paper Fig 4 and the ROS ``*_optical_frame`` convention): +x
             along image columns (right), +y along image rows (down), +z the optical axis. A level
             camera looks at the zenith.
``body``     The robot's REP-103 body frame (x forward, y left, z up). The default mounting puts
             the camera looking up with its +y axis along body +x (forward), so body +y is camera
             -x.

Angles (all names carry their unit: ``_deg`` or ``_rad``)
------
``azimuth``  of a direction: clockwise from true North, as the paper does (``A``). Direction ``(cos
             h sin A, cos h cos A, sin h)`` in ENU for altitude h.
``bearing``  of the camera: the true bearing of the camera +y axis, clockwise from North.
``psi``      the paper's yaw: the bearing relative to the sun's azimuth, ``psi = bearing - A_sun``
             (eq 21 with the erratum of eq 26 fixed: ``A_g = A_a + A_sun``).
``pitch``    the paper's alpha, a rotation about camera +x; ``roll`` the paper's beta, about camera
             +y.
``yaw_enu``  REP-103 yaw of the body: counter-clockwise from East, ``yaw_enu = 90 deg - bearing``.
``aop``      angle of polarization in the paper's eq 28 convention: angle of the E-vector projected
             on the sensor x-y plane, measured from +y_cam towards +x_cam, axial (mod 180 deg).

Camera attitude (eq 21): ``R_sun_cam = Rz(-psi) @ Rx(pitch) @ Ry(roll)`` with the standard
right-handed elementary rotations, and ``R_enu_cam = Rz(-bearing) @ Rx(pitch) @ Ry(roll)``.

Wrapping: ``wrap_180`` -> (-180, 180], ``wrap_360`` -> [0, 360), ``fold_axial`` -> (-90, 90] for
axial errors, and AoP images are folded to [-pi/2, pi/2) (``fold_aop_rad``). The ``*_float`` forms
take one finite float without numpy (per-estimate code, numba kernels) and give the same bits.

"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .errors import CompassError

__all__ = [
    'wrap_180_deg',
    'wrap_360_deg',
    'fold_axial_deg',
    'fold_axial_rad',
    'fold_aop_rad',
    'wrap_180_deg_float',
    'wrap_360_deg_float',
    'fold_axial_rad_float',
    'rot_x',
    'rot_y',
    'rot_z',
    'R_sun_cam_from_attitude',
    'R_enu_cam_from_attitude',
    'attitude_from_R_enu_cam',
    'enu_direction',
    'azimuth_altitude_from_enu',
    'bearing_to_yaw_enu_deg',
    'yaw_enu_to_bearing_deg',
    'psi_to_bearing_deg',
    'bearing_to_psi_deg',
    'quat_to_matrix',
    'matrix_to_quat',
    'validate_quaternion',
    'QuaternionError',
    'R_BODY_CAM_DEFAULT',
    'aop_from_evector_cam_rad',
    'evector_cam_from_aop',
    'axial_mean_rad',
    'axial_difference_deg',
    'CameraAttitude',
    'camera_attitude_from_body_quat',
    'R_enu_body_from_camera_attitude',
    'body_quat_from_camera_attitude',
    'unit_axis_body',
    'unit_polarizer_frame_body',
    'unit_evector_body',
    'unit_angle_from_evector_body_rad',
    'ANGLE_ZEROS',
    'ANGLE_SENSES',
]


# --------------------------------------------------------------------------------------------
# Wrapping
# --------------------------------------------------------------------------------------------
def wrap_180_deg(angle_deg):
    """
    Wrap angles in degrees to (-180, 180].

    Parameters
    ----------
    angle_deg : float or array_like
        Angle(s) [deg], any value.

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [deg] in (-180, 180]; a float for scalar input.

    """
    a = np.asarray(angle_deg, dtype=float)
    w = np.mod(a + 180.0, 360.0) - 180.0  # [-180, 180)
    w = np.where(w == -180.0, 180.0, w)
    return w if w.ndim else float(w)


def wrap_360_deg(angle_deg):
    """
    Wrap angles in degrees to [0, 360).

    Parameters
    ----------
    angle_deg : float or array_like
        Angle(s) [deg], any value.

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [deg] in [0, 360); a float for scalar input.

    """
    a = np.asarray(angle_deg, dtype=float)
    w = np.mod(a, 360.0)
    w = np.where(w >= 360.0, 0.0, w)  # np.mod(-1e-20, 360) == 360.0 in floating point
    return w if w.ndim else float(w)


def wrap_180_deg_float(angle_deg: float) -> float:
    """
    Wrap one finite float in degrees to (-180, 180], as :func:`wrap_180_deg` does.

    Plain arithmetic, no numpy call: the same floor modulo as ``np.mod`` and so the same bits,
    cheap enough to run once per estimate in sweeps of 1e5, and compilable by numba
    (``njit(inline="always")(...)``) for kernels.

    Parameters
    ----------
    angle_deg : float
        Angle [deg], finite.

    Returns
    -------
    float
        The angle [deg] in (-180, 180].

    """
    w = (angle_deg + 180.0) % 360.0 - 180.0
    return 180.0 if w == -180.0 else w


def wrap_360_deg_float(angle_deg: float) -> float:
    """
    Wrap one finite float in degrees to [0, 360), as :func:`wrap_360_deg` does.

    Plain arithmetic like :func:`wrap_180_deg_float`.

    Parameters
    ----------
    angle_deg : float
        Angle [deg], finite.

    Returns
    -------
    float
        The angle [deg] in [0, 360).

    """
    w = angle_deg % 360.0
    return 0.0 if w >= 360.0 else w


def fold_axial_rad_float(angle_rad: float) -> float:
    """
    Fold one finite axial angle (mod pi) in radians to (-pi/2, pi/2], as :func:`fold_axial_rad`.

    Plain arithmetic like :func:`wrap_180_deg_float`.

    Parameters
    ----------
    angle_rad : float
        Axial angle [rad], finite, defined modulo pi.

    Returns
    -------
    float
        The angle [rad] in (-pi/2, pi/2].

    """
    w = (angle_rad + 0.5 * math.pi) % math.pi - 0.5 * math.pi
    return 0.5 * math.pi if w <= -0.5 * math.pi else w


def fold_axial_deg(angle_deg):
    """
    Fold axial angles (defined mod 180 deg) to (-90, 90].

    Used for heading errors of axial methods, which measure the solar meridian modulo 180 deg. A
    finite float is folded without numpy (hot in sweeps) and gives the same bits.

    Parameters
    ----------
    angle_deg : float or array_like
        Axial angle(s) [deg].

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [deg] in (-90, 90]; a float for scalar input.

    """
    if isinstance(angle_deg, float) and math.isfinite(angle_deg):
        w = (
            angle_deg + 90.0
        ) % 180.0 - 90.0  # a scalar: the same floor modulo without numpy (sweeps)
        return 90.0 if w <= -90.0 else w
    a = np.asarray(angle_deg, dtype=float)
    w = np.mod(a + 90.0, 180.0) - 90.0  # [-90, 90)
    w = np.where(w <= -90.0, 90.0, w)
    return w if w.ndim else float(w)


def fold_axial_rad(angle_rad):
    """
    Fold axial angles (defined mod pi) to (-pi/2, pi/2].

    Parameters
    ----------
    angle_rad : float or array_like
        Axial angle(s) [rad].

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [rad] in (-pi/2, pi/2]; a float for scalar input.

    """
    a = np.asarray(angle_rad, dtype=float)
    w = np.mod(a + np.pi / 2, np.pi) - np.pi / 2
    w = np.where(w <= -np.pi / 2, np.pi / 2, w)
    return w if w.ndim else float(w)


def fold_aop_rad(aop_rad):
    """
    Fold an AoP image to [-pi/2, pi/2), the ``render`` contract.

    Parameters
    ----------
    aop_rad : array_like
        Angle of polarization [rad] in the eq 28 convention, any value; float32 stays float32.

    Returns
    -------
    numpy.ndarray
        The AoP [rad] in [-pi/2, pi/2), same dtype and shape as the input.

    """
    a = np.asarray(aop_rad)
    half = a.dtype.type(np.pi / 2) if a.dtype.kind == 'f' else np.pi / 2
    w = np.mod(a + half, 2 * half) - half
    return np.where(w >= half, -half, w).astype(a.dtype, copy=False)


def axial_mean_rad(angles_rad, weights=None):
    """
    Compute the weighted axial (mod pi) circular mean ``0.5 * arg(sum w exp(2i a))``.

    The doubled-angle mean of axial data, with the resultant length R in [0, 1] as the measure of
    concentration (1 = all equal, 0 = no preferred axis).

    Parameters
    ----------
    angles_rad : array_like
        Axial angles [rad], defined modulo pi.
    weights : array_like, optional
        Non-negative weights, the shape of ``angles_rad``; equal weights by default.

    Returns
    -------
    mean_rad : float
        The mean axis [rad] in [-pi/2, pi/2]; 0 when the weights sum to 0 or less.
    resultant_length : float
        R = |sum w exp(2i a)| / sum w in [0, 1]; 0 when the weights sum to 0 or less.

    """
    a = np.asarray(angles_rad, dtype=float)
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=float)
    c = float(np.sum(w * np.cos(2 * a)))
    s = float(np.sum(w * np.sin(2 * a)))
    total = float(np.sum(w))
    if total <= 0:
        return 0.0, 0.0
    return 0.5 * math.atan2(s, c), math.hypot(c, s) / total


def axial_difference_deg(a_deg, b_deg):
    """
    Compute the difference a - b of two axial angles (mod 180 deg), folded to (-90, 90].

    Parameters
    ----------
    a_deg, b_deg : float or array_like
        Axial angles [deg], broadcast against each other.

    Returns
    -------
    float or numpy.ndarray
        a - b [deg] in (-90, 90].

    """
    return fold_axial_deg(np.asarray(a_deg, dtype=float) - np.asarray(b_deg, dtype=float))


# --------------------------------------------------------------------------------------------
# Rotations (standard right-handed elementary rotations, vectorised over angle arrays)
# --------------------------------------------------------------------------------------------
def _rot(theta_rad, axis):
    if isinstance(theta_rad, (float, int)) and not isinstance(theta_rad, bool):
        c, s = (
            math.cos(theta_rad),
            math.sin(theta_rad),
        )  # a scalar: 2 us instead of 45 (hot in sweeps)
        if axis == 0:
            return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        if axis == 1:
            return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    t = np.asarray(theta_rad, dtype=float)
    c, s = np.cos(t), np.sin(t)
    o, z = np.ones_like(t), np.zeros_like(t)
    if axis == 0:
        m = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == 1:
        m = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        m = [[c, -s, z], [s, c, z], [z, z, o]]
    out = np.array(m, dtype=float)  # (3, 3, ...)
    return np.moveaxis(out, (0, 1), (-2, -1))  # (..., 3, 3)


def rot_x(theta_rad):
    """
    Build the right-handed rotation about +x (active: rotates vectors by theta).

    Parameters
    ----------
    theta_rad : float or array_like
        Rotation angle(s) [rad].

    Returns
    -------
    numpy.ndarray
        Rotation matrix, shape (3, 3) for a scalar angle or (..., 3, 3) for an array.

    """
    return _rot(theta_rad, 0)


def rot_y(theta_rad):
    """
    Build the right-handed rotation about +y (active: rotates vectors by theta).

    Parameters
    ----------
    theta_rad : float or array_like
        Rotation angle(s) [rad].

    Returns
    -------
    numpy.ndarray
        Rotation matrix, shape (3, 3) for a scalar angle or (..., 3, 3) for an array.

    """
    return _rot(theta_rad, 1)


def rot_z(theta_rad):
    """
    Build the right-handed rotation about +z (active: rotates vectors by theta).

    Parameters
    ----------
    theta_rad : float or array_like
        Rotation angle(s) [rad].

    Returns
    -------
    numpy.ndarray
        Rotation matrix, shape (3, 3) for a scalar angle or (..., 3, 3) for an array.

    """
    return _rot(theta_rad, 2)


def R_sun_cam_from_attitude(psi_deg, pitch_deg, roll_deg):
    """
    Build the camera-to-Sun-azimuth-frame rotation ``C_c^a`` of eq 21.

    ``C_c^a = Rz(-psi) @ Rx(pitch) @ Ry(roll)``: maps camera-frame vectors into the Sun-azimuth
    frame.

    Parameters
    ----------
    psi_deg : float or array_like
        The paper's yaw psi [deg]: bearing of camera +y relative to the sun's azimuth, clockwise.
    pitch_deg : float or array_like
        The paper's pitch alpha [deg], a rotation about camera +x.
    roll_deg : float or array_like
        The paper's roll beta [deg], a rotation about camera +y.

    Returns
    -------
    numpy.ndarray
        ``R_sun_cam``, shape (..., 3, 3) (broadcast over the angles).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    return (rot_z(-np.radians(psi_deg)) @ rot_x(np.radians(pitch_deg))) @ rot_y(
        np.radians(roll_deg)
    )


def R_enu_cam_from_attitude(bearing_deg, pitch_deg, roll_deg):
    """
    Build the camera-to-ENU rotation ``Rz(-bearing) @ Rx(pitch) @ Ry(roll)``.

    Eq 21 with the sun's azimuth added back to the yaw (``bearing = psi + A_sun``).

    Parameters
    ----------
    bearing_deg : float or array_like
        True bearing of camera +y [deg], clockwise from North.
    pitch_deg : float or array_like
        The paper's pitch alpha [deg], a rotation about camera +x.
    roll_deg : float or array_like
        The paper's roll beta [deg], a rotation about camera +y.

    Returns
    -------
    numpy.ndarray
        ``R_enu_cam``, shape (..., 3, 3) (broadcast over the angles).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    return R_sun_cam_from_attitude(bearing_deg, pitch_deg, roll_deg)  # eq 21, yaw = bearing


@dataclass(frozen=True)
class CameraAttitude:
    """
    Hold a camera attitude in the paper's terms (eq 21), degrees.

    ``bearing_deg`` of camera +y clockwise from North, ``pitch_deg`` (alpha, about camera +x),
    ``roll_deg`` (beta, about camera +y). ``gimbal_lock`` is True when |pitch| ~ 90 deg, where
    bearing and roll are not separable (the bearing is then 0 and roll absorbs it).
    """

    bearing_deg: float
    pitch_deg: float
    roll_deg: float
    gimbal_lock: bool = False


def attitude_from_R_enu_cam(R_enu_cam, lock_tol=1e-9) -> CameraAttitude:
    """
    Recover bearing, pitch and roll from one camera-to-ENU rotation.

    The inverse of :func:`R_enu_cam_from_attitude`. From ``R = Rz(-B) Rx(a) Ry(b)``:
    R[2,1] = sin a, R[2,0] = -sin b cos a, R[2,2] = cos b cos a, R[0,1] = sin B cos a,
    R[1,1] = cos B cos a.

    Parameters
    ----------
    R_enu_cam : array_like
        Rotation matrix (3, 3) mapping camera-frame vectors into ENU.
    lock_tol : float, default 1e-9
        Gimbal lock when cos(pitch) is below this: bearing is then set to 0 and roll absorbs it.

    Returns
    -------
    CameraAttitude
        Bearing [deg, 0..360), pitch [deg, -90..90], roll [deg, -180..180] and the gimbal-lock
        flag.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    R = np.asarray(R_enu_cam, dtype=float)
    sin_a = float(np.clip(R[2, 1], -1.0, 1.0))
    pitch = math.degrees(math.asin(sin_a))
    cos_a = math.sqrt(max(0.0, 1.0 - sin_a * sin_a))
    if cos_a < lock_tol:
        # x_cam stays horizontal: R[:,0] = Rz(-B) Ry-free... bearing and roll mix; put it all in
        # roll. With B = 0: R = Rx(a) Ry(b) -> R[0,0] = cos b, R[0,2] = sin b.
        roll = math.degrees(math.atan2(R[0, 2], R[0, 0]))
        return CameraAttitude(0.0, pitch, roll, True)
    roll = math.degrees(math.atan2(-R[2, 0], R[2, 2]))
    bearing = float(wrap_360_deg(math.degrees(math.atan2(R[0, 1], R[1, 1]))))
    return CameraAttitude(bearing, pitch, roll, False)


# --------------------------------------------------------------------------------------------
# Directions and headings
# --------------------------------------------------------------------------------------------
def enu_direction(azimuth_deg, altitude_deg):
    """
    Compute ENU unit vector(s) of an azimuth and altitude.

    ``(cos h sin A, cos h cos A, sin h)`` for azimuth A clockwise from North and altitude h.

    Parameters
    ----------
    azimuth_deg : float or array_like
        Azimuth [deg], clockwise from true North.
    altitude_deg : float or array_like
        Altitude above the horizon [deg].

    Returns
    -------
    numpy.ndarray
        Unit vector(s) in ENU, shape (..., 3).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 16 (the same angles; Fig
       2).

    """
    A = np.radians(np.asarray(azimuth_deg, dtype=float))
    h = np.radians(np.asarray(altitude_deg, dtype=float))
    return np.stack([np.cos(h) * np.sin(A), np.cos(h) * np.cos(A), np.sin(h)], axis=-1)


def azimuth_altitude_from_enu(v):
    """
    Compute azimuth and altitude of ENU vector(s), the inverse of :func:`enu_direction`.

    Uses ``atan2`` for both angles (the paper's eqs 23-24 in the ENU frame, without the quotient).

    Parameters
    ----------
    v : array_like
        Vector(s) in ENU, shape (..., 3), any non-zero length.

    Returns
    -------
    azimuth_deg : float or numpy.ndarray
        Azimuth [deg] in [0, 360), clockwise from North.
    altitude_deg : numpy.ndarray
        Altitude [deg] in [-90, 90].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 23-24.

    """
    v = np.asarray(v, dtype=float)
    az = wrap_360_deg(np.degrees(np.arctan2(v[..., 0], v[..., 1])))
    alt = np.degrees(np.arctan2(v[..., 2], np.hypot(v[..., 0], v[..., 1])))
    return az, alt


def bearing_to_yaw_enu_deg(bearing_deg):
    """
    Convert a true bearing to REP-103 yaw, ``yaw_enu = 90 - bearing``.

    Parameters
    ----------
    bearing_deg : float or array_like
        True bearing [deg], clockwise from North.

    Returns
    -------
    float or numpy.ndarray
        REP-103 yaw [deg], counter-clockwise from East, in (-180, 180].

    References
    ----------
    .. [1] T. Foote and M. Purvis, "REP 103: Standard Units of Measure and Coordinate Conventions",
       ROS Enhancement Proposals, 2010.

    """
    return wrap_180_deg(90.0 - np.asarray(bearing_deg, dtype=float))


def yaw_enu_to_bearing_deg(yaw_enu_deg):
    """
    Convert REP-103 yaw to a true bearing, ``bearing = 90 - yaw_enu``.

    Parameters
    ----------
    yaw_enu_deg : float or array_like
        REP-103 yaw [deg], counter-clockwise from East.

    Returns
    -------
    float or numpy.ndarray
        True bearing [deg], clockwise from North, in [0, 360).

    References
    ----------
    .. [1] T. Foote and M. Purvis, "REP 103: Standard Units of Measure and Coordinate Conventions",
       ROS Enhancement Proposals, 2010.

    """
    return wrap_360_deg(90.0 - np.asarray(yaw_enu_deg, dtype=float))


def psi_to_bearing_deg(psi_deg, sun_azimuth_deg):
    """
    Convert the paper's psi (yaw in the Sun-azimuth frame) to the true bearing.

    ``bearing = psi + A_sun``, the relation of eq 26 with its sign erratum fixed.

    Parameters
    ----------
    psi_deg : float or array_like
        Yaw psi [deg] of camera +y relative to the sun's azimuth.
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], clockwise from North.

    Returns
    -------
    float or numpy.ndarray
        True bearing of camera +y [deg] in [0, 360).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 21 and 26 (with the sign
       erratum of eq 26 fixed).

    """
    return wrap_360_deg(
        np.asarray(psi_deg, dtype=float) + np.asarray(sun_azimuth_deg, dtype=float)
    )


def bearing_to_psi_deg(bearing_deg, sun_azimuth_deg):
    """
    Convert a true bearing to the paper's psi, ``psi = bearing - A_sun``.

    Parameters
    ----------
    bearing_deg : float or array_like
        True bearing of camera +y [deg], clockwise from North.
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], clockwise from North.

    Returns
    -------
    float or numpy.ndarray
        Yaw psi [deg] in the Sun-azimuth frame, in (-180, 180].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 21 and 26 (with the sign
       erratum of eq 26 fixed).

    """
    return wrap_180_deg(
        np.asarray(bearing_deg, dtype=float) - np.asarray(sun_azimuth_deg, dtype=float)
    )


# --------------------------------------------------------------------------------------------
# Quaternions (ROS order x, y, z, w; active rotation child -> parent)
# --------------------------------------------------------------------------------------------
class QuaternionError(CompassError):
    """A quaternion that cannot be used (NaN/inf, zero, or not unit within tolerance)."""


def validate_quaternion(q_xyzw, unit_tol=1e-3):
    """
    Check a quaternion and return it normalised.

    ``unit_tol`` bounds |norm - 1|: a producer that sends a non-unit quaternion has a bug, and
    silently normalising it would hide it (ROS messages are expected to be normalised).

    Parameters
    ----------
    q_xyzw : array_like
        Quaternion, ROS order (x, y, z, w), 4 components.
    unit_tol : float, default 1e-3
        Largest accepted |norm - 1|.

    Returns
    -------
    numpy.ndarray
        The unit quaternion (x, y, z, w), shape (4,).

    Raises
    ------
    QuaternionError
        With the reason: not 4 components, NaN/inf, zero, or not unit within ``unit_tol``.

    """
    q = np.asarray(q_xyzw, dtype=float).reshape(-1)
    if q.shape != (4,):
        raise QuaternionError(f'quaternion must have 4 components, got {q.shape[0]}')
    if not np.all(np.isfinite(q)):
        raise QuaternionError('quaternion has NaN or inf components')
    scale = float(np.max(np.abs(q)))
    if scale > 1e6:  # far from unit; also keeps the sum of squares below overflow
        raise QuaternionError(f'quaternion is not unit (largest component {scale:.3g})')
    n = float(np.linalg.norm(q))
    if n < 1e-12:
        raise QuaternionError('quaternion is zero')
    if abs(n - 1.0) > unit_tol:
        raise QuaternionError(f'quaternion is not unit (norm {n:.6f}, tolerance {unit_tol})')
    return q / n


def quat_to_matrix(q_xyzw):
    """
    Convert unit quaternion(s) (x, y, z, w) to rotation matrices.

    The standard active rotation (child -> parent); vectorised over leading axes.

    Parameters
    ----------
    q_xyzw : array_like
        Unit quaternion(s), ROS order (x, y, z, w), shape (..., 4).

    Returns
    -------
    numpy.ndarray
        Rotation matrices, shape (..., 3, 3).

    """
    q = np.asarray(q_xyzw, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def matrix_to_quat(R):
    """
    Convert one rotation matrix to a unit quaternion (x, y, z, w) with w >= 0.

    Shepperd's method: the pivot is the largest of the trace and the diagonal, so no division by a
    small number.

    Parameters
    ----------
    R : array_like
        Rotation matrix, shape (3, 3).

    Returns
    -------
    numpy.ndarray
        Unit quaternion (x, y, z, w), shape (4,), with w >= 0.

    References
    ----------
    .. [1] S. W. Shepperd, "Quaternion from rotation matrix", Journal of Guidance and Control 1(3),
       pp. 223-224, 1978.

    """
    m = np.asarray(R, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def yaw_enu_quaternion(yaw_enu_rad):
    """
    Build the quaternion (x, y, z, w) of a pure REP-103 yaw (roll = pitch = 0).

    Parameters
    ----------
    yaw_enu_rad : float
        REP-103 yaw [rad], counter-clockwise from East.

    Returns
    -------
    numpy.ndarray
        Unit quaternion (x, y, z, w), shape (4,).

    """
    return np.array([0.0, 0.0, math.sin(yaw_enu_rad / 2), math.cos(yaw_enu_rad / 2)])


#: Camera mounted looking up, camera +y along body +x (forward), camera +x along body -y (right).
#: Columns are the camera axes expressed in the body frame: R_body_cam @ v_cam = v_body.
R_BODY_CAM_DEFAULT = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------------------------
# Body <-> camera attitude (R_enu_cam = R_enu_body @ R_body_cam)
# --------------------------------------------------------------------------------------------
def camera_attitude_from_body_quat(
    q_enu_body_xyzw, R_body_cam=R_BODY_CAM_DEFAULT
) -> CameraAttitude:
    """
    Compute the eq 21 camera attitude of a body orientation.

    The attitude of ``R_enu_cam = R_enu_body @ R_body_cam``.

    Parameters
    ----------
    q_enu_body_xyzw : array_like
        Quaternion (x, y, z, w) of the body in ENU (REP-103, what an IMU publishes).
    R_body_cam : array_like, default R_BODY_CAM_DEFAULT
        Mounting, shape (3, 3): the camera axes expressed in the body frame.

    Returns
    -------
    CameraAttitude
        Bearing of camera +y [deg, clockwise from North], pitch and roll [deg] (eq 21).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    R_enu_cam = quat_to_matrix(np.asarray(q_enu_body_xyzw, dtype=float)) @ np.asarray(
        R_body_cam, dtype=float
    )
    return attitude_from_R_enu_cam(R_enu_cam)


def R_enu_body_from_camera_attitude(
    att: CameraAttitude, R_body_cam=R_BODY_CAM_DEFAULT
) -> np.ndarray:
    """
    Compute ``R_enu_body = R_enu_cam @ R_body_cam^T`` of a camera attitude.

    The inverse of :func:`camera_attitude_from_body_quat`.

    Parameters
    ----------
    att : CameraAttitude
        Eq 21 bearing, pitch and roll [deg].
    R_body_cam : array_like, default R_BODY_CAM_DEFAULT
        Mounting, shape (3, 3): the camera axes expressed in the body frame.

    Returns
    -------
    numpy.ndarray
        Rotation (3, 3) mapping body-frame vectors into ENU.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    R_enu_cam = R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg)
    return R_enu_cam @ np.asarray(R_body_cam, dtype=float).T


def body_quat_from_camera_attitude(
    att: CameraAttitude, R_body_cam=R_BODY_CAM_DEFAULT
) -> np.ndarray:
    """
    Compute the body quaternion (x, y, z, w) in ENU of a camera attitude (w >= 0).

    The quaternion of :func:`R_enu_body_from_camera_attitude`.

    Parameters
    ----------
    att : CameraAttitude
        Eq 21 bearing, pitch and roll [deg].
    R_body_cam : array_like, default R_BODY_CAM_DEFAULT
        Mounting, shape (3, 3): the camera axes expressed in the body frame.

    Returns
    -------
    numpy.ndarray
        Unit quaternion (x, y, z, w) of the body in ENU, shape (4,), w >= 0.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    return matrix_to_quat(R_enu_body_from_camera_attitude(att, R_body_cam))


# --------------------------------------------------------------------------------------------
# Angle of polarization <-> E-vector (camera frame)
# --------------------------------------------------------------------------------------------
def aop_from_evector_cam_rad(e_cam):
    """
    Compute the AoP ``atan2(E_x, E_y)`` of camera-frame E-vector(s), eq 28.

    The angle of the E-vector projected on the sensor x-y plane, from +y_cam towards +x_cam.

    Parameters
    ----------
    e_cam : array_like
        E-vector(s) in the camera frame, shape (..., 3), any length and sign (axial).

    Returns
    -------
    numpy.ndarray
        AoP [rad] in [-pi/2, pi/2), shape (...).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28.

    """
    e = np.asarray(e_cam)
    return fold_aop_rad(np.arctan2(e[..., 0], e[..., 1]))


def evector_cam_from_aop(aop_rad, rays_cam):
    """
    Lift AoP to unit 3-D E-vectors perpendicular to each pixel's ray (camera frame).

    The inverse of eq 28. The sensor measures the orthographic projection of E on its x-y plane, so
    E = (sin a, cos a, e_z) up to scale with E . r = 0. Multiplying through by r_z avoids dividing
    by it (fisheye rays near 90 deg off-axis): E ~ (r_z sin a, r_z cos a, -(r_x sin a + r_y cos
    a)).

    Parameters
    ----------
    aop_rad : array_like
        AoP [rad] in the eq 28 convention, shape (...).
    rays_cam : array_like
        Viewing rays of the pixels in the camera frame, shape (..., 3), any length.

    Returns
    -------
    numpy.ndarray
        Unit E-vectors in the camera frame, shape (..., 3).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28.

    """
    a = np.asarray(aop_rad)
    r = np.asarray(rays_cam)
    sa, ca = np.sin(a), np.cos(a)
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    e = np.stack([rz * sa, rz * ca, -(rx * sa + ry * ca)], axis=-1)
    n = np.linalg.norm(e, axis=-1, keepdims=True)
    return e / np.maximum(n, np.finfo(e.dtype).tiny)


# --------------------------------------------------------------------------------------------
# Photodiode-array units (POL-OP): viewing direction and polarizer angles -> body frame
# --------------------------------------------------------------------------------------------
#: What a unit's 0 deg polarizer is parallel to: its local meridian (the great circle through the
#: zenith and the unit's axis) or the horizon (the horizontal direction perpendicular to the axis).
ANGLE_ZEROS = ('meridian', 'horizontal')
#: Sense of increasing polarizer angle as seen looking out along the unit's axis (from the sensor
#: towards the sky): ``cw`` is a right-handed (positive) rotation about the axis.
ANGLE_SENSES = ('cw', 'ccw')


def unit_axis_body(azimuth_deg, elevation_deg):
    """
    Compute the viewing axis of a photodiode unit in the REP-103 body frame.

    A level body with its front at true bearing B sees along compass azimuth ``B + azimuth_deg`` at
    altitude ``elevation_deg``.

    Parameters
    ----------
    azimuth_deg : float or array_like
        Azimuth of the axis [deg], clockwise from the body's front seen from above (90 = the body's
        right, -y).
    elevation_deg : float or array_like
        Elevation of the axis [deg] above the body's x-y plane.

    Returns
    -------
    numpy.ndarray
        Unit vector(s) in the body frame (x forward, y left, z up), shape (..., 3).

    """
    a, e = np.broadcast_arrays(
        np.radians(np.asarray(azimuth_deg, dtype=float)),
        np.radians(np.asarray(elevation_deg, dtype=float)),
    )
    return np.stack([np.cos(e) * np.cos(a), -np.cos(e) * np.sin(a), np.sin(e)], axis=-1)


def unit_polarizer_frame_body(azimuth_deg, elevation_deg, angle_zero='meridian', angle_sense='cw'):
    """
    Compute the (zero, quarter) directions spanning a unit's polarizer plane, body frame.

    A polarizer at angle theta transmits along ``cos(theta) zero + sin(theta) quarter``. ``zero``
    is the local meridian's tangent pointing up (towards the zenith) for ``angle_zero="meridian"``,
    or the horizontal direction on the unit's right (seen looking out along the axis) for
    ``"horizontal"``; ``quarter`` is ``zero`` turned by +90 deg in ``angle_sense`` (``cw``: a
    right-handed rotation about the axis, ``quarter = axis x zero``). The meridian tangent is
    ``(-sin e * h, cos e)`` with h the unit's horizontal azimuth direction (the paper's eq 16
    meridian tangent): continuous up to a unit looking at the zenith, whose meridian is then its
    azimuth's vertical plane (so ``azimuth_deg`` orients a zenith unit).

    Parameters
    ----------
    azimuth_deg : float or array_like
        Azimuth of the unit's axis [deg], clockwise from the body's front seen from above.
    elevation_deg : float or array_like
        Elevation of the unit's axis [deg] above the body's x-y plane.
    angle_zero : {"meridian", "horizontal"}, default "meridian"
        What the 0 deg polarizer is parallel to (:data:`ANGLE_ZEROS`).
    angle_sense : {"cw", "ccw"}, default "cw"
        Sense of increasing polarizer angle looking out along the axis (:data:`ANGLE_SENSES`).

    Returns
    -------
    zero : numpy.ndarray
        Unit direction of the 0 deg polarizer, body frame, shape (..., 3).
    quarter : numpy.ndarray
        Unit direction of the 90 deg polarizer, body frame, shape (..., 3).

    Raises
    ------
    ValueError
        ``angle_zero`` or ``angle_sense`` is not one of the allowed values.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 16 (meridian tangent)
       and 17 (horizontal direction).

    """
    if angle_zero not in ANGLE_ZEROS:
        raise ValueError(f'angle_zero must be one of {ANGLE_ZEROS}, got {angle_zero!r}')
    if angle_sense not in ANGLE_SENSES:
        raise ValueError(f'angle_sense must be one of {ANGLE_SENSES}, got {angle_sense!r}')
    a, e = np.broadcast_arrays(
        np.radians(np.asarray(azimuth_deg, dtype=float)),
        np.radians(np.asarray(elevation_deg, dtype=float)),
    )
    axis = unit_axis_body(azimuth_deg, elevation_deg)
    h = np.stack(
        [np.cos(a), -np.sin(a), np.zeros_like(a)], axis=-1
    )  # horizontal, along the azimuth
    up = np.concatenate([-np.sin(e)[..., None] * h[..., :2], np.cos(e)[..., None]], axis=-1)
    right = np.cross(
        axis, up
    )  # looking out along the axis with the zenith up: the right-hand side
    zero = up if angle_zero == 'meridian' else right
    quarter = np.cross(axis, zero)  # +90 deg, right-handed about the axis (clockwise looking out)
    if angle_sense == 'ccw':
        quarter = -quarter
    return zero, quarter


def unit_evector_body(
    angle_rad, azimuth_deg, elevation_deg, angle_zero='meridian', angle_sense='cw'
):
    """
    Compute the unit E-vector, body frame, of light at a polarizer angle of a unit.

    The inverse of :func:`unit_angle_from_evector_body_rad` (axial: E and -E are the same
    polarization). A unit at elevation 90 deg, azimuth 0, ``angle_zero="meridian"``,
    ``angle_sense="ccw"`` measures the camera's eq 28 AoP of the default mounting
    (:data:`R_BODY_CAM_DEFAULT`).

    Parameters
    ----------
    angle_rad : float or array_like
        Polarization angle [rad] in the unit's polarizer angles.
    azimuth_deg : float or array_like
        Azimuth of the unit's axis [deg], clockwise from the body's front seen from above.
    elevation_deg : float or array_like
        Elevation of the unit's axis [deg] above the body's x-y plane.
    angle_zero : {"meridian", "horizontal"}, default "meridian"
        What the 0 deg polarizer is parallel to.
    angle_sense : {"cw", "ccw"}, default "cw"
        Sense of increasing polarizer angle looking out along the axis.

    Returns
    -------
    numpy.ndarray
        Unit E-vector(s) in the body frame, shape (..., 3).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 15.

    """
    zero, quarter = unit_polarizer_frame_body(azimuth_deg, elevation_deg, angle_zero, angle_sense)
    t = np.asarray(angle_rad, dtype=float)[..., None]
    return np.cos(t) * zero + np.sin(t) * quarter


def unit_angle_from_evector_body_rad(
    e_body, azimuth_deg, elevation_deg, angle_zero='meridian', angle_sense='cw'
):
    """
    Compute the polarization angle a photodiode unit measures for body-frame E-vector(s).

    The angle of E projected on the unit's polarizer plane, ``atan2(E . quarter, E . zero)``.

    Parameters
    ----------
    e_body : array_like
        E-vector(s) in the body frame, shape (..., 3), any length and sign (axial).
    azimuth_deg : float or array_like
        Azimuth of the unit's axis [deg], clockwise from the body's front seen from above.
    elevation_deg : float or array_like
        Elevation of the unit's axis [deg] above the body's x-y plane.
    angle_zero : {"meridian", "horizontal"}, default "meridian"
        What the 0 deg polarizer is parallel to.
    angle_sense : {"cw", "ccw"}, default "cw"
        Sense of increasing polarizer angle looking out along the axis.

    Returns
    -------
    numpy.ndarray
        Polarization angle [rad] in [-pi/2, pi/2), shape (...).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 15 (the inverse of the
       decomposition).

    """
    zero, quarter = unit_polarizer_frame_body(azimuth_deg, elevation_deg, angle_zero, angle_sense)
    e = np.asarray(e_body, dtype=float)
    return fold_aop_rad(np.arctan2(np.sum(e * quarter, axis=-1), np.sum(e * zero, axis=-1)))
