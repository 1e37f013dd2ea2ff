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
Which polarizer angle convention a photodiode array has, from its data.

A convention is one of the ``angle_zero`` x ``angle_sense`` pairs.

The counterpart of the camera's polarizer-direction check: the four conventions map the same
readings to four different sets of E-vectors; only the right one makes them consistent with one sun
(a small least-squares misfit) at the ephemeris' elevation. No reference heading is needed. With a
reference bearing per sample the heading error of each convention is reported too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .heading import estimate_recording, make_array_estimator
from ..conventions import ANGLE_SENSES, ANGLE_ZEROS, wrap_180_deg

__all__ = ['ConventionScore', 'check_convention']


@dataclass
class ConventionScore:
    """How well one polarizer convention explains a recording."""

    angle_zero: str
    angle_sense: str
    misfit_median_deg: float | None  # median rms angle residual over the samples with a fit
    sun_elevation_diff_median_deg: float | None
    fitted_fraction: float  # share of samples with a least-squares fit
    error_rms_deg: float | None = None  # against the reference, axial (mod 180), when given


def check_convention(
    intensities,
    geometry,
    sun_azimuth_deg,
    sun_altitude_deg,
    pitch_deg=0.0,
    roll_deg=0.0,
    reference_bearing_deg=None,
) -> tuple[list, str]:
    """
    Score the four polarizer conventions on a recording, best first.

    Parameters
    ----------
    intensities : array_like
        (S, U, C) readings.
    geometry : ArrayGeometry
        Units, channels and gains (its own convention is ignored).
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], scalar or (S,).
    sun_altitude_deg : float or array_like
        Sun altitude [deg], scalar or (S,).
    pitch_deg : float or array_like, optional
        Tilt [deg] (0 for a robot on level ground).
    roll_deg : float or array_like, optional
        Tilt [deg].
    reference_bearing_deg : float or array_like, optional
        Reference bearing of the front [deg], scalar or (S,): adds each convention's axial error
        RMS.

    Returns
    -------
    tuple of (list of ConventionScore, str)
        The scores sorted by median misfit, and a verdict line ('clear' when the best misfit is
        below 2/3 of the runner-up's).

    """
    scores = []
    for zero in ANGLE_ZEROS:
        for sense in ANGLE_SENSES:
            g = geometry.with_convention(zero, sense)
            est = make_array_estimator(
                'tilt_aware', g, max_misfit_deg=90.0, max_sun_elevation_diff_deg=180.0
            )
            res = estimate_recording(
                est, intensities, sun_azimuth_deg, sun_altitude_deg, pitch_deg, roll_deg
            )
            alts = np.broadcast_to(np.asarray(sun_altitude_deg, dtype=float), (len(res),))
            mis = [r.extras['misfit_rms_deg'] for r in res if 'misfit_rms_deg' in r.extras]
            eld = [
                abs(r.sun_altitude_deg - a)
                for r, a in zip(res, alts)
                if r.sun_altitude_deg is not None
            ]
            err = None
            if reference_bearing_deg is not None:
                ref = np.broadcast_to(np.asarray(reference_bearing_deg, dtype=float), (len(res),))
                e = [
                    float(wrap_180_deg(2.0 * (r.bearing_deg - b))) / 2.0
                    for r, b in zip(res, ref)
                    if r.ok
                ]
                err = float(np.sqrt(np.mean(np.square(e)))) if e else None
            scores.append(
                ConventionScore(
                    zero,
                    sense,
                    float(np.median(mis)) if mis else None,
                    float(np.median(eld)) if eld else None,
                    len(mis) / max(len(res), 1),
                    err,
                )
            )
    scores.sort(key=lambda s: (s.misfit_median_deg is None, s.misfit_median_deg or 0.0))
    best = scores[0]
    if best.misfit_median_deg is None:
        return scores, 'no convention gives a fit: too few usable units in every sample'
    runner = scores[1].misfit_median_deg
    clear = runner is not None and best.misfit_median_deg < (2.0 / 3.0) * runner
    verdict = (
        f'{"clear" if clear else "UNCLEAR"}: angle_zero {best.angle_zero}, angle_sense '
        f'{best.angle_sense} '
        f'(median misfit {best.misfit_median_deg:.1f} deg vs '
        f'{runner if runner is not None else float("nan"):.1f} '
        'for the runner-up)'
    )
    return scores, verdict
