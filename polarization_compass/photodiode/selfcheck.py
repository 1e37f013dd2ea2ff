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
Which polarizer angle convention and wiring a photodiode array has, from its data.

A convention is one of the ``angle_zero`` x ``angle_sense`` pairs. The counterpart of the camera's
polarizer-direction check: the four conventions map the same readings to four different sets of
E-vectors; only the right one makes them consistent with one sun (a small least-squares misfit) at
the ephemeris' elevation. No reference heading is needed. With a reference bearing per sample the
heading error of each convention is reported too. The same score catches common wiring mistakes
(:func:`wiring_hypotheses`), and :func:`estimate_recording_checked` withholds every heading when
one of them fits the readings clearly better than the geometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import geometry_from_dict, geometry_to_dict
from .heading import estimate_recording, make_array_estimator
from ..conventions import ANGLE_SENSES, ANGLE_ZEROS, wrap_180_deg
from ..estimators.base import HeadingResult, Status

__all__ = [
    'ConventionScore',
    'check_convention',
    'contradicting_hypothesis',
    'estimate_recording_checked',
    'score_geometries',
    'wiring_hypotheses',
]


@dataclass
class ConventionScore:
    """How well one polarizer convention explains a recording."""

    angle_zero: str
    angle_sense: str
    misfit_median_deg: float | None  # median rms angle residual over the samples with a fit
    sun_elevation_diff_median_deg: float | None
    fitted_fraction: float  # share of samples with a least-squares fit
    error_rms_deg: float | None = None  # against the reference, axial (mod 180), when given


def wiring_hypotheses(geometry) -> dict:
    """
    Return the geometries of the common configuration mistakes, keyed by what the mistake is.

    The other three polarizer conventions, azimuths counted the other way (``-azimuth``), and the
    recording's units one position late or early (the readings of unit u come from the geometry's
    unit u + 1 or u - 1; the columns the geometry disables stay disabled, so every hypothesis uses
    the same readings). A cyclic shift that is a rigid rotation of the units (recording order =
    azimuth order at equal steps) cannot be told from a heading offset and is left out.

    Parameters
    ----------
    geometry : ArrayGeometry
        The configured sensor description.

    Returns
    -------
    dict of str to ArrayGeometry
        ``'as configured'`` first, then the alternatives.

    """
    g = geometry
    out = {'as configured': g}
    for zero in ANGLE_ZEROS:
        for sense in ANGLE_SENSES:
            if (zero, sense) != (g.angle_zero, g.angle_sense):
                out[f'angle_zero {zero}, angle_sense {sense}'] = g.with_convention(zero, sense)
    d = geometry_to_dict(g)
    mirrored = {**d, 'units': [{**u, 'azimuth_deg': -u['azimuth_deg']} for u in d['units']]}
    out['azimuths counted the other way'] = geometry_from_dict(mirrored)
    U = g.n_units
    for k, name in ((1, 'late'), (-1, 'early')):
        units = [_moved(d['units'][(u + k) % U], d['units'][u]) for u in range(U)]
        if U >= 3 and not _rigid_rotation(g, k) and _same_channels(units, d['units']):
            out[f'units one position {name}'] = geometry_from_dict({**d, 'units': units})
    return out


def _rigid_rotation(g, k: int) -> bool:
    """Return whether shifting the units by ``k`` positions is a rotation about the vertical."""
    az = np.array([u.azimuth_deg for u in g.units])
    el = np.array([u.elevation_deg for u in g.units])
    step = wrap_180_deg(np.roll(az, -k) - az)
    return bool(np.allclose(np.roll(el, -k), el) and np.allclose(step, step[0], atol=1e-6))


def _moved(unit: dict, column: dict) -> dict:
    """Return ``unit`` read from another column: the column's enabled flag stays with it."""
    out = {k: v for k, v in unit.items() if k != 'enabled'}
    if column.get('enabled') is False:
        out['enabled'] = False
    return out


def _same_channels(a, b) -> bool:
    return all(len(x['channels_deg']) == len(y['channels_deg']) for x, y in zip(a, b))


