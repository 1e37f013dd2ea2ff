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
The 180 deg side of a photodiode array's sun: ephemeris elevation, brightness gradient, prior.

The least-squares sun is known up to sign; the two candidates put it at elevations ``+el`` and
``-el`` above the side frame's horizon (levelled when the tilt is known). Evidence, in this order:

1. **The ephemeris on both sides.** Each candidate's elevation is compared with the ephemeris
   altitude ``alt``: its distance ``d = max(0, |el_c - alt| - T)`` from the band the sun can be in
   (``T = 0`` after levelling; ``T = max_tilt_deg`` in the sensor's own frame, whose tilt is not
   known), in sigmas ``z = d / sig`` with ``sig = hypot(sigma_el, side_elevation_sigma_deg)`` (the
   fit's sigma and that of the levelled frame itself: a tilt or mount known to a few degrees, the
   time). The upper candidate is taken when the lower one is at least ``sign_margin_sigma`` sigmas
   further from the ephemeris and the upper one itself within that margin (a fitted sun far from
   both says nothing). For a level frame this needs ``2 min(el, alt) >= margin * sig``: a sun
   near the horizon never decides, however high the fit puts it.
2. **The brightness gradient** of the units (brighter towards the sun): the t statistic of a
   straight-line fit over n units has n - 2 degrees of freedom; it is converted to the normal
   deviate of the same two-sided p (a t of 4 from 3 units is p = 0.16, not 6e-5) and must reach
   ``brightness_min_t``. It is not used when the elevation leans the other way by a sigma or more.
3. **A prior bearing** within ``prior_max_diff_deg``.

Else the result is ``ambiguous``: an honest ``ambiguous`` is better than a flip. The result says
which decided it (``ambiguity_resolved_by``: ``sun_elevation``, ``brightness``, ``prior`` or None).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtri, stdtr

from ..estimators._common import (
    brightness_t_from_stats,
    resolve_ambiguity,
    sun_side_candidates,
)
from ..estimators.sun_from_evectors import unit_brightness_stats

__all__ = ['elevation_evidence', 'brightness_evidence', 'pick_array_side']

_UNRESOLVED = '180 deg ambiguity not resolved: '


def elevation_evidence(
    el_deg: float, sigma_el_deg: float, alt_deg: float, tilt_band_deg: float, ref_sigma_deg: float
) -> tuple[float, float]:
    """
    Return how many sigmas each candidate's elevation is from the ephemeris band.

    Parameters
    ----------
    el_deg : float
        The fitted sun's elevation above the side frame's horizon [deg], >= 0 (the upper
        candidate; the lower one is at ``-el_deg``).
    sigma_el_deg : float
        1-sigma of the fitted elevation [deg].
    alt_deg : float
        Ephemeris altitude of the sun [deg].
    tilt_band_deg : float
        Half-width of the band of elevations the sun can have in the side frame around
        ``alt_deg`` [deg]: 0 when levelled, the tilt bound otherwise.
    ref_sigma_deg : float
        1-sigma of the side frame's elevation itself [deg] (tilt, mount, time).

    Returns
    -------
    tuple of float
        ``(z_upper, z_lower)``, each >= 0.

    """
    sig = max(math.hypot(sigma_el_deg, ref_sigma_deg), 1e-9)

    def z(el_c: float) -> float:
        return max(0.0, abs(el_c - alt_deg) - tilt_band_deg) / sig

    return z(el_deg), z(-el_deg)


