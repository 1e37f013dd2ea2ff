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
How a sensor sits on the body: its mount pitch and roll (the ``mount:`` section of a sensor file).

A sensor screwed onto a robot is rarely level with the body the IMU levels. Its tilt relative to
the body is given in the paper's terms (eq 21), with the body's default-mounted camera frame
(:data:`~.conventions.R_BODY_CAM_DEFAULT`: camera +y = body front, camera +x = body right) as the
reference: ``R_bodycam_sensorcam = Rx(pitch) @ Ry(roll)``. The sensor's attitude in the world is
the body's composed with it, :func:`R_enu_sensor_cam` -- the one place the two meet. A level body
(pitch = roll = 0) carrying a mounted sensor is therefore eq 21 with the mount's pitch and roll.

YAML (in an array geometry or a ``CAMERA.yaml``)::

    mount:
      pitch_deg: -4.1        # paper's alpha of the sensor relative to the body
      roll_deg: -2.0         # paper's beta
      pitch_sigma_deg: 0.3   # optional, written by calibrate-mount
      roll_sigma_deg: 0.3
      turns: 12              # optional record of the calibration: turns, samples,
                             # residual_before_deg, residual_after_deg, sigma_widened_by,
                             # recordings_used, recordings_left_out, method
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from .conventions import (
    attitude_from_R_enu_cam,
    CameraAttitude,
    enu_direction,
    R_BODY_CAM_DEFAULT,
    R_enu_cam_from_attitude,
    rot_x,
    rot_y,
)
from .errors import CompassError

__all__ = [
    'Mount',
    'MountError',
    'mount_from_dict',
    'mount_to_dict',
    'R_body_sensor',
    'R_enu_sensor_cam',
    'mounted_attitude',
    'camera_tilt_deg',
    'sun_sensor',
    'MAX_MOUNT_TILT_DEG',
]

#: a mount tilted more than this is a description error, not a tilt (deg)
MAX_MOUNT_TILT_DEG = 45.0
_NUMBER_KEYS = ('pitch_deg', 'roll_deg', 'pitch_sigma_deg', 'roll_sigma_deg')
_RECORD_KEYS = (
    'turns',
    'samples',
    'residual_before_deg',
    'residual_after_deg',
    'yaw_offsets_deg',
    'sigma_widened_by',
    'recordings_used',
    'recordings_left_out',
    'method',
)


class MountError(CompassError):
    """A ``mount:`` section that cannot be used."""


@dataclass(frozen=True)
class Mount:
    """
    Hold a sensor's tilt relative to the body, degrees (paper's alpha and beta, module doc).

    ``record`` keeps what the calibration wrote (turns, samples, residuals), passed through.
    """

    pitch_deg: float = 0.0
    roll_deg: float = 0.0
    pitch_sigma_deg: float | None = None
    roll_sigma_deg: float | None = None
    record: dict = field(default_factory=dict)

    @property
    def is_level(self) -> bool:
        """Return True when the mount adds no rotation."""
        return self.pitch_deg == 0.0 and self.roll_deg == 0.0