def score_geometries(
    intensities, geometries: dict, sun_azimuth_deg, sun_altitude_deg, pitch_deg, roll_deg
) -> dict:
    """
    Return each geometry's median rms angle residual [deg] over the samples with a fit.

    Parameters
    ----------
    intensities : array_like
        (S, U, C) readings.
    geometries : dict of str to ArrayGeometry
        The hypotheses (:func:`wiring_hypotheses`).
    sun_azimuth_deg, sun_altitude_deg : float or array_like
        Ephemeris [deg], scalar or (S,).
    pitch_deg, roll_deg : float or array_like
        Tilt [deg].

    Returns
    -------
    dict of str to float or None
        Median misfit per hypothesis (None: no sample gave a fit).

    """
    out = {}
    for name, g in geometries.items():
        est = make_array_estimator(
            'tilt_aware', g, max_misfit_deg=90.0, max_sun_elevation_diff_deg=180.0
        )
        res = estimate_recording(
            est, intensities, sun_azimuth_deg, sun_altitude_deg, pitch_deg, roll_deg
        )
        mis = [r.extras['misfit_rms_deg'] for r in res if 'misfit_rms_deg' in r.extras]
        out[name] = float(np.median(mis)) if mis else None
    return out


#: An alternative whose median misfit is below this share of the configured one contradicts it.
CONTRADICTION_RATIO = 2.0 / 3.0


def contradicting_hypothesis(
    intensities,
    geometry,
    sun_azimuth_deg,
    sun_altitude_deg,
    pitch_deg=0.0,
    roll_deg=0.0,
    max_samples: int = 120,
):
    """
    Return the configuration mistake the readings fit clearly better than the geometry, or None.

    Scored on at most ``max_samples`` evenly spaced samples (:func:`score_geometries`).

    Parameters
    ----------
    intensities : array_like
        (S, U, C) readings.
    geometry : ArrayGeometry
        The configured sensor description.
    sun_azimuth_deg, sun_altitude_deg : float or array_like
        Ephemeris [deg], scalar or (S,).
    pitch_deg, roll_deg : float or array_like, optional
        Tilt [deg] (0: level ground).
    max_samples : int, optional
        Samples scored.

    Returns
    -------
    tuple or None
        ``(mistake, its median misfit, the configured one's)`` [deg], or None.

    """
    x = np.asarray(intensities, dtype=float)
    idx = np.unique(np.linspace(0, x.shape[0] - 1, min(max_samples, x.shape[0])).astype(int))

    def take(v):
        a = np.asarray(v, dtype=float)
        return a if a.ndim == 0 else np.broadcast_to(a, (x.shape[0],))[idx]

    scores = score_geometries(
        x[idx],
        wiring_hypotheses(geometry),
        take(sun_azimuth_deg),
        take(sun_altitude_deg),
        take(pitch_deg),
        take(roll_deg),
    )
    own = scores.pop('as configured')
    if own is None:
        return None
    best = min(((v, k) for k, v in scores.items() if v is not None), default=None)
    if best is not None and best[0] < CONTRADICTION_RATIO * own:
        return best[1], best[0], own
    return None


def estimate_recording_checked(
    estimator,
    intensities,
    sun_azimuth_deg,
    sun_altitude_deg,
    pitch_deg=None,
    roll_deg=None,
    prior_bearing_deg=None,
    progress=None,
) -> list:
    """
    Estimate every sample (:func:`~.heading.estimate_recording`) unless the wiring is wrong.

    When the readings fit a common configuration mistake (:func:`contradicting_hypothesis`)
    clearly better than the geometry, no sample keeps a heading: each result becomes ``poor_fit``
    with the mistake in its reason.

    Parameters
    ----------
    estimator : ArrayHeadingEstimator
        The estimator.
    intensities : array_like
        (S, U, C) readings.
    sun_azimuth_deg, sun_altitude_deg : float or array_like
        Ephemeris [deg], scalar or (S,).
    pitch_deg, roll_deg : float or array_like, optional
        Known tilt [deg]; the check assumes level ground without it.
    prior_bearing_deg : float or array_like, optional
        Prior bearing [deg].
    progress : callable, optional
        ``progress(done, total)`` every 1000 samples (:func:`~.heading.estimate_recording`).

    Returns
    -------
    list of HeadingResult
        One per sample.

    """
    res = estimate_recording(
        estimator,
        intensities,
        sun_azimuth_deg,
        sun_altitude_deg,
        pitch_deg,
        roll_deg,
        prior_bearing_deg,
        progress,
    )
    tilt = (0.0, 0.0) if pitch_deg is None or roll_deg is None else (pitch_deg, roll_deg)
    bad = contradicting_hypothesis(
        intensities, estimator.geometry, sun_azimuth_deg, sun_altitude_deg, *tilt
    )
    if bad is None:
        return res
    why = (
        f'the readings fit "{bad[0]}" better than the geometry (median misfit {bad[1]:.1f} vs '
        f'{bad[2]:.1f} deg): check the geometry with check-array'
    )
    return [
        HeadingResult.failed(r.method, Status.POOR_FIT, why, r.pixels, **r.extras) if r.ok else r
        for r in res
    ]


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
