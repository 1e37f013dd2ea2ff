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
The IMU tilt's uncertainty that a tilt-reading method's heading sigma takes on.

``heading_estimator`` (tilt_aware), ``tilt_corrector`` and ``replay`` grow the heading sigma by
``J Sigma_att J^T`` (docs/ros.md, "Attitude uncertainty"); ``Sigma_att`` comes from the IMU
message's orientation covariance (:func:`imu_tilt_variance_deg2`) plus a stated extra.
"""

from __future__ import annotations

import math

__all__ = [
    'imu_tilt_variance_deg2',
    'AttitudeUncertainty',
    'tilt_sigma_deg',
    'with_attitude_sigma',
]


def imu_tilt_variance_deg2(cov) -> float | None:
    """
    Return the tilt variance [deg^2] a sensor_msgs/Imu orientation covariance states, or None.

    The larger of the roll and pitch variances (elements 0 and 4, rad^2, body axes), so that it
    bounds the camera's pitch and roll whatever the mounting; None for an all-zero matrix
    ("covariance unknown", sensor_msgs/Imu) or unusable (non-finite, negative) diagonal elements.
    (Element 0 = -1, "no orientation", is rejected before: ``decode_orientation``.)

    Parameters
    ----------
    cov : sequence of float
        The 9 row-major elements of ``orientation_covariance`` [rad^2].

    Returns
    -------
    float or None
        Variance [deg^2].

    """
    c = [float(x) for x in cov]
    if len(c) != 9 or all(x == 0.0 for x in c):
        return None
    d = (c[0], c[4])
    if not all(math.isfinite(x) and x >= 0.0 for x in d):
        return None
    return math.degrees(math.sqrt(max(d))) ** 2


class AttitudeUncertainty:
    """
    The latest IMU's tilt uncertainty and a stated extra, as both tilt-reading nodes propagate it.

    ``heading_estimator`` (tilt_aware) and ``tilt_corrector`` grow the heading sigma by
    ``J Sigma_att J^T`` (docs/ros.md); this holds ``Sigma_att``'s source: the latest IMU message's
    tilt variance (:func:`imu_tilt_variance_deg2`; None for an all-zero, i.e. unknown, covariance)
    and warns once when nothing states an uncertainty.
    """

    def __init__(self):
        self.var_deg2 = None
        self._warned_unknown = False

    def update(self, cov) -> None:
        """Take the tilt variance of an Imu message's ``orientation_covariance``."""
        self.var_deg2 = imu_tilt_variance_deg2(cov)

    def sigma_deg(self, extra_deg: float, logger) -> tuple[float, bool]:
        """
        Return the camera pitch/roll 1-sigma [deg] and whether the IMU covariance is known.

        ``sqrt(var + extra^2)`` with ``extra_deg`` the node's ``attitude_sigma_deg`` (what the
        covariance does not hold: boresight, time offset x tilt rate); the first call with neither
        logs a warning through ``logger``.
        """
        v = self.var_deg2
        if v is None and extra_deg == 0.0 and not self._warned_unknown:
            self._warned_unknown = True
            logger.warning(
                'IMU orientation_covariance is all zeros (unknown): no attitude uncertainty is '
                'propagated into the heading sigma; set attitude_sigma_deg to state one'
            )
        return tilt_sigma_deg(v, extra_deg), v is not None


def tilt_sigma_deg(var_deg2: float | None, extra_deg: float) -> float:
    """
    Return the camera pitch/roll 1-sigma [deg]: ``sqrt(var + extra^2)``.

    Parameters
    ----------
    var_deg2 : float or None
        The IMU's tilt variance [deg^2] (:func:`imu_tilt_variance_deg2`); None: unknown (0).
    extra_deg : float
        The stated 1-sigma [deg] the covariance does not hold (``attitude_sigma_deg``).

    Returns
    -------
    float
        The isotropic tilt 1-sigma [deg].

    """
    return math.sqrt((var_deg2 or 0.0) + extra_deg * extra_deg)


def with_attitude_sigma(
    result, method: str, pitch_deg, roll_deg, tilt_sigma: tuple, notes: dict | None = None
):
    """
    Add the IMU tilt's uncertainty to a tilt-reading method's sigma: ``J Sigma_att J^T``.

    ``Sigma_att`` is isotropic with the 1-sigma of ``tilt_sigma``; ``J`` comes from the method
    (:meth:`~polarization_compass.estimators.base.Estimator.tilt_sensitivity`). Only an ``ok``
    result with a sigma, estimated with a known pitch and roll, by a method that reads the tilt.

    Parameters
    ----------
    result : HeadingResult
        The method's result.
    method : str
        The method's registered name.
    pitch_deg, roll_deg : float or None
        The camera pitch and roll [deg] the result was estimated with.
    tilt_sigma : tuple of (float, bool)
        The tilt 1-sigma [deg] (:func:`tilt_sigma_deg`) and whether the IMU stated a covariance.
    notes : dict, optional
        Filled, when the sigma is propagated, with ``attitude_sigma_deg`` (the tilt 1-sigma),
        ``attitude_covariance`` (``imu`` or ``unknown``) and ``sigma_attitude_deg`` (the
        heading's share) [deg].

    Returns
    -------
    HeadingResult
        ``result``, or a copy whose ``sigma_deg`` is ``hypot(sigma, sigma_attitude)`` and whose
        extras keep ``sigma_fit_deg`` and ``sigma_attitude_deg``.

    """
    import dataclasses

    from ..estimators import registry

    if not (result.ok and result.sigma_deg is not None) or pitch_deg is None or roll_deg is None:
        return result
    j = registry.get(method).tilt_sensitivity(result, pitch_deg, roll_deg)
    if j is None:
        return result
    s_tilt, known = tilt_sigma
    s_att = math.hypot(j[0] * s_tilt, j[1] * s_tilt)
    if notes is not None:
        notes.update(
            attitude_sigma_deg=s_tilt,
            attitude_covariance='imu' if known else 'unknown',
            sigma_attitude_deg=s_att,
        )
    if s_att == 0.0:
        return result
    return dataclasses.replace(
        result,
        sigma_deg=math.hypot(result.sigma_deg, s_att),
        extras={**result.extras, 'sigma_fit_deg': result.sigma_deg, 'sigma_attitude_deg': s_att},
    )
