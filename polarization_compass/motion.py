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
The simulator's built-in motion profile and simulated IMU (ROS-free).

The profile is a turn at a constant rate with a pitch/roll schedule, like the paper's field runs
(Fig 17: a full turn at pitch -20 deg); the IMU gives its reading of the body attitude
(:func:`imu_reading`). Shared by the ``sky_simulator`` node and ``record-sim``.

Camera attitude in the paper's terms (eq 21): ``bearing(t) = start + turn_rate * t`` (clockwise
from North, wrapped to [0, 360)), ``pitch(t) = pitch + pitch_amplitude * sin(2 pi t / period)``,
``roll(t) = roll + roll_amplitude * sin(2 pi t / period - pi / 2)`` (roll lags pitch by 90 deg, so
a run with both amplitudes sweeps a circle of tilts).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from .conventions import (
    attitude_from_R_enu_cam,
    CameraAttitude,
    R_enu_cam_from_attitude,
    rot_x,
    rot_y,
    rot_z,
    wrap_360_deg,
)

__all__ = ['MotionProfile', 'frame_times_ns', 'imu_reading', 'MountingErrors']


@dataclass(frozen=True)
class MotionProfile:
    """
    Describe the simulator's built-in motion: a turn at a constant rate with a tilt schedule.

    ``bearing(t) = start + turn_rate * t`` (wrapped to [0, 360)),
    ``pitch(t) = pitch + pitch_amplitude * sin(2 pi t / period)``,
    ``roll(t) = roll + roll_amplitude * sin(2 pi t / period - pi / 2)``.

    Parameters
    ----------
    start_bearing_deg : float, default 0
        Bearing of camera +y at t = 0 [deg], clockwise from North.
    turn_rate_deg_s : float, default 10
        Turn rate [deg/s], clockwise positive.
    pitch_deg, roll_deg : float, default -20 and 0
        Mean camera pitch alpha and roll beta [deg] (eq 21).
    pitch_amplitude_deg, roll_amplitude_deg : float, default 0
        Amplitudes [deg] of the sinusoidal tilt schedule (roll lags pitch by 90 deg).
    tilt_period_s : float, default 20
        Period [s] of the tilt schedule.
    turns : float, default 1
        Length of the run in turns, when ``duration_s`` is 0; 0 with no duration: until stopped.
    duration_s : float, default 0
        Length of the run [s]; 0 to use ``turns``.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21 (pitch alpha, roll
       beta) and Fig 17 (a full turn at pitch -20 deg).

    """

    start_bearing_deg: float = 0.0
    turn_rate_deg_s: float = 10.0
    pitch_deg: float = -20.0
    roll_deg: float = 0.0
    pitch_amplitude_deg: float = 0.0
    roll_amplitude_deg: float = 0.0
    tilt_period_s: float = 20.0
    turns: float = 1.0
    duration_s: float = 0.0

    def attitude(self, t_s: float) -> CameraAttitude:
        """
        Return the camera attitude at simulated time ``t_s``.

        Parameters
        ----------
        t_s : float
            Time since the start of the run [s].

        Returns
        -------
        CameraAttitude
            Bearing [deg] in [0, 360), pitch and roll [deg] (eq 21).

        """
        w = 2.0 * math.pi * t_s / self.tilt_period_s
        return CameraAttitude(
            float(wrap_360_deg(self.start_bearing_deg + self.turn_rate_deg_s * t_s)),
            self.pitch_deg + self.pitch_amplitude_deg * math.sin(w),
            self.roll_deg + self.roll_amplitude_deg * math.sin(w - math.pi / 2),
        )

    def total_s(self) -> float | None:
        """
        Return the length of the run in simulated seconds.

        Returns
        -------
        float or None
            ``duration_s`` if set, else ``turns`` turns at the turn rate [s]; None = until stopped.

        """
        if self.duration_s > 0:
            return float(self.duration_s)
        if self.turns > 0 and self.turn_rate_deg_s != 0:
            return self.turns * 360.0 / abs(self.turn_rate_deg_s)
        return None

    def yaw_rate_enu_rad_s(self) -> float:
        """
        Return the REP-103 yaw rate of the turn (counter-clockwise positive).

        Returns
        -------
        float
            Yaw rate about ENU z [rad/s]: minus the clockwise turn rate.

        """
        return -math.radians(self.turn_rate_deg_s)


def frame_times_ns(start_ns: int, rate_hz: float, total_s: float | None, k: int) -> int | None:
    """
    Return the stamp of frame ``k`` (``start + k / rate``), or None past the end of the run.

    Frames are at ``t = k / rate`` for ``0 <= t < total``: a full turn at 10 deg/s and 10 Hz is
    360 frames, bearings 0, 1, ..., 359 deg.

    Parameters
    ----------
    start_ns : int
        Stamp of frame 0 [ns].
    rate_hz : float
        Frame rate [Hz], > 0.
    total_s : float or None
        Length of the run [s] (:meth:`MotionProfile.total_s`); None = no end.
    k : int
        Frame index, >= 0.

    Returns
    -------
    int or None
        The stamp [ns], or None when frame ``k`` is at or past the end.

    """
    t_ns = int(start_ns) + int(round(k * 1e9 / rate_hz))
    if total_s is not None and (t_ns - start_ns) >= total_s * 1e9 - 1:
        return None
    return t_ns


