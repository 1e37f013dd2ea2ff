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
Checks of an estimator's result against the whole sky, and of several methods against each other.

:func:`side_preference` and :func:`side_votes`: which end of an axial heading the whole sky
supports (the AoP pattern at the known sun altitude, the brightness of the two half-skies);
:func:`assess_result`: an honest sigma (with the jackknife over sky sectors), the 180 deg side and
the ``poor_fit`` / ``inconsistent`` status of one result on a real sky; :func:`mark_inconsistent`:
results of several methods on one frame that disagree. The fit itself is in :mod:`.skyfit`.
"""

from __future__ import annotations

import math

import numpy as np

from .conventions import wrap_180_deg
from .skyfit import (
    _loss,
    _sun_cam,
    fit_sky,
    jackknife_sigma_deg,
    misfit_at,
    OUTLIER_DEG,
    SkySample,
)


def side_preference(
    sample: SkySample,
    psi_deg: float,
    sun_altitude_deg: float,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
) -> dict:
    """
    Tell which end of the axial heading ``psi_deg`` / ``psi_deg + 180`` the whole sky supports.

    The pattern measure is the Cauchy loss difference of the AoP pattern at the known sun altitude
    (the pattern of a sun at altitude h is not symmetric under a 180 deg turn unless h is near 0 or
    90 deg). The brightness measure compares the half-sky towards the sun with the half-sky away
    from it (saturated sun and glare pixels count as bright, flare ghosts are small against a
    half-sky).

    Parameters
    ----------
    sample : SkySample
        Sampled sky pixels (:func:`sample_sky`).
    psi_deg : float
        Camera-frame sun angle psi of eq 21 [deg].
    sun_altitude_deg : float
        Sun altitude [deg].
    pitch_deg : float, default 0
        Camera pitch [deg].
    roll_deg : float, default 0
        Camera roll [deg].

    Returns
    -------
    dict
        ``"pattern"``: loss at ``psi_deg + 180`` minus loss at ``psi_deg`` (> 0 favours
        ``psi_deg``); ``"brightness"``: (mean intensity towards the sun - mean away) / mean
        intensity (> 0 favours ``psi_deg``), None without intensity or with an empty half-sky.

    """
    this = _loss(sample, _sun_cam([psi_deg], [sun_altitude_deg], pitch_deg, roll_deg))[0]
    other = _loss(sample, _sun_cam([psi_deg + 180.0], [sun_altitude_deg], pitch_deg, roll_deg))[0]
    out = {'pattern': float(other - this), 'brightness': None}
    if sample.intensity is not None:
        s = _sun_cam([psi_deg], [0.0], pitch_deg, roll_deg)[0]
        toward = (s[0] * sample.rays[0] + s[1] * sample.rays[1]) > 0
        i = sample.intensity.astype(np.float64)
        if toward.any() and (~toward).any() and i.mean() > 0:
            out['brightness'] = float((i[toward].mean() - i[~toward].mean()) / i.mean())
    return out


def side_votes(
    sample: SkySample,
    psi_deg: float,
    sun_altitude_deg: float,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
):
    """
    Return the whole sky's votes on the 180 deg side of ``psi_deg`` and their values.

    Each of :func:`side_preference`'s two measures votes +1 (``psi_deg``) or -1 (``psi_deg + 180``)
    when its magnitude exceeds its threshold (:data:`PATTERN_VOTE`, :data:`BRIGHTNESS_VOTE`), else
    abstains.

    Parameters
    ----------
    sample : SkySample
        Sampled sky pixels (:func:`sample_sky`).
    psi_deg : float
        Camera-frame sun angle psi of eq 21 [deg].
    sun_altitude_deg : float
        Sun altitude [deg].
    pitch_deg : float, default 0
        Camera pitch [deg].
    roll_deg : float, default 0
        Camera roll [deg].

    Returns
    -------
    votes : list of int
        Zero to two votes, each +1 or -1.
    values : dict
        ``{"pattern": ..., "brightness": ...}`` of :func:`side_preference` rounded to 4 decimals
        for reports (``brightness`` may be None).

    """
    pref = side_preference(sample, psi_deg, sun_altitude_deg, pitch_deg, roll_deg)
    votes = []
    if abs(pref['pattern']) > PATTERN_VOTE:
        votes.append(1 if pref['pattern'] > 0 else -1)
    b = pref['brightness']
    if b is not None and abs(b) > BRIGHTNESS_VOTE:
        votes.append(1 if b > 0 else -1)
    return votes, {
        'pattern': round(pref['pattern'], 4),
        'brightness': None if b is None else round(b, 4),
    }


# --------------------------------------------------------------------------------------------
# Assessment of an estimator's result against the whole sky (honest sigma and status on real skies)
# --------------------------------------------------------------------------------------------
#: a sky whose robust residual scatter at the estimate exceeds this, or whose inlier share is below
#: :data:`MIN_INLIER_FRACTION`, fits no single sun well: status ``poor_fit``
MAX_SCATTER_DEG = 25.0
MIN_INLIER_FRACTION = 0.5
#: a side vote counts when the pattern loss difference / brightness contrast exceeds these
PATTERN_VOTE = 0.05
BRIGHTNESS_VOTE = 0.05
#: a heading further than 3 sigma + this from the whole sky's own best heading (same sun, same
#: tilt) is ``inconsistent`` (e.g. a method that assumed a level camera when the tilt is known)
AGREE_FLOOR_DEG = 0.5


def assess_result(
    result,
    sample: SkySample | None,
    sun_altitude_deg: float,
    pitch_deg=None,
    roll_deg=None,
    prior_bearing_deg=None,
):
    """
    Check an estimator's result against the whole sky.

    - sigma: ``hypot(method sigma, jackknife sigma)``; the jackknife over sky sectors measures the
      misfit of this frame to the model (:func:`jackknife_sigma_deg`), which on real skies
      dominates shot noise;
    - side: unless a prior decides it, the 180 deg side is re-decided by the whole sky
      (:func:`side_votes`: AoP pattern at the known sun altitude, half-sky brightness); when
      every vote is against the method's side the heading is turned by 180 deg, when the votes
      disagree the result becomes axial (``ambiguous``);
    - status ``poor_fit`` when the sky at the estimate has a robust scatter above
      :data:`MAX_SCATTER_DEG` or less than :data:`MIN_INLIER_FRACTION` of its weight within
      :data:`OUTLIER_DEG`;
    - status ``inconsistent`` when the whole sky's own robust fit (same sun altitude and tilt, psi
      within +-30 deg) is further from the heading than 3 combined sigmas +
      :data:`AGREE_FLOOR_DEG`.

    Parameters
    ----------
    result : HeadingResult
        An estimator's result (:class:`~polarization_compass.estimators.HeadingResult`).
    sample : SkySample or None
        Sampled sky pixels of the same frame (:func:`sample_sky`); None when too little sky is
        usable to judge.
    sun_altitude_deg : float
        Sun altitude [deg].
    pitch_deg : float, optional
        Known camera pitch [deg]; None counts as level (0).
    roll_deg : float, optional
        Known camera roll [deg]; None counts as level (0).
    prior_bearing_deg : float, optional
        A prior heading [deg]; when given, the whole sky does not re-decide the 180 deg side.

    Returns
    -------
    HeadingResult
        A new result with the combined sigma, the side decision, possibly status ``poor_fit`` or
        ``inconsistent`` with its reason, and ``extras["sky_check"]`` saying what was measured.
        ``result`` itself when ``sample`` is None, the result has no heading, or its status is
        neither ``ok`` nor ``ambiguous``.

    """
    from dataclasses import replace

    from .estimators.base import HeadingResult, Status

    if (
        sample is None
        or result.psi_deg is None
        or result.status not in (Status.OK, Status.AMBIGUOUS)
    ):
        return result
    pitch = 0.0 if pitch_deg is None else float(pitch_deg)
    roll = 0.0 if roll_deg is None else float(roll_deg)
    psi = float(result.psi_deg)
    axial = bool(result.axial)
    check = {}
    side_note = ''
    if prior_bearing_deg is None:
        votes, check['side_votes'] = side_votes(sample, psi, sun_altitude_deg, pitch, roll)
        if votes and all(v < 0 for v in votes):
            psi = float(wrap_180_deg(psi + 180.0))
            side_note = '; 180 deg side re-decided by the whole sky (AoP pattern and brightness)'
            axial = False
        elif votes and all(v > 0 for v in votes):
            if axial:
                side_note = '; 180 deg side decided by the whole sky (AoP pattern and brightness)'
            axial = False
        elif votes:
            axial = True
            side_note = "; the whole sky's side votes disagree: 180 deg ambiguity left open"
    fit = misfit_at(sample, psi, sun_altitude_deg, pitch, roll)
    jk = jackknife_sigma_deg(sample, psi, sun_altitude_deg, pitch, roll)
    best = fit_sky(sample, sun_altitude_deg, pitch, roll, psi_range_deg=(psi - 30.0, psi + 30.0))
    off = float(wrap_180_deg(psi - best.psi_deg))
    check['whole_sky_psi_deg'] = round(best.psi_deg, 3)
    check.update(
        {
            'scatter_deg': round(fit.scatter_deg, 3),
            'inlier_fraction': round(fit.inlier_fraction, 3),
            'jackknife_sigma_deg': round(jk, 3),
            'pixels': fit.pixels,
            'method_sigma_deg': result.sigma_deg,
        }
    )
    sigma = None if result.sigma_deg is None else float(math.hypot(result.sigma_deg, jk))
    extras = dict(result.extras)
    extras['sky_check'] = check
    new = HeadingResult.from_psi(
        result.method,
        psi,
        _sun_az(result),
        sigma if sigma is not None else None,
        result.pixels,
        result.quality,
        axial,
        result.reason + side_note,
        sun_altitude_deg=result.sun_altitude_deg,
        extras=extras,
    )
    limit = 3.0 * math.hypot(result.sigma_deg or 0.0, jk) + AGREE_FLOOR_DEG
    if (
        fit.scatter_deg <= MAX_SCATTER_DEG
        and fit.inlier_fraction >= MIN_INLIER_FRACTION
        and abs(off) > limit
    ):
        new = replace(
            new,
            status=Status.INCONSISTENT,
            reason=f'the whole sky at the known sun and tilt fits best {off:+.2f} deg away from '
            'this '
            f'heading, beyond 3 sigma + {AGREE_FLOOR_DEG:g} deg ({limit:.2f} deg)',
        )
    if fit.scatter_deg > MAX_SCATTER_DEG or fit.inlier_fraction < MIN_INLIER_FRACTION:
        new = replace(
            new,
            status=Status.POOR_FIT,
            reason=f'the sky fits no single sun well at this heading: robust AoP scatter '
            f'{fit.scatter_deg:.1f} deg (limit {MAX_SCATTER_DEG:g}), '
            f'{100 * fit.inlier_fraction:.0f} % '
            f'of the sky within {OUTLIER_DEG:g} deg (need {100 * MIN_INLIER_FRACTION:.0f} %)',
        )
    return new


def _sun_az(result) -> float:
    """Return the sun azimuth a result was made with (bearing - psi)."""
    return float(wrap_180_deg(result.bearing_deg - result.psi_deg))


def mark_inconsistent(results, min_sigma_deg: float = 0.5):
    """
    Mark results of several methods on one frame as inconsistent.

    Each usable result (status ``ok`` or ``ambiguous`` with a heading) that disagrees with more
    than half of the other usable ones by more than 3 combined sigmas (axially when either is
    axial) gets status ``inconsistent`` with a reason naming the worst disagreement.

    Parameters
    ----------
    results : sequence of HeadingResult
        Results of several methods on the same frame.
    min_sigma_deg : float, default 0.5
        Floor on each result's sigma in the combined sigma [deg].

    Returns
    -------
    list of HeadingResult
        A new list in the order of ``results``; unchanged when fewer than two are usable.

    """
    from dataclasses import replace

    from .conventions import fold_axial_deg
    from .estimators.base import Status

    usable = [
        i
        for i, r in enumerate(results)
        if r.status in (Status.OK, Status.AMBIGUOUS) and r.psi_deg is not None
    ]
    out = list(results)
    if len(usable) < 2:
        return out
    for i in usable:
        ri = results[i]
        bad, seen, worst = 0, 0, None
        for j in usable:
            if j == i:
                continue
            rj = results[j]
            d = ri.psi_deg - rj.psi_deg
            d = abs(float(fold_axial_deg(d) if (ri.axial or rj.axial) else wrap_180_deg(d)))
            s = math.hypot(
                max(ri.sigma_deg or 0.0, min_sigma_deg), max(rj.sigma_deg or 0.0, min_sigma_deg)
            )
            seen += 1
            if d > 3.0 * s:
                bad += 1
                if worst is None or d > worst[0]:
                    worst = (d, rj.method, s)
        if seen and bad * 2 > seen:
            out[i] = replace(
                ri,
                status=Status.INCONSISTENT,
                reason=f'disagrees with {bad} of {seen} other methods beyond 3 sigma (e.g. '
                f'{worst[1]}: {worst[0]:.1f} deg apart, combined sigma {worst[2]:.2f} deg)',
            )
    return out
