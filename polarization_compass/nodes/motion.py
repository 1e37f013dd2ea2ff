"""The simulator's built-in motion profile (ROS-free): a turn at a constant rate with a pitch/roll
schedule, like the paper's field runs (Fig 17: a full turn at pitch -20 deg).

Camera attitude in the paper's terms (eq 21): ``bearing(t) = start + turn_rate * t`` (clockwise from
North, wrapped to [0, 360)), ``pitch(t) = pitch + pitch_amplitude * sin(2 pi t / period)``,
``roll(t) = roll + roll_amplitude * sin(2 pi t / period - pi / 2)`` (roll lags pitch by 90 deg, so a
run with both amplitudes sweeps a circle of tilts).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..conventions import R_BODY_CAM_DEFAULT, CameraAttitude, R_enu_cam_from_attitude, wrap_360_deg

__all__ = ["MotionProfile", "body_from_camera", "frame_times_ns"]


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


def body_from_camera(att: CameraAttitude, R_body_cam=R_BODY_CAM_DEFAULT) -> np.ndarray:
    """``R_enu_body`` of a camera attitude: ``R_enu_cam @ R_body_cam^T``."""
    return R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg) @ np.asarray(R_body_cam).T


def frame_times_ns(start_ns: int, rate_hz: float, total_s: float | None, k: int) -> int | None:
    """Stamp of frame ``k`` (``start + k / rate``), or None past the end of the run.

    Frames are at ``t = k / rate`` for ``0 <= t < total``: a full turn at 10 deg/s and 10 Hz is
    360 frames, bearings 0, 1, ..., 359 deg.
    """
    t_ns = int(start_ns) + int(round(k * 1e9 / rate_hz))
    if total_s is not None and (t_ns - start_ns) >= total_s * 1e9 - 1:
        return None
    return t_ns
