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
Per-frame processing behind the nodes, ROS-free.

Per-frame processing behind the nodes, ROS-free: mosaic -> observation -> heading, the IMU history
the tilt and the ambiguity prior come from, and the sun per stamp.

The node classes in :mod:`polarization_compass.nodes` only move messages in and out of these
objects, so the same code runs wherever frames come from (a live camera, a bag, a test).

Frames: the IMU orientation is the body's (REP-103 base_link) in ENU; the camera is mounted by
``R_body_cam`` (default :data:`~polarization_compass.conventions.R_BODY_CAM_DEFAULT`: looking up,
camera +y = body +x), so the camera attitude of eq 21 is ``attitude_from_R_enu_cam(R_enu_body @
R_body_cam)`` and, with the default mounting, the REP-103 yaw of the body is ``90 deg - bearing``.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
import math

import numpy as np

from ..camera import CameraModel
from ..conventions import camera_attitude_from_body_quat, R_BODY_CAM_DEFAULT
from ..demosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45
from ..errors import CompassError

__all__ = [
    'AttitudeBuffer',
    'CameraTilt',
    'SunSource',
    'HeadingFrontEnd',
    'PipelineError',
    'warm_up',
    'TiltAndPrior',
    'FrameInputs',
    'CameraInfoState',
    'check_prior_agreement',
    'PRIOR_DISAGREES_N_SIGMA',
    'ImageLossWatch',
]


