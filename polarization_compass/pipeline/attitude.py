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
The IMU attitude history (samples by stamp, interpolated) and the camera tilt at a stamp.

The camera's tilt on the body (the ``mount:`` of its ``CAMERA.yaml``, :mod:`~..mount`) is composed
here, in :meth:`AttitudeBuffer.camera_tilt`, for every camera estimator fed by an IMU (the
``heading_estimator`` node, replay): the one place the body attitude meets the camera's mount.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from ..conventions import camera_attitude_from_body_quat, R_BODY_CAM_DEFAULT
from ..mount import mounted_attitude

__all__ = [
    'CameraTilt',
    'AttitudeBuffer',
]


# ------------------------------------------------------------------------------------------------
# Attitude history
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraTilt:
    """
    Hold the camera attitude (eq 21) at an image stamp and how it was obtained.

    Parameters
    ----------
    bearing_deg : float
        True bearing of camera +y [deg], clockwise from North.
    pitch_deg, roll_deg : float
        The paper's pitch alpha and roll beta [deg].
    gap_ns : int
        Distance [ns] from the image stamp to the nearest IMU sample used.
    interpolated : bool
        Interpolated between two samples (else the nearer sample).

    """

    bearing_deg: float
    pitch_deg: float
    roll_deg: float
    gap_ns: int  # distance to the nearest IMU sample used
    interpolated: bool


