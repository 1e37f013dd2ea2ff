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
Rotations: standard right-handed elementary rotations (vectorised over angle arrays), eq 21.

The camera attitude (bearing or psi, pitch, roll) to ``R_sun_cam``/``R_enu_cam`` and back
(:class:`CameraAttitude`, flagged at gimbal lock).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .angles import wrap_360_deg


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