def imu_reading(
    R_enu_body,
    normals,
    attitude_noise_deg: float,
    yaw_noise_deg: float,
    yaw_bias_deg: float,
    roll_bias_deg: float = 0.0,
    pitch_bias_deg: float = 0.0,
):
    """
    Return the simulated IMU's orientation of a body attitude and the variances it reports.

    Roll and pitch errors (bias + noise x draw) rotate about body x and y, the yaw error about ENU
    z: ``R_meas = Rz(d_yaw) @ R_enu_body @ Ry(d_pitch) @ Rx(d_roll)``.

    Parameters
    ----------
    R_enu_body : numpy.ndarray
        (3, 3) true rotation, body (REP-103 base_link) to ENU.
    normals : sequence of float
        Three standard normal draws (roll, pitch, yaw).
    attitude_noise_deg : float
        Roll/pitch white noise [deg], 1 sigma.
    yaw_noise_deg : float
        Yaw white noise [deg], 1 sigma.
    yaw_bias_deg : float
        Yaw bias [deg].
    roll_bias_deg, pitch_bias_deg : float, default 0
        Roll and pitch biases [deg].

    Returns
    -------
    R_meas : numpy.ndarray
        (3, 3) measured rotation, body to ENU.
    variances : tuple of float
        ``(var_roll, var_pitch, var_yaw)`` [rad^2], floored at 1e-12: roll = pitch = (noise and the
        larger roll/pitch bias in quadrature)^2, yaw = (yaw noise and yaw bias in quadrature)^2.

    """
    d_roll = math.radians(roll_bias_deg + attitude_noise_deg * normals[0])
    d_pitch = math.radians(pitch_bias_deg + attitude_noise_deg * normals[1])
    d_yaw = math.radians(yaw_bias_deg + yaw_noise_deg * normals[2])
    R = rot_z(d_yaw) @ R_enu_body @ rot_y(d_pitch) @ rot_x(d_roll)
    var_rp = max(
        math.radians(math.hypot(attitude_noise_deg, max(abs(roll_bias_deg), abs(pitch_bias_deg))))
        ** 2,
        1e-12,
    )
    var_y = max(math.radians(math.hypot(yaw_noise_deg, yaw_bias_deg)) ** 2, 1e-12)
    return R, (var_rp, var_rp, var_y)