def brightness_evidence(s0, axes_cam, direction_cam) -> tuple[float | None, int]:
    """
    Return the brightness gradient's normal-equivalent deviate and its degrees of freedom.

    Parameters
    ----------
    s0 : array_like
        (n,) brightness of the units used.
    axes_cam : array_like
        (n, 3) their viewing axes, camera-equivalent frame.
    direction_cam : array_like
        (3,) ``s_upper - s_lower``: positive when brighter towards the upper candidate's sun.

    Returns
    -------
    tuple
        ``(z, dof)``: z signed like the slope's t statistic, with the same two-sided p under a t
        distribution of ``dof = n - 2`` degrees of freedom; z is None with fewer than 3 units or
        without spread.

    """
    n = int(np.asarray(s0).size)
    t = brightness_t_from_stats(unit_brightness_stats(s0, axes_cam), direction_cam, 3)
    dof = n - 2
    if t is None or dof < 1:
        return None, dof
    if not math.isfinite(t):
        return t, dof
    p_half = float(stdtr(dof, -abs(t)))  # one tail
    z = math.inf if p_half <= 0.0 else float(-ndtri(p_half))
    return math.copysign(max(z, 0.0), t), dof


def pick_array_side(name, f, sigma_el_rad, s0, axes_cam, sky, knobs):
    """
    Pick the sun's side of an array's fit (module docstring) and say what decided it.

    Parameters
    ----------
    name : str
        The method.
    f : SunFrames
        The fitted sun's frames (:func:`~..estimators.sun_from_evectors.sun_frames`).
    sigma_el_rad : float
        1-sigma of the fitted sun's elevation [rad].
    s0 : array_like
        (n,) brightness of the units used.
    axes_cam : array_like
        (n, 3) their viewing axes, camera-equivalent frame.
    sky : object
        ``sun_azimuth_deg``, ``sun_altitude_deg`` and ``prior_bearing_deg``.
    knobs : dict
        ``sign_margin_sigma``, ``side_elevation_sigma_deg``, ``max_tilt_deg``,
        ``brightness_min_t``, ``prior_max_diff_deg``.

    Returns
    -------
    tuple
        ``(Candidate, resolved_by or None, reason, evidence)``; ``evidence`` is a dict of the
        numbers (``side_elevation_z``, ``brightness_z``, ``brightness_dof``).

    """
    upper, lower = sun_side_candidates(f)
    el, alt = f.elevation_deg, float(sky.sun_altitude_deg)
    band = 0.0 if f.levelled else knobs['max_tilt_deg']
    z_up, z_lo = elevation_evidence(
        el, math.degrees(sigma_el_rad), alt, band, knobs['side_elevation_sigma_deg']
    )
    zb, dof = brightness_evidence(s0, axes_cam, upper.sun_cam - lower.sun_cam)
    ev = {'side_elevation_z': [z_up, z_lo], 'brightness_z': zb, 'brightness_dof': dof}
    m = knobs['sign_margin_sigma']
    frame = 'levelled' if f.levelled else f'body-frame (tilt within {band:g} deg)'
    el_txt = (
        f'{frame} sun elevation {el:.1f} deg vs ephemeris {alt:.1f} deg: this side '
        f'{z_up:.1f} sigma, the other {z_lo:.1f} sigma'
    )
    if z_lo - z_up >= m and z_up <= m:
        return upper, 'sun_elevation', f'sun side from the {el_txt}', ev
    reasons = [f'{el_txt} (margin {m:g})']
    if zb is not None and abs(zb) >= knobs['brightness_min_t']:
        if zb < 0 and z_lo - z_up >= 1.0:
            reasons.append(
                f'the brightness gradient (z = {zb:.1f}, {dof} dof) contradicts the elevation'
            )
        else:
            pick = upper if zb > 0 else lower
            why = f'sun side from the brightness gradient (z = {zb:.1f} over {dof} dof)'
            return pick, 'brightness', why, ev
    elif zb is not None:
        reasons.append(
            f'brightness gradient too weak (z = {abs(zb):.1f} over {dof} dof < '
            f'{knobs["brightness_min_t"]:g})'
        )
    else:
        reasons.append('no brightness gradient (fewer than 3 units)')
    pick, by, why = resolve_ambiguity(name, upper, lower, None, sky, knobs, use_brightness=False)
    if by is not None:
        return pick, by, why, ev
    why = why.removeprefix(_UNRESOLVED)
    return upper, None, _UNRESOLVED + '; '.join([*reasons, why]), ev