class AttitudeBuffer:
    """
    Keep recent body orientation samples and look them up at any stamp.

    Samples (stamp_ns, unit quaternion x, y, z, w of the body in ENU) are kept for ``keep_ns``
    behind the newest one. :meth:`at` interpolates (normalised linear interpolation, hemisphere
    aligned) between the samples either side of ``t`` when both are within ``tol_ns``; with one
    side only, the nearer sample within ``tol_ns``; otherwise None (stale or missing: the caller
    reports it, nothing is guessed).

    Time-line jumps: a sample more than ``keep_ns`` ahead of the newest is held aside until a
    second sample near it confirms the jump (one bad stamp far in the future must not evict every
    good sample); a sample more than ``keep_ns`` behind the newest is dropped (a late message),
    unless the newest is a lone sample (then that one was the outlier) or three such samples come
    in a row (the clock went back, e.g. a bag played again): then the buffer starts over from them.
    ``jumps_held``/``late_dropped``/``resets`` count these events.

    Parameters
    ----------
    keep_ns : int, default 10 s
        History kept behind the newest sample [ns].
    mount : Mount or None, optional
        The camera's tilt on the body (``CAMERA.yaml``'s ``mount:``), composed with the body's
        attitude by :meth:`camera_tilt`; None: the camera sits as ``R_body_cam`` says.

    """

    def __init__(self, keep_ns: int = 10_000_000_000, mount=None):
        import threading

        self.keep_ns = int(keep_ns)
        self.mount = mount
        self._lock = threading.Lock()  # nodes add from one thread and look up from another
        self._t: list[int] = []
        self._q: list[np.ndarray] = []
        self._ahead = None  # (stamp, q) of an unconfirmed jump ahead
        self._behind = 0
        self.out_of_order = 0
        self.jumps_held = 0
        self.late_dropped = 0
        self.resets = 0

    def __len__(self):
        return len(self._t)

    @property
    def newest_ns(self) -> int | None:
        """Stamp [ns] of the newest sample, or None when empty."""
        return self._t[-1] if self._t else None

    def add(self, t_ns: int, q_xyzw) -> None:
        """
        Add one orientation sample (thread-safe; see the class docstring for time-line jumps).

        Parameters
        ----------
        t_ns : int
            Stamp [ns].
        q_xyzw : array_like
            Unit quaternion (x, y, z, w) of the body in ENU (REP-103).

        """
        with self._lock:
            self._add(int(t_ns), np.asarray(q_xyzw, dtype=float))

    def _restart(self, samples) -> None:
        self._t = [t for t, _ in samples]
        self._q = [q for _, q in samples]
        self._ahead = None
        self._behind = 0
        self.resets += 1

    def _add(self, t_ns: int, q: np.ndarray) -> None:
        if self._t:
            newest = self._t[-1]
            if t_ns > newest + self.keep_ns:  # far ahead: confirm before trusting
                if self._ahead is not None and abs(t_ns - self._ahead[0]) <= self.keep_ns:
                    self._restart(sorted([self._ahead, (t_ns, q)], key=lambda x: x[0]))
                else:
                    self._ahead = (t_ns, q)
                    self.jumps_held += 1
                return
            if t_ns < newest - self.keep_ns:  # far behind
                self._behind += 1
                if len(self._t) == 1 or self._behind >= 3:
                    self._restart([(t_ns, q)])
                else:
                    self.late_dropped += 1
                return
        self._behind = 0
        self._ahead = None
        if self._t and t_ns < self._t[-1]:
            self.out_of_order += 1
            k = bisect.bisect_right(self._t, t_ns)
            self._t.insert(k, t_ns)
            self._q.insert(k, q)
        else:
            self._t.append(t_ns)
            self._q.append(q)
        cut = bisect.bisect_left(self._t, self._t[-1] - self.keep_ns)
        if cut > 0:
            del self._t[:cut]
            del self._q[:cut]

    def around(self, t_ns: int, tol_ns: int):
        """
        Find the samples either side of a stamp within a tolerance.

        Parameters
        ----------
        t_ns : int
            Stamp [ns].
        tol_ns : int
            Largest accepted distance [ns].

        Returns
        -------
        before : tuple or None
            ``(stamp_ns, q_xyzw)`` of the last sample at or before ``t_ns``; None when absent or
            further than ``tol_ns``.
        after : tuple or None
            ``(stamp_ns, q_xyzw)`` of the first sample after ``t_ns``, likewise.

        """
        k = bisect.bisect_right(self._t, t_ns)
        before = (
            (self._t[k - 1], self._q[k - 1]) if k > 0 and t_ns - self._t[k - 1] <= tol_ns else None
        )
        after = (
            (self._t[k], self._q[k]) if k < len(self._t) and self._t[k] - t_ns <= tol_ns else None
        )
        return before, after

    def at(self, t_ns: int, tol_ns: int, hold: bool = True):
        """
        Look up the body orientation at a stamp, interpolating between samples.

        Normalised linear interpolation of the quaternions, hemisphere aligned.

        Parameters
        ----------
        t_ns : int
            Stamp [ns].
        tol_ns : int
            Largest accepted distance [ns] to a sample.
        hold : bool, default True
            False (a reference heading, whose errors are the product): only a sample exactly at
            ``t_ns`` or an interpolation between samples on both sides within ``tol_ns``; never the
            nearer sample of one side (after a stream stopped, a held value is a wrong truth).

        Returns
        -------
        tuple or None
            ``(q_xyzw, gap_ns, interpolated)``: the unit quaternion of the body in ENU, the
            distance [ns] to the nearest sample used, and whether it was interpolated; None when no
            sample is within ``tol_ns``.

        """
        with self._lock:
            b, a = self.around(int(t_ns), int(tol_ns))
        if b is None and a is None:
            return None
        if b is not None and b[0] == t_ns:
            return b[1], 0, False
        if not hold and (a is None or b is None):
            return None
        if b is not None and a is None:
            return b[1], int(t_ns - b[0]), False
        if b is None:
            return a[1], int(a[0] - t_ns), False
        f = (t_ns - b[0]) / (a[0] - b[0])
        q0, q1 = b[1], a[1]
        if float(q0 @ q1) < 0:
            q1 = -q1
        q = (1.0 - f) * q0 + f * q1
        q = q / np.linalg.norm(q)  # |q| >= cos(half the angle between them) > 0
        return q, int(min(t_ns - b[0], a[0] - t_ns)), True

    def camera_tilt(
        self, t_ns: int, tol_ns: int, R_body_cam=R_BODY_CAM_DEFAULT
    ) -> CameraTilt | None:
        """
        Look up the eq 21 camera attitude at a stamp.

        Parameters
        ----------
        t_ns : int
            Stamp [ns].
        tol_ns : int
            Largest accepted distance [ns] to a sample.
        R_body_cam : array_like, default R_BODY_CAM_DEFAULT
            Mounting, (3, 3): the camera axes expressed in the body frame.

        Returns
        -------
        CameraTilt or None
            Bearing, pitch and roll [deg] of ``R_enu_body @ R_body_cam`` composed with the
            buffer's ``mount`` (:func:`~..mount.mounted_attitude`); None when no sample is within
            ``tol_ns``.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eq 21.

        """
        hit = self.at(t_ns, tol_ns)
        if hit is None:
            return None
        q, gap, interp = hit
        att = camera_attitude_from_body_quat(q, R_body_cam)
        if self.mount is not None:
            att = mounted_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg, self.mount)
        return CameraTilt(att.bearing_deg, att.pitch_deg, att.roll_deg, gap, interp)