@dataclass(frozen=True)
class MountingErrors:
    """
    Describe what the tilt correction is told about the camera's pitch and roll.

    Against the truth: the errors of the camera-to-IMU mounting and of the IMU (all zero = a
    perfect IMU). Pitch and roll are the paper's (eq 21, ``R = Rz(-bearing) Rx(pitch) Ry(roll)``):
    rotations about camera x and y, so ``B = Rz(yaw) Rx(pitch) Ry(roll)`` and the noise and bias
    rotate by ``Rx(d_pitch) Ry(d_roll)`` on the right; for a level camera a pitch bias b reads
    pitch b, a boresight pitch p reads pitch -p.

    Parameters
    ----------
    noise_deg : float, default 0
        IMU pitch/roll white noise per reading [deg], 1 sigma.
    pitch_bias_deg, roll_bias_deg : float, default 0
        IMU tilt biases [deg].
    boresight_roll_deg, boresight_pitch_deg, boresight_yaw_deg : float, default 0
        The camera is mounted rotated by ``B`` (camera axes) from where the IMU-to-camera
        calibration says, so the attitude derived from the IMU is ``R_enu_cam_true @ B^T``
        (boresight misalignment) [deg].
    time_offset_s : float, default 0
        The IMU sample belongs to this much later than the image [s] ...
    tilt_rate_deg_s : float, default 0
        ... during which the platform tilts at this rate [deg/s] in a random direction.

    Raises
    ------
    ValueError
        A field is not a finite number with absolute value <= 90.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """

    noise_deg: float = 0.0
    pitch_bias_deg: float = 0.0
    roll_bias_deg: float = 0.0
    boresight_roll_deg: float = 0.0
    boresight_pitch_deg: float = 0.0
    boresight_yaw_deg: float = 0.0
    time_offset_s: float = 0.0
    tilt_rate_deg_s: float = 0.0

    FIELDS = (
        'noise_deg',
        'pitch_bias_deg',
        'roll_bias_deg',
        'boresight_roll_deg',
        'boresight_pitch_deg',
        'boresight_yaw_deg',
        'time_offset_s',
        'tilt_rate_deg_s',
    )

    def __post_init__(self):
        for k in self.FIELDS:
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and abs(v) <= 90.0):
                raise ValueError(f'{k} must be a finite number with |{k}| <= 90, got {v!r}')

    @property
    def has_boresight(self) -> bool:
        """Whether any boresight angle is non-zero."""
        return any(
            getattr(self, k) != 0.0
            for k in ('boresight_roll_deg', 'boresight_pitch_deg', 'boresight_yaw_deg')
        )

    @property
    def has_imu(self) -> bool:
        """Whether any IMU error (noise, bias, or a time offset with a tilt rate) is non-zero."""
        return any(
            getattr(self, k) != 0.0 for k in ('noise_deg', 'pitch_bias_deg', 'roll_bias_deg')
        ) or (self.time_offset_s != 0.0 and self.tilt_rate_deg_s != 0.0)

    def tilt_sigma_deg(self, tilt_deg: float = 0.0) -> tuple:
        """
        Return the 1-sigma uncertainty of the measured pitch and roll these errors amount to.

        What a user who states these errors knows about the tilt a method is given, per axis in
        quadrature: the noise; the bias and the boresight angle of that axis, each taken as the
        1-sigma of an error of unknown sign (so a bias of exactly the stated size contributes
        ``err^2 / sigma^2 = 1``); the time-offset tilt ``tilt_rate * time_offset`` in a uniformly
        random direction (variance ``a^2 / 2`` per axis); and the boresight yaw, which turns the
        tilt vector of magnitude ``tilt_deg`` by that angle (``tilt * yaw [rad]``). Pitch and roll
        errors are taken as uncorrelated.

        Parameters
        ----------
        tilt_deg : float, default 0
            Magnitude of the camera's tilt [deg] (e.g. ``hypot(pitch, roll)`` as measured).

        Returns
        -------
        tuple of float
            ``(pitch_sigma_deg, roll_sigma_deg)`` [deg].

        """
        a2 = 0.5 * (self.tilt_rate_deg_s * self.time_offset_s) ** 2
        y2 = (abs(tilt_deg) * math.radians(self.boresight_yaw_deg)) ** 2
        n2 = self.noise_deg**2
        return (
            math.sqrt(n2 + self.pitch_bias_deg**2 + self.boresight_pitch_deg**2 + a2 + y2),
            math.sqrt(n2 + self.roll_bias_deg**2 + self.boresight_roll_deg**2 + a2 + y2),
        )

    def without(self, *groups: str) -> 'MountingErrors':
        """
        Return a copy with the ``boresight`` and/or ``imu`` errors set to zero.

        Parameters
        ----------
        *groups : {"boresight", "imu"}
            The error groups to remove (``imu``: noise, bias and time offset); other names are
        ignored.

        Returns
        -------
        MountingErrors
            The copy.

        """
        import dataclasses

        ch = {}
        if 'boresight' in groups:
            ch.update(boresight_roll_deg=0.0, boresight_pitch_deg=0.0, boresight_yaw_deg=0.0)
        if 'imu' in groups:
            ch.update(noise_deg=0.0, pitch_bias_deg=0.0, roll_bias_deg=0.0, time_offset_s=0.0)
        return dataclasses.replace(self, **ch)

    def measured_attitude(self, true: CameraAttitude, normals) -> CameraAttitude:
        """
        Return the camera attitude the pipeline derives from the IMU for the attitude ``true``.

        Parameters
        ----------
        true : CameraAttitude
            True bearing [deg], pitch and roll [deg] (eq 21).
        normals : sequence of float
            Three standard normal draws (roll noise, pitch noise, direction of the tilt during the
            time offset as the angle ``2 pi Phi(z)``); pass the same draws to compare error sources
            paired.

        Returns
        -------
        CameraAttitude
            The measured attitude: the time-offset tilt, then the boresight, then the IMU bias
            and noise applied.

        """
        R = R_enu_cam_from_attitude(true.bearing_deg, true.pitch_deg, true.roll_deg)
        if self.time_offset_s != 0.0 and self.tilt_rate_deg_s != 0.0:
            ang = math.radians(self.tilt_rate_deg_s * self.time_offset_s)
            direction = math.pi * (
                1.0 + math.erf(normals[2] / math.sqrt(2.0))
            )  # uniform in [0, 2 pi)
            R = R @ rot_x(ang * math.cos(direction)) @ rot_y(ang * math.sin(direction))
        if self.has_boresight:
            B = (
                rot_z(math.radians(self.boresight_yaw_deg))
                @ rot_x(math.radians(self.boresight_pitch_deg))
                @ rot_y(math.radians(self.boresight_roll_deg))
            )
            R = R @ B.T
        d_roll = math.radians(self.roll_bias_deg + self.noise_deg * normals[0])
        d_pitch = math.radians(self.pitch_bias_deg + self.noise_deg * normals[1])
        if d_roll or d_pitch:
            R = R @ rot_x(d_pitch) @ rot_y(d_roll)
        return attitude_from_R_enu_cam(R)