def _num(where: str, v, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise MountError(f'{where} must be a number, got {v!r}')
    v = float(v)
    if not math.isfinite(v) or not (lo <= v <= hi):
        raise MountError(f'{where} must be finite and in [{lo:g}, {hi:g}], got {v:g}')
    return v


def mount_from_dict(d, where: str = 'mount') -> Mount:
    """
    Validate a parsed ``mount:`` mapping.

    Parameters
    ----------
    d : dict
        The mapping (keys in the module docstring).
    where : str, optional
        Name of the source, for the error messages.

    Returns
    -------
    Mount
        The mount.

    Raises
    ------
    MountError
        One line naming the key that is missing, unknown or out of range.

    """
    if not isinstance(d, dict):
        raise MountError(f'{where} must be a mapping with pitch_deg and roll_deg')
    known = set(_NUMBER_KEYS) | set(_RECORD_KEYS)
    unknown = sorted(set(map(str, d)) - known)
    if unknown:
        raise MountError(
            f'{where}: unknown key(s) {", ".join(unknown)}; known: {", ".join(sorted(known))}'
        )
    for k in ('pitch_deg', 'roll_deg'):
        if k not in d:
            raise MountError(f'{where}: missing {k}')
    lim = MAX_MOUNT_TILT_DEG
    p = _num(f'{where}.pitch_deg', d['pitch_deg'], -lim, lim)
    r = _num(f'{where}.roll_deg', d['roll_deg'], -lim, lim)
    sig = [
        None if d.get(k) is None else _num(f'{where}.{k}', d[k], 0.0, 90.0)
        for k in ('pitch_sigma_deg', 'roll_sigma_deg')
    ]
    record = {k: d[k] for k in _RECORD_KEYS if k in d}
    return Mount(p, r, sig[0], sig[1], record)


def mount_to_dict(m: Mount) -> dict:
    """
    Return the YAML mapping of a mount (round-trips through :func:`mount_from_dict`).

    Parameters
    ----------
    m : Mount
        The mount.

    Returns
    -------
    dict
        ``pitch_deg``, ``roll_deg``, the sigmas when known, then the calibration record.

    """
    out = {'pitch_deg': float(m.pitch_deg), 'roll_deg': float(m.roll_deg)}
    if m.pitch_sigma_deg is not None:
        out['pitch_sigma_deg'] = float(m.pitch_sigma_deg)
    if m.roll_sigma_deg is not None:
        out['roll_sigma_deg'] = float(m.roll_sigma_deg)
    out.update(m.record)
    return out


def _R_cam_sensor(pitch_deg, roll_deg) -> np.ndarray:
    """Return ``Rx(pitch) @ Ry(roll)``: the sensor's camera axes in the body's camera frame."""
    return rot_x(np.radians(pitch_deg)) @ rot_y(np.radians(roll_deg))


def R_body_sensor(mount: Mount | None) -> np.ndarray:
    """
    Return the rotation from the sensor's body-like frame to the body frame (REP-103).

    Parameters
    ----------
    mount : Mount or None
        The mount (None: level, the identity).

    Returns
    -------
    numpy.ndarray
        (3, 3) ``R_BODY_CAM @ Rx(pitch) Ry(roll) @ R_BODY_CAM^T``: columns are the sensor's front,
        left and up axes expressed in the body frame.

    """
    if mount is None or mount.is_level:
        return np.eye(3)
    R = _R_cam_sensor(mount.pitch_deg, mount.roll_deg)
    return R_BODY_CAM_DEFAULT @ R @ R_BODY_CAM_DEFAULT.T


def R_enu_sensor_cam(bearing_deg, pitch_deg, roll_deg, mount: Mount | None) -> np.ndarray:
    """
    Compose the body attitude with the mount: the sensor's camera-frame-to-ENU rotation.

    ``R_enu_cam_from_attitude(bearing, pitch, roll) @ Rx(mount pitch) @ Ry(mount roll)``.

    Parameters
    ----------
    bearing_deg : float or array_like
        True bearing of the body's front [deg], clockwise from North.
    pitch_deg, roll_deg : float or array_like
        The body's pitch and roll [deg] (paper's alpha, beta; what the IMU says).
    mount : Mount or None
        The sensor's mount (None: level).

    Returns
    -------
    numpy.ndarray
        (..., 3, 3), broadcast over the angles.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    R = R_enu_cam_from_attitude(bearing_deg, pitch_deg, roll_deg)
    if mount is None or mount.is_level:
        return R
    return R @ _R_cam_sensor(mount.pitch_deg, mount.roll_deg)


def mounted_attitude(bearing_deg, pitch_deg, roll_deg, mount: Mount | None) -> CameraAttitude:
    """
    Return the eq 21 attitude of a mounted camera from its body's (a camera estimator's tilt).

    The decomposition of :func:`R_enu_sensor_cam`: the attitude a camera estimator needs is the
    camera's, the body's composed with the ``mount:`` of its ``CAMERA.yaml``. The pitch and roll do
    not depend on the bearing (``Rz(-bearing)`` multiplies from the left); the bearing of camera +y
    differs from the body's by a second-order amount (0.3 deg for 4 deg of body and of mount
    pitch and roll alike).

    Parameters
    ----------
    bearing_deg : float
        True bearing of the body's front [deg] (0 when only the tilt is wanted).
    pitch_deg, roll_deg : float
        The body's pitch and roll [deg] (paper's alpha, beta: the IMU's, ``--pitch/--roll``).
    mount : Mount or None
        The camera's mount (None or level: the body's attitude is returned unchanged).

    Returns
    -------
    CameraAttitude
        Bearing of camera +y, pitch and roll [deg] of the mounted camera (eq 21).

    """
    if mount is None or mount.is_level:
        return CameraAttitude(float(bearing_deg), float(pitch_deg), float(roll_deg))
    return attitude_from_R_enu_cam(R_enu_sensor_cam(bearing_deg, pitch_deg, roll_deg, mount))


def camera_tilt_deg(pitch_deg, roll_deg, mount: Mount | None) -> tuple:
    """
    Return a mounted camera's pitch and roll from its body's, when the body's are known.

    :func:`mounted_attitude` for callers that hold only the tilt (``estimate --pitch/--roll``).

    Parameters
    ----------
    pitch_deg, roll_deg : float or None
        The body's pitch and roll [deg]; None: not known.
    mount : Mount or None
        The camera's mount.

    Returns
    -------
    tuple
        ``(pitch_deg, roll_deg)`` of the camera [deg]; ``(None, None)`` when the body's tilt is not
        known (a mount alone does not give the camera's tilt), the inputs without a mount.

    """
    if pitch_deg is None or roll_deg is None:
        return None, None
    att = mounted_attitude(0.0, pitch_deg, roll_deg, mount)
    return att.pitch_deg, att.roll_deg


def sun_sensor(
    sun_azimuth_deg, sun_altitude_deg, bearing_deg, pitch_deg, roll_deg, mount: Mount | None
) -> np.ndarray:
    """
    Return the sun direction in the sensor's body-like frame (REP-103 axes of the sensor).

    Parameters
    ----------
    sun_azimuth_deg, sun_altitude_deg : float or array_like
        The sun [deg], azimuth clockwise from true North.
    bearing_deg : float or array_like
        True bearing of the body's front [deg].
    pitch_deg, roll_deg : float or array_like
        The body's pitch and roll [deg].
    mount : Mount or None
        The sensor's mount.

    Returns
    -------
    numpy.ndarray
        (..., 3) unit sun vector(s); the body frame when the mount is level.

    """
    R = R_enu_sensor_cam(bearing_deg, pitch_deg, roll_deg, mount) @ R_BODY_CAM_DEFAULT.T
    s = enu_direction(sun_azimuth_deg, sun_altitude_deg)
    return np.einsum('...ji,...j->...i', R, s)