class PipelineError(CompassError):
    """A frame that cannot be processed (bad mosaic for this camera, unusable configuration)."""


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

    """

    def __init__(self, keep_ns: int = 10_000_000_000):
        import threading

        self.keep_ns = int(keep_ns)
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
            Bearing, pitch and roll [deg] of ``R_enu_body @ R_body_cam``; None when no sample is
            within ``tol_ns``.

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
        return CameraTilt(att.bearing_deg, att.pitch_deg, att.roll_deg, gap, interp)


# ------------------------------------------------------------------------------------------------
# Tilt and ambiguity prior per image
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FrameInputs:
    """
    Hold what one method gets with an image besides the pixels.

    Parameters
    ----------
    pitch_deg, roll_deg : float or None
        Camera pitch and roll [deg] (eq 21) for methods that need the tilt; else None.
    prior_bearing_deg : float or None
        Prior bearing of camera +y [deg, clockwise from North] that resolves the 180 deg ambiguity.
    tilt_missing : bool, default False
        The method needs the camera tilt and no IMU sample is near the image stamp (the frame is
        bad input for it).

    """

    pitch_deg: float | None
    roll_deg: float | None
    prior_bearing_deg: float | None
    tilt_missing: bool = False


class TiltAndPrior:
    """
    Make the per-image tilt and prior decisions of the ``heading_estimator`` node.

    Tilt (methods whose class ``needs_tilt``, e.g. ``tilt_aware``): pitch and roll of the IMU at
    the image stamp (``tilt``: the lookup within the IMU tolerance). Prior bearing of camera +y,
    which resolves the 180 deg ambiguity: ``prior_source`` ``imu``: the bearing of the IMU attitude
    nearest the stamp within ``prior_max_age_s`` (``imu_near``; its coarse yaw is enough to pick
    the sun's side); ``last``: this method's last resolved (not axial) heading when its stamp is
    within ``prior_max_age_s``; ``none``. An IMU prior is also a check (:meth:`checked`): a heading
    further from it than 3 combined sigmas (``prior_sigma_deg`` the IMU yaw's 1-sigma) is not
    ``ok``.

    Parameters
    ----------
    method : str
        Name of the method (:mod:`~polarization_compass.estimators.registry`).
    prior_source : {"imu", "last", "none"}, default "imu"
        Where the prior bearing comes from.
    prior_max_age_s : float, default 2
        Largest age [s] of the prior's source.
    prior_sigma_deg : float, default 15
        1-sigma [deg] of the IMU yaw, for :meth:`checked` (0: no check).

    """

    def __init__(
        self,
        method: str,
        prior_source: str = 'imu',
        prior_max_age_s: float = 2.0,
        prior_sigma_deg: float = 15.0,
    ):
        from ..estimators import registry

        cls = registry.find(method)
        self.needs_tilt = bool(cls is not None and cls.needs_tilt)
        self.prior_source = prior_source
        self.prior_max_age_s = float(prior_max_age_s)
        self.prior_sigma_deg = float(prior_sigma_deg)
        self.last_bearing = None  # (stamp_ns, bearing_deg) of the last resolved heading

    @property
    def needs_imu(self) -> bool:
        """Whether the IMU is read at all (tilt or prior)."""
        return self.needs_tilt or self.prior_source == 'imu'

    def lookups(
        self, imu: AttitudeBuffer, t_ns: int, tolerance_ns: int, R_body_cam=R_BODY_CAM_DEFAULT
    ):
        """
        Look up the tilt and the prior's attitude for :meth:`inputs` in an IMU history.

        Parameters
        ----------
        imu : AttitudeBuffer
            The body orientation history.
        t_ns : int
            Image stamp [ns].
        tolerance_ns : int
            Largest accepted distance [ns] of the tilt's IMU sample.
        R_body_cam : array_like, default R_BODY_CAM_DEFAULT
            Mounting, (3, 3): the camera axes expressed in the body frame.

        Returns
        -------
        tilt : CameraTilt or None
            The camera attitude at ``t_ns`` within ``tolerance_ns``; None when absent or not
            needed.
        imu_near : CameraTilt or None
            The camera attitude within ``prior_max_age_s``; None when absent or not needed.

        """
        if not len(imu):
            return None, None
        tilt = imu.camera_tilt(t_ns, tolerance_ns, R_body_cam) if self.needs_tilt else None
        near = (
            imu.camera_tilt(t_ns, int(self.prior_max_age_s * 1e9), R_body_cam)
            if self.prior_source == 'imu'
            else None
        )
        return tilt, near

    def inputs(
        self, t_ns: int, tilt: CameraTilt | None, imu_near: CameraTilt | None
    ) -> FrameInputs:
        """
        Decide the tilt and prior bearing the method gets with one image.

        Parameters
        ----------
        t_ns : int
            Image stamp [ns].
        tilt : CameraTilt or None
            The camera attitude at the stamp (:meth:`lookups`).
        imu_near : CameraTilt or None
            The camera attitude within ``prior_max_age_s`` (:meth:`lookups`).

        Returns
        -------
        FrameInputs
            Pitch and roll [deg] (when the method needs them), the prior bearing [deg] and whether
            a needed tilt is missing.

        """
        pitch = roll = prior = None
        if self.needs_tilt and tilt is not None:
            pitch, roll = tilt.pitch_deg, tilt.roll_deg
        if self.prior_source == 'imu':
            prior = None if imu_near is None else imu_near.bearing_deg
        elif self.prior_source == 'last' and self.last_bearing is not None:
            if abs(t_ns - self.last_bearing[0]) <= self.prior_max_age_s * 1e9:
                prior = self.last_bearing[1]
        return FrameInputs(pitch, roll, prior, self.needs_tilt and tilt is None)

    def checked(self, result, inputs: FrameInputs):
        """
        Apply :func:`check_prior_agreement` against the IMU prior of ``inputs``.

        Only with ``prior_source`` imu: the ``last`` heading is no independent prior (the robot may
        have turned).

        Parameters
        ----------
        result : HeadingResult
            The estimate.
        inputs : FrameInputs
            The frame's inputs (their ``prior_bearing_deg``).

        Returns
        -------
        HeadingResult
            ``result``, or a ``prior_disagrees`` failure.

        """
        if self.prior_source != 'imu':
            return result
        return check_prior_agreement(result, inputs.prior_bearing_deg, self.prior_sigma_deg)

    def remember(self, t_ns: int, result) -> None:
        """
        Keep a result's bearing as the ``last`` prior when it is a resolved heading.

        Parameters
        ----------
        t_ns : int
            Image stamp [ns].
        result : HeadingResult
            The method's result; ignored unless ok and not axial.

        """
        if result.ok and not result.axial and result.bearing_deg is not None:
            self.last_bearing = (int(t_ns), float(result.bearing_deg))


#: A heading further from a given IMU prior than this many combined sigmas is not ``ok``.
PRIOR_DISAGREES_N_SIGMA = 3.0


def check_prior_agreement(
    result,
    prior_bearing_deg: float | None,
    prior_sigma_deg: float,
    n_sigma: float = PRIOR_DISAGREES_N_SIGMA,
):
    """
    Check a heading against an independent prior bearing (the named step "heading vs. IMU prior").

    A result whose bearing is further from ``prior_bearing_deg`` than ``n_sigma`` times
    ``sqrt(sigma^2 + prior_sigma_deg^2)`` becomes a failed result with status ``prior_disagrees``
    and the reason. An axial result is compared modulo 180 deg
    (:func:`~polarization_compass.conventions.fold_axial_deg`), a resolved one modulo 360
    (:func:`~polarization_compass.conventions.wrap_180_deg`). Separate from any check of the sky
    fit itself (those belong to the estimators).

    Parameters
    ----------
    result : HeadingResult
        The estimate.
    prior_bearing_deg : float or None
        The prior true bearing of camera +y [deg] (e.g. the IMU's yaw); None: no check.
    prior_sigma_deg : float
        1-sigma of the prior [deg]; <= 0: no check.
    n_sigma : float, default PRIOR_DISAGREES_N_SIGMA
        The gate in combined sigmas.

    Returns
    -------
    HeadingResult
        ``result`` itself, or the failed result (its ``extras`` keep the rejected bearing and
        sigma).

    """
    if (
        prior_bearing_deg is None
        or not result.ok
        or result.bearing_deg is None
        or not prior_sigma_deg > 0
    ):
        return result
    from dataclasses import replace
    import math

    from ..conventions import fold_axial_deg, wrap_180_deg
    from ..estimators.base import HeadingResult, Status

    if not math.isfinite(float(prior_bearing_deg)):
        return result
    d = float(result.bearing_deg) - float(prior_bearing_deg)
    off = abs(float(fold_axial_deg(d) if result.axial else wrap_180_deg(d)))
    sigma = float(result.sigma_deg or 0.0)
    limit = n_sigma * math.hypot(sigma, float(prior_sigma_deg))
    if off <= limit:
        return result
    extras = dict(
        result.extras,
        rejected_bearing_deg=float(result.bearing_deg),
        rejected_sigma_deg=sigma,
        prior_difference_deg=off,
    )
    failed = HeadingResult.failed(
        result.method,
        Status.PRIOR_DISAGREES,
        f'heading {result.bearing_deg:.1f} deg is {off:.1f} deg from the IMU prior '
        f'{float(prior_bearing_deg) % 360.0:.1f} deg, more than {n_sigma:g} x '
        f'sqrt(sigma {sigma:.2g}^2 + prior sigma {float(prior_sigma_deg):g}^2) = '
        f'{limit:.1f} deg',
        pixels=result.pixels,
        **extras,
    )
    return replace(failed, quality=result.quality)


class CameraInfoState:
    """
    The intrinsics in use from a camera_info stream, and why none are.

    The intrinsics in use from a camera_info stream, and why none are (ROS-free; the node and the
    replay).

    :meth:`accept` a decoded, validated camera; :meth:`reject` a message that failed decoding or
    :func:`~polarization_compass.camera.check_intrinsics`. A rejection also withdraws the camera
    accepted before it: the stream now says something else about the camera (a recalibration,
    another resolution or binning), and using the old intrinsics could be worse than none -- frames
    get a ``bad_input`` status naming the rejection until a valid camera_info arrives.
    :meth:`camera` is the camera to use, None when no camera_info arrived yet (the caller's
    fallback applies), or raises :class:`PipelineError`.
    """

    def __init__(self):
        self._camera = None
        self.rejected_reason: str | None = None
        self.accepted = 0
        self.rejected = 0

    def accept(self, camera) -> None:
        """
        Use a camera from now on.

        Parameters
        ----------
        camera : CameraModel
            Decoded and validated (:func:`~polarization_compass.camera.check_intrinsics`).

        """
        self._camera = camera
        self.rejected_reason = None
        self.accepted += 1

    def reject(self, reason: str) -> None:
        """
        Record a rejected camera_info; the camera in use is withdrawn.

        Parameters
        ----------
        reason : str
            Why it was rejected (one line).

        """
        self.rejected_reason = str(reason)
        self.rejected += 1

    @property
    def received_any(self) -> bool:
        """Whether any camera_info arrived (accepted or rejected)."""
        return self.accepted + self.rejected > 0

    def camera(self):
        """
        Return the camera to use.

        Returns
        -------
        CameraModel or None
            The accepted camera; None before any camera_info (the caller's fallback applies).

        Raises
        ------
        PipelineError
            The latest camera_info was rejected (its reason).

        """
        if self.rejected_reason is not None:
            raise PipelineError(
                f'the latest camera_info was rejected ({self.rejected_reason}); no intrinsics '
                'in use until a valid one arrives'
            )
        return self._camera


class ImageLossWatch:
    """
    Count images lost before they reached the node, from the camera_info stream.

    Lost means the middleware's keep-last queue overflowed or the transport dropped them. A camera
    driver publishes one camera_info per image with the image's stamp, so a camera_info stamp
    without any image of that stamp ``after_ns`` (stamp time) behind the newest camera_info is one
    image lost. Never counts a frame twice; undercounts when camera_info messages are lost too (or
    when no camera_info is published: then nothing is counted). Counts only once an image and a
    camera_info of the same stamp were seen (a driver stamping them differently is never reported
    as losing every image). Thread-safe (images and camera_info arrive on different executor
    threads).
    """

    def __init__(self, after_ns: int = 1_000_000_000, keep: int = 512):
        from collections import OrderedDict
        import threading

        self.after_ns = int(after_ns)
        self.keep = int(keep)
        self._lock = threading.Lock()
        self._info: OrderedDict = OrderedDict()  # camera_info stamps waiting for their image
        self._images: OrderedDict = OrderedDict()  # image stamps seen (good or bad)
        self.lost = 0
        self.paired = False  # an image and a camera_info of one stamp were seen

    def image(self, t_ns: int) -> None:
        """
        Record an image that arrived (good or bad).

        Parameters
        ----------
        t_ns : int
            Its header stamp [ns].

        """
        with self._lock:
            t = int(t_ns)
            if self._info.pop(t, 0) is None:
                self.paired = True
            self._images[t] = None
            while len(self._images) > self.keep:
                self._images.popitem(last=False)

    def camera_info(self, t_ns: int) -> int:
        """
        Record a camera_info stamp and count the images found lost now.

        Parameters
        ----------
        t_ns : int
            The camera_info's header stamp [ns].

        Returns
        -------
        int
            Images newly found lost (their camera_info is ``after_ns`` behind the newest).

        """
        with self._lock:
            t = int(t_ns)
            if t not in self._images:
                self._info[t] = None
            else:
                self.paired = True
            newest = max(self._info, default=t)
            lost = [s for s in self._info if s < newest - self.after_ns] if self.paired else []
            for s in lost:
                del self._info[s]
            while len(self._info) > self.keep:  # a stream of camera_info without images at all
                self._info.popitem(last=False)
            self.lost += len(lost)
            return len(lost)


# ------------------------------------------------------------------------------------------------
# The sun per stamp
# ------------------------------------------------------------------------------------------------
class SunSource:
    """
    Give the sun's azimuth and altitude at a UTC stamp for the current site.

    Through :class:`~polarization_compass.solar.SunCache` (one SPA batch per 10 minutes of stamps).

    Parameters
    ----------
    latitude_deg : float
        Site latitude [deg], north positive.
    longitude_deg : float
        Site longitude [deg], east positive.
    altitude_m : float
        Site height above sea level [m].
    model : {"spa", "paper"}, default "spa"
        Sun position model (:mod:`~polarization_compass.solar`).

    References
    ----------
    .. [1] I. Reda and A. Andreas, "Solar position algorithm for solar radiation applications",
       Solar Energy 76(5): 577-589, 2004.

    """

    def __init__(
        self, latitude_deg: float, longitude_deg: float, altitude_m: float, model: str = 'spa'
    ):
        self.model = model
        self._site = None
        self._cache = None
        self.set_site(latitude_deg, longitude_deg, altitude_m)

    def set_site(self, latitude_deg: float, longitude_deg: float, altitude_m: float) -> None:
        """
        Move the site; a new sun cache only when the sun would move by more than ~1e-5 deg.

        Parameters
        ----------
        latitude_deg : float
            Site latitude [deg], north positive.
        longitude_deg : float
            Site longitude [deg], east positive.
        altitude_m : float
            Site height above sea level [m].

        """
        site = (float(latitude_deg), float(longitude_deg), float(altitude_m))
        if self._site is not None:
            # a GNSS fix moves by metres: a new cache only when the sun would move by > ~1e-5 deg
            if (
                abs(site[0] - self._site[0]) < 1e-5
                and abs(site[1] - self._site[1]) < 1e-5
                and abs(site[2] - self._site[2]) < 100.0
            ):
                return
        from ..solar import SunCache

        self._cache = SunCache(*site, model=self.model)
        self._site = site

    @property
    def site(self):
        """Return the current site ``(latitude_deg, longitude_deg, altitude_m)``."""
        return self._site

    def at_ns(self, t_ns: int) -> tuple[float, float]:
        """
        Compute the sun at a UTC stamp.

        Parameters
        ----------
        t_ns : int
            UTC stamp [ns since the Unix epoch].

        Returns
        -------
        azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        altitude_deg : float
            Sun altitude [deg] as the model gives it.

        Raises
        ------
        PipelineError
            The sun model refuses the stamp (the message says why).

        """
        from ..solar import SolarError

        t_us = np.datetime64(int(t_ns) // 1000, 'us')
        try:
            p = self._cache(t_us)
        except SolarError as exc:
            raise PipelineError(f'sun position at stamp {t_ns / 1e9:.3f} s: {exc}') from None
        return float(p.azimuth_deg), float(p.altitude_deg)


# ------------------------------------------------------------------------------------------------
# Mosaic -> observation -> heading
# ------------------------------------------------------------------------------------------------
class HeadingFrontEnd:
    """
    Turn a raw mosaic into a heading with one method and its knobs.

    A raw mosaic (uint8/uint16/float32) plus the camera, the sun and optionally the tilt and a
    prior bearing in, a :class:`~polarization_compass.estimators.HeadingResult` out.

    Parameters
    ----------
    method : str
        Name of the method (:mod:`~polarization_compass.estimators.registry`).
    knobs : dict, optional
        The method's knobs.
    layout : str or sequence, default IMX250MZR_LAYOUT
        The sensor's 2 x 2 polarizer pattern [deg] (:mod:`~polarization_compass.demosaic`).
    pol45_toward : str, default "+x-y"
        Image direction of the 45 deg polarizer (IMX250MZR as delivered: +x-y).
    demosaic : {"superpixel", "bilinear"}, default "superpixel"
        Demosaicing.
    intensity : bool, default False
        Also compute S0 and pass it as the observation's intensity (lets a method resolve the 180
        deg ambiguity from the sky's brightness gradient).
    sky_check : bool, default False
        Check each result against the whole sky (:func:`~polarization_compass.skyfit.assess_result`
        on :func:`whole_sky_sample`: misfit sigma, 180 deg side, ``poor_fit``; ~15-30 ms per
        frame), as ``estimate`` does on real images.

    Raises
    ------
    EstimatorError
        Unknown method or knob.

    """

    def __init__(
        self,
        method: str,
        knobs: dict | None = None,
        layout=IMX250MZR_LAYOUT,
        pol45_toward: str = IMX250MZR_POL45,
        demosaic: str = 'superpixel',
        intensity: bool = False,
        sky_check: bool = False,
    ):
        from ..demosaic import parse_layout
        from ..estimators import make_estimator

        self.method = method
        self.estimator = make_estimator(method, **(knobs or {}))
        self.layout = parse_layout(layout, pol45_toward)
        self.demosaic = demosaic
        self.intensity = bool(intensity)
        self.sky_check = bool(sky_check)

    def set_knobs(self, knobs: dict) -> None:
        """
        Replace the estimator's knobs; the old ones stay when the new ones are refused.

        Parameters
        ----------
        knobs : dict
            The method's knobs.

        Raises
        ------
        EstimatorError
            A knob is unknown or out of range (the message says which).

        """
        from ..estimators import make_estimator

        self.estimator = make_estimator(self.method, **knobs)

    def set_layout(self, layout, pol45_toward: str) -> None:
        """
        Replace the sensor's polarizer layout.

        Parameters
        ----------
        layout : str or sequence
            The 2 x 2 polarizer pattern [deg]
            (:func:`~polarization_compass.demosaic.parse_layout`).
        pol45_toward : str
            Image direction of the 45 deg polarizer.

        """
        from ..demosaic import parse_layout

        self.layout = parse_layout(layout, pol45_toward)

    def observation_key(self, camera: CameraModel) -> tuple:
        """
        Key this method's observation of a frame, so a replay demosaics once per distinct key.

        Equal keys give equal observations: the pixels are the estimator's ``pixels_needed`` (a
        disc for sm_asm/symmetry, a strided frame for least squares, a window and side grid for
        zenith), plus the demosaic, intensity and layout.

        Parameters
        ----------
        camera : CameraModel
            The camera the frames come from.

        Returns
        -------
        tuple
            A hashable key.

        """
        return (self.estimator.pixels_needed(camera), self.demosaic, self.intensity, self.layout)

    def observation(
        self,
        mosaic: np.ndarray,
        camera: CameraModel,
        sun_azimuth_deg: float,
        sun_altitude_deg: float,
        pitch_deg=None,
        roll_deg=None,
        prior_bearing_deg=None,
        estimator=None,
    ):
        """
        Build the estimator's observation of a full-sensor mosaic.

        Only the pixels the method reads (its ``pixels_needed``: strided superpixels, a region, or
        the zenith window and its whole-sky side grid, demosaiced sparsely) are demosaiced, by
        :func:`polarization_compass.estimators.mosaic_input.observation_from_mosaic`.

        Parameters
        ----------
        mosaic : numpy.ndarray
            Raw DoFP image, the camera's (height, width).
        camera : CameraModel
            The camera.
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        sun_altitude_deg : float
            Sun altitude [deg].
        pitch_deg, roll_deg : float, optional
            Known camera pitch and roll [deg] (eq 21).
        prior_bearing_deg : float, optional
            Prior bearing of camera +y [deg, clockwise from North].
        estimator : Estimator, optional
            The estimator whose pixels to read; this front end's by default.

        Returns
        -------
        Observation
            AoP [rad, eq 28], DoP, rays and the sun, tilt and prior.

        Raises
        ------
        PipelineError
            The mosaic does not match the camera or cannot be demosaiced.

        """
        from ..estimators.mosaic_input import MosaicInputError, observation_from_mosaic

        # one consistent configuration for the whole frame (a node may change knobs from another
        # thread)
        est, demosaic, layout, intensity = (
            estimator or self.estimator,
            self.demosaic,
            self.layout,
            self.intensity,
        )
        m = np.asarray(mosaic)
        if m.shape != camera.shape:
            raise PipelineError(
                f'mosaic is {m.shape[1]}x{m.shape[0]}, the camera is '
                f'{camera.width_px}x{camera.height_px}'
            )
        try:
            return observation_from_mosaic(
                m,
                camera,
                sun_azimuth_deg,
                sun_altitude_deg,
                method=demosaic,
                layout=layout.angles_deg,
                pol45_toward=layout.pol45_toward,
                selection=est.pixels_needed(camera),
                with_intensity=intensity,
                pitch_deg=pitch_deg,
                roll_deg=roll_deg,
                prior_bearing_deg=prior_bearing_deg,
            )
        except MosaicInputError as exc:
            raise PipelineError(str(exc)) from None

    def estimate(
        self,
        mosaic,
        camera,
        sun_azimuth_deg,
        sun_altitude_deg,
        pitch_deg=None,
        roll_deg=None,
        prior_bearing_deg=None,
    ):
        """
        Estimate the heading of one full-sensor mosaic.

        Parameters
        ----------
        mosaic : numpy.ndarray
            Raw DoFP image, the camera's (height, width).
        camera : CameraModel
            The camera.
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from North.
        sun_altitude_deg : float
            Sun altitude [deg].
        pitch_deg, roll_deg : float, optional
            Known camera pitch and roll [deg] (eq 21).
        prior_bearing_deg : float, optional
            Prior bearing of camera +y [deg, clockwise from North].

        Returns
        -------
        HeadingResult
            psi, bearing and REP-103 yaw [deg], or a failure status with a reason.

        Raises
        ------
        PipelineError
            The mosaic does not match the camera or cannot be demosaiced.

        """
        est, layout = self.estimator, self.layout
        obs = self.observation(
            mosaic,
            camera,
            sun_azimuth_deg,
            sun_altitude_deg,
            pitch_deg,
            roll_deg,
            prior_bearing_deg,
            est,
        )
        res = est.estimate(obs)
        if self.sky_check:
            from ..skyfit import assess_result

            sample = whole_sky_sample(mosaic, camera, layout)
            res = assess_result(
                res, sample, sun_altitude_deg, pitch_deg, roll_deg, prior_bearing_deg
            )
        return res


def warm_up(
    front: HeadingFrontEnd, encoding_dtype=np.uint16, camera: CameraModel | None = None
) -> float:
    """
    Run a front end once on a rendered, slightly tilted frame so its numba kernels are compiled.

    Compiled (or loaded from the cache) before the first real image. With ``camera`` (the node's
    expected intrinsics) the frame has that camera's size, so the per-camera caches (rays, pixel
    selections, mirror maps) are built now too rather than on the first image; without, a tiny
    camera (kernels only).

    Parameters
    ----------
    front : HeadingFrontEnd
        The front end to warm up.
    encoding_dtype : numpy dtype, default numpy.uint16
        Dtype of the mosaics it will get (uint8, uint16, else float32).
    camera : CameraModel, optional
        The expected camera.

    Returns
    -------
    float
        Seconds it took.

    """
    import time

    from ..conventions import CameraAttitude
    from ..render import Renderer, SunDirection
    from ..scene import default_scene
    from ..sensor import sensor_config_for_encoding, simulate_mosaic

    t0 = time.perf_counter()
    cam = camera or CameraModel('pinhole', 96, 80, 4.0, 3.45 * 2448 / 96, 3.45 * 2448 / 96)
    scene = default_scene().replace(camera=cam)
    frame = Renderer(scene).render(
        attitude=CameraAttitude(30.0, -3.0, 2.0), sun=SunDirection(180.0, 30.0)
    )
    encoding = {np.dtype(np.uint8): 'mono8', np.dtype(np.uint16): 'mono16'}.get(
        np.dtype(encoding_dtype), '32FC1'
    )
    cfg = sensor_config_for_encoding({}, encoding)
    mosaic = simulate_mosaic(
        frame.aop_rad, frame.dop, frame.intensity, cfg, cfg.layout, np.random.default_rng(0)
    )
    front.estimate(mosaic, cam, 180.0, 30.0, -3.0, 2.0, 30.0)
    return time.perf_counter() - t0


# ------------------------------------------------------------------------------------------------
# Polarizer convention watched on live frames
# ------------------------------------------------------------------------------------------------
class PolarizerMonitor:
    """
    Watch the polarizer convention on live frames.

    Runs :func:`polarization_compass.polarizer_check.check_polarizer` on every ``every_n``-th
    mosaic (0 = never; the first check is on frame ``every_n``), on a decimated superpixel grid (at
    most ``max_blocks`` 2 x 2 blocks, block-aligned so the layout's phase is kept), and remembers
    the last decisive verdict.

    :attr:`error` is the text a node publishes as a diagnostics ERROR while the last decisive check
    contradicts the configured layout (it names the fix); ``cannot_tell`` keeps the previous
    verdict.
    """

    def __init__(self, every_n: int = 100, max_blocks: int = 10000):
        self.every_n = int(every_n)
        self.max_blocks = int(max_blocks)
        self.count = 0
        self.last: dict | None = None
        self.error: str | None = None

    def feed(
        self,
        mosaic,
        camera: CameraModel,
        layout,
        sun_altitude_deg=None,
        pitch_deg=None,
        roll_deg=None,
    ) -> dict | None:
        """
        Count a frame and, on every ``every_n``-th, check the polarizer convention.

        Parameters
        ----------
        mosaic : numpy.ndarray
            Raw full-sensor DoFP image.
        camera : CameraModel
            The camera (rays of the decimated superpixels, cached).
        layout : MosaicLayout
            The configured :class:`~polarization_compass.demosaic.MosaicLayout`.
        sun_altitude_deg : float, optional
            Sun altitude [deg]; None: fitted.
        pitch_deg, roll_deg : float, optional
            Known tilt [deg] (eq 21); None: level.

        Returns
        -------
        dict or None
            The :func:`~polarization_compass.polarizer_check.check_polarizer` report on a checked
            frame, else None.

        """
        if self.every_n <= 0:
            return None
        self.count += 1
        if self.count % self.every_n:  # the every_n-th frame, not the first: start-up stays fast
            return None
        from ..estimators.mosaic_input import _grid_rays
        from ..polarizer_check import check_polarizer

        m = np.asarray(mosaic)
        small, k, nx, ny = decimated_blocks(m, self.max_blocks)

        def rays_for_shape(shape):
            _, _, rays, ok = _grid_rays(camera, (1.5, 2.0 * k, nx), (1.5, 2.0 * k, ny))
            return rays, ok

        sat = float(np.iinfo(m.dtype).max) if np.issubdtype(m.dtype, np.integer) else None
        rep = check_polarizer(
            [('mosaic', small, sat)],
            camera,
            layout.angles_deg,
            layout.pol45_toward,
            rays_for_shape,
            sun_altitude_deg,
            pitch_deg or 0.0,
            roll_deg or 0.0,
        )
        self.last = rep
        if rep['verdict'] == 'contradicted':
            self.error = (
                f'polarizer convention contradicted by the sky (margin {rep["margin"]:.2f}): '
                f'{rep.get("fix", "")}'
            )
        elif rep['verdict'] == 'supported':
            self.error = None
        return rep


def decimated_blocks(mosaic: np.ndarray, max_blocks: int):
    """
    Keep every k-th 2 x 2 block of a mosaic, as one smaller mosaic with the same 2 x 2 phase.

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw DoFP image (H, W).
    max_blocks : int
        At most this many blocks are kept (k the smallest step that achieves it).

    Returns
    -------
    tuple
        ``(small, k, nx, ny)``: the (2 ny, 2 nx) mosaic whose block (j, i) is centred at 1-based
        sensor pixel ``(1.5 + 2 k i, 1.5 + 2 k j)``, the step k and the block counts.

    """
    H, W = mosaic.shape
    by, bx = H // 2, W // 2
    k = max(1, int(math.ceil(math.sqrt(by * bx / max(int(max_blocks), 1)))))
    ny, nx = (by + k - 1) // k, (bx + k - 1) // k
    blocks = mosaic[: 2 * by, : 2 * bx].reshape(by, 2, bx, 2)[::k, :, ::k, :]
    return np.ascontiguousarray(blocks).reshape(2 * ny, 2 * nx), k, nx, ny


def whole_sky_sample(mosaic, camera: CameraModel, layout, max_blocks: int = 8000):
    """
    Sample the whole usable sky of a full-sensor mosaic, whatever pixels a method reads.

    Superpixels of a block decimation; saturated blocks and their glare removed; intensity kept for
    the whole-sky side vote.

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw full-sensor DoFP image.
    camera : CameraModel
        The camera (rays cached per intrinsics and grid).
    layout : MosaicLayout
        The polarizer layout.
    max_blocks : int, default 8000
        Blocks demosaiced at most.

    Returns
    -------
    SkySample or None
        The :class:`~polarization_compass.skyfit.SkySample`, None when too little sky is usable.

    """
    from ..demosaic import aop_dop_from_stokes, stokes_from_mosaic
    from ..estimators.mosaic_input import _grid_rays
    from ..polarizer_check import saturated_blocks
    from ..skyfit import data_mask, sample_sky

    m = np.asarray(mosaic)
    small, k, nx, ny = decimated_blocks(m, max_blocks)
    sat = float(np.iinfo(m.dtype).max) if np.issubdtype(m.dtype, np.integer) else None
    s0, s1, s2 = stokes_from_mosaic(
        small, layout.angles_deg, layout.pol45_toward, 'superpixel', sat
    )
    aop, dop, valid = aop_dop_from_stokes(s0, s1, s2)
    _, _, rays, has_ray = _grid_rays(camera, (1.5, 2.0 * k, nx), (1.5, 2.0 * k, ny))
    bright = np.where(saturated_blocks(small, sat, s0.shape), np.float32(np.inf), s0)
    keep = data_mask(bright, has_ray, float('inf'))
    return sample_sky(aop, dop, valid & keep, rays, s0)
