"""The simulator's built-in motion profile (ROS-free): a turn at a constant rate with a pitch/roll
schedule, like the paper's field runs (Fig 17: a full turn at pitch -20 deg), and the simulated IMU's
reading of the body attitude (:func:`imu_reading`). Shared by the ``sky_simulator`` node and ``record-sim``.

Camera attitude in the paper's terms (eq 21): ``bearing(t) = start + turn_rate * t`` (clockwise from
North, wrapped to [0, 360)), ``pitch(t) = pitch + pitch_amplitude * sin(2 pi t / period)``,
``roll(t) = roll + roll_amplitude * sin(2 pi t / period - pi / 2)`` (roll lags pitch by 90 deg, so a
run with both amplitudes sweeps a circle of tilts).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .conventions import CameraAttitude, rot_x, rot_y, rot_z, wrap_360_deg

__all__ = ["MotionProfile", "frame_times_ns", "imu_reading"]


@dataclass(frozen=True)
class MotionProfile:
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
        w = 2.0 * math.pi * t_s / self.tilt_period_s
        return CameraAttitude(float(wrap_360_deg(self.start_bearing_deg + self.turn_rate_deg_s * t_s)),
                              self.pitch_deg + self.pitch_amplitude_deg * math.sin(w),
                              self.roll_deg + self.roll_amplitude_deg * math.sin(w - math.pi / 2))

    def total_s(self) -> float | None:
        """Length of the run in simulated seconds; None = until stopped."""
        if self.duration_s > 0:
            return float(self.duration_s)
        if self.turns > 0 and self.turn_rate_deg_s != 0:
            return self.turns * 360.0 / abs(self.turn_rate_deg_s)
        return None

    def yaw_rate_enu_rad_s(self) -> float:
        """REP-103 yaw rate (counter-clockwise positive) of the turn."""
        return -math.radians(self.turn_rate_deg_s)


def frame_times_ns(start_ns: int, rate_hz: float, total_s: float | None, k: int) -> int | None:
    """Stamp of frame ``k`` (``start + k / rate``), or None past the end of the run.

    Frames are at ``t = k / rate`` for ``0 <= t < total``: a full turn at 10 deg/s and 10 Hz is
    360 frames, bearings 0, 1, ..., 359 deg.
    """
    t_ns = int(start_ns) + int(round(k * 1e9 / rate_hz))
    if total_s is not None and (t_ns - start_ns) >= total_s * 1e9 - 1:
        return None
    return t_ns


def imu_reading(R_enu_body, normals, attitude_noise_deg: float, yaw_noise_deg: float, yaw_bias_deg: float,
                roll_bias_deg: float = 0.0, pitch_bias_deg: float = 0.0):
    """The simulated IMU's orientation of a body attitude, and the variances it reports.

    ``normals``: three standard normal draws (roll, pitch, yaw). Roll and pitch errors (bias + noise x
    draw, deg) rotate about body x and y, the yaw error about ENU z:
    ``R_meas = Rz(d_yaw) @ R_enu_body @ Ry(d_pitch) @ Rx(d_roll)``. Reported variances (rad^2, floored
    at 1e-12): roll = pitch = (noise and the larger roll/pitch bias in quadrature)^2, yaw = (yaw noise
    and yaw bias in quadrature)^2. Returns ``(R_meas, (var_roll, var_pitch, var_yaw))``.
    """
    d_roll = math.radians(roll_bias_deg + attitude_noise_deg * normals[0])
    d_pitch = math.radians(pitch_bias_deg + attitude_noise_deg * normals[1])
    d_yaw = math.radians(yaw_bias_deg + yaw_noise_deg * normals[2])
    R = rot_z(d_yaw) @ R_enu_body @ rot_y(d_pitch) @ rot_x(d_roll)
    var_rp = max(math.radians(math.hypot(attitude_noise_deg, max(abs(roll_bias_deg), abs(pitch_bias_deg)))) ** 2,
                 1e-12)
    var_y = max(math.radians(math.hypot(yaw_noise_deg, yaw_bias_deg)) ** 2, 1e-12)
    return R, (var_rp, var_rp, var_y)
