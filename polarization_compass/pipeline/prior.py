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

"""A method's per-image tilt and ambiguity prior, and the check of a heading against the prior."""

from __future__ import annotations

from dataclasses import dataclass

from .attitude import AttitudeBuffer, CameraTilt
from ..conventions import R_BODY_CAM_DEFAULT

__all__ = [
    'FrameInputs',
    'TiltAndPrior',
    'PRIOR_DISAGREES_N_SIGMA',
    'check_prior_agreement',
]


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
        self.method = method
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
