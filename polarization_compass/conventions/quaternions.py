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
Quaternions (ROS order x, y, z, w; active rotation child -> parent) and the body-camera mounting.

Body <-> camera attitude: ``R_enu_cam = R_enu_body @ R_body_cam`` (:data:`R_BODY_CAM_DEFAULT`).
"""

from __future__ import annotations

import math

import numpy as np

from .rotations import attitude_from_R_enu_cam, CameraAttitude, R_enu_cam_from_attitude
from ..errors import CompassError


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
