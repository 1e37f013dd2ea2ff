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
Machinery shared by the heading estimators.

The Rayleigh geometry helpers, the data-driven (cluster-robust sandwich) uncertainty, the 180 deg
ambiguity resolvers and the result. The knobs (:mod:`._knobs`) and the pixel views and input checks
(:mod:`._views`) have modules of their own; their names are importable from here too.

Nothing here re-derives a convention: frames and angles come from :mod:`..conventions`.

Uncertainty
-----------
Every method is a smooth function of the measured AoP values, so to first order ``d psi = sum_i g_i
* da_i`` with an analytic sensitivity ``g_i``. The noise ``da_i`` is estimated by the residual of
pixel i against the Rayleigh pattern of the fitted solution, and the variance by the cluster-robust
sandwich ``Var = G/(G-1) * (n-1)/(n-p) * sum_blocks (sum_{i in block} g_i r_i)^2`` with square
blocks of ``block_px`` sensor pixels: noise that is correlated between neighbouring pixels
(bilinear demosaicing) stays inside a block and is counted; independent noise (superpixels) gives
the plain sandwich. No noise model or electron count is needed.

"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

# the knobs and the views moved to modules of their own; importable from here as before
from ._knobs import COMMON_KNOBS, Knob, KnobbedEstimator  # noqa: F401
from ._views import (  # noqa: F401
    _BadInput,
    check_sun,
    PixelView,
    Samples,
    samples_from_view,
    select_view,
    selection_for,
    view_grid_layout,
    view_segments,
)
from .base import HeadingResult, Observation
from ..conventions import psi_to_bearing_deg, wrap_180_deg

__all__ = [
    'brightness_t_from_stats',
    'view_segments',
    'view_grid_layout',
    'Knob',
    'KnobbedEstimator',
    'Samples',
    'PixelView',
    'select_view',
    'samples_from_view',
    'cluster_sigma_rad',
    'cr1_factor',
    'Candidate',
    'resolve_ambiguity',
    'psi_from_sun_rad',
    'level_sun_candidates',
    'sun_side_candidates',
    'rayleigh_aop_rad',
]


# --------------------------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------------------------
def psi_from_sun_rad(s_lev) -> float:
    """
    Return psi (rad) of a camera whose levelled frame sees the sun at ``s_lev``.

    s_lev = Rz(psi) s_sun, so psi = -atan2(s_x, s_y).
    """
    return -math.atan2(float(s_lev[0]), float(s_lev[1]))


def sun_from_psi_level(psi_rad: float, altitude_rad: float) -> np.ndarray:
    """Camera-frame sun of a level camera with yaw psi: Rz(psi) (0, cos h, sin h)."""
    ch = math.cos(altitude_rad)
    return np.array([-math.sin(psi_rad) * ch, math.cos(psi_rad) * ch, math.sin(altitude_rad)])


def rayleigh_aop_rad(sun_cam, rays) -> np.ndarray:
    """Eq 28 AoP of the Rayleigh E-vector s x r at rays (3, n), float64, axial in (-pi/2, pi/2]."""
    s = np.asarray(sun_cam, dtype=float)
    ex = s[1] * rays[2] - s[2] * rays[1]
    ey = s[2] * rays[0] - s[0] * rays[2]
    return np.arctan2(ex, ey)


def axial_residual_rad(aop_rad, pred_rad) -> np.ndarray:
    """Axial difference folded to [-pi/2, pi/2) without a division."""
    d = np.asarray(aop_rad) - np.asarray(pred_rad)
    return np.mod(d + np.pi / 2, np.pi) - np.pi / 2


# --------------------------------------------------------------------------------------------
# Uncertainty
# --------------------------------------------------------------------------------------------
def cr1_factor(n_clusters: int, n: int, n_params: int) -> float:
    """
    Return the CR1 small-sample factor of a cluster-robust variance.

    ``G / (G - 1) * (n - 1) / (n - k)``
    for ``G = n_clusters`` clusters (blocks), ``n`` observations (pixels) and ``k = n_params``
    parameters; each part is 1 where it is undefined (``G <= 1``, ``n <= k``). Reference: A. C.
    Cameron and D. L. Miller, "A Practitioner's Guide to Cluster-Robust Inference", J. Human
    Resources 50(2), 317-372 (2015) (the factor Stata uses). Plain arithmetic: the compiled
    least-squares kernel runs it through numba.
    """
    return (n_clusters / (n_clusters - 1.0) if n_clusters > 1 else 1.0) * (
        (n - 1.0) / (n - n_params) if n > n_params else 1.0
    )


def cluster_variance(influence, x_px, y_px, block_px: int, n_params: int = 2) -> float:
    """
    Return the cluster-robust sandwich variance of ``sum_i influence_i``.

    The influence is sensitivity * residual; the clusters are blocks of ``block_px`` sensor pixels,
    and the variance carries the :func:`cr1_factor`.
    """
    phi = np.asarray(influence, dtype=float)
    n = phi.size
    if n == 0:
        return 0.0
    bx = np.floor((np.asarray(x_px) - 0.5) / block_px).astype(np.int64)
    by = np.floor((np.asarray(y_px) - 0.5) / block_px).astype(np.int64)
    bx -= bx.min()
    by -= by.min()
    key = by * (int(bx.max()) + 1) + bx
    sums = np.bincount(key, weights=phi)
    occupied = np.bincount(key) > 0
    G = int(occupied.sum())
    total = float(np.dot(sums, sums))
    return total * cr1_factor(G, n, n_params)


def cluster_sigma_rad(influence, samples: Samples, block_px: int, n_params: int = 2) -> float:
    return math.sqrt(
        max(cluster_variance(influence, samples.x_px, samples.y_px, block_px, n_params), 0.0)
    )


def finish_sigma_deg(sigma_rad: float, knobs: dict) -> float:
    """Statistical sigma (rad) to degrees, with the floor in quadrature and never exactly zero."""
    s = math.degrees(sigma_rad)
    return max(math.hypot(s, knobs['sigma_floor_deg']), 1e-9)


# --------------------------------------------------------------------------------------------
# The 180 deg ambiguity
# --------------------------------------------------------------------------------------------
@dataclass
class Candidate:
    """One of the two headings. ``sun_cam`` is the camera-frame sun it implies."""

    psi_rad: float
    sun_cam: np.ndarray


def brightness_t_from_stats(stats, direction_cam, min_samples: int = 10) -> float | None:
    """
    T statistic of the least-squares slope of intensity against ``r . direction``.

    Positive: the sky is brighter towards ``direction``. The residual standard error includes the
    sky's non-linear brightness profile, so the test is conservative. None without data or with
    fewer than ``min_samples`` samples (pixels; a photodiode array's units).
    """
    if stats is None or stats[0] < min_samples:
        return None
    n, sI, sII = float(stats[0]), float(stats[1]), float(stats[2])
    sr, sIr = np.asarray(stats[3:6]), np.asarray(stats[6:9])
    Srr = np.array(
        [
            [stats[9], stats[10], stats[11]],
            [stats[10], stats[12], stats[13]],
            [stats[11], stats[13], stats[14]],
        ],
        dtype=float,
    )
    d = np.asarray(direction_cam, dtype=float)
    su = float(d @ sr)
    suu = float(d @ Srr @ d) - su * su / n
    suI = float(d @ sIr) - su * sI / n
    sII_c = sII - sI * sI / n
    if not suu > 1e-300:
        return None
    slope = suI / suu
    rss = max(sII_c - slope * suI, 0.0)
    se2 = rss / max(n - 2.0, 1.0) / suu
    if not se2 > 0.0:
        return math.copysign(math.inf, slope) if slope != 0.0 else 0.0
    return slope / math.sqrt(se2)


def resolve_ambiguity(
    name: str,
    first: Candidate,
    second: Candidate,
    brightness: float | None,
    obs: Observation,
    knobs: dict,
    sun_rule=None,
    rule_name: str = 'sun_elevation',
    use_brightness: bool = True,
):
    """
    Pick one of two candidates 180 deg apart; returns (candidate, resolved_by or None, reason).

    Order: ``sun_rule`` (a callable giving (candidate or None, reason), e.g. from the sun's
    elevation; ``resolved_by`` is then ``rule_name``), the sky's brightness gradient
    (``brightness``: the t statistic of intensity against ``r . (s_first - s_second)``, None
    without intensity; not consulted when ``use_brightness`` is False), the prior bearing.
    Unresolved: ``first`` and None.
    """
    reasons = []
    if sun_rule is not None:
        pick, why = sun_rule()
        if pick is not None:
            return pick, rule_name, why
        reasons.append(why)
    t = brightness
    if not use_brightness:
        pass
    elif t is not None:
        if abs(t) >= knobs['brightness_min_t']:
            pick = first if t > 0 else second
            return pick, 'brightness', f'sun side from the brightness gradient (t = {t:.1f})'
        reasons.append(
            f'brightness gradient too weak (|t| = {abs(t):.1f} < {knobs["brightness_min_t"]:g})'
        )
    else:
        reasons.append('no intensity')
    if obs.prior_bearing_deg is not None and math.isfinite(float(obs.prior_bearing_deg)):
        diffs = [
            abs(
                float(
                    wrap_180_deg(
                        psi_to_bearing_deg(math.degrees(c.psi_rad), obs.sun_azimuth_deg)
                        - float(obs.prior_bearing_deg)
                    )
                )
            )
            for c in (first, second)
        ]
        k = int(np.argmin(diffs))
        if diffs[k] <= knobs['prior_max_diff_deg']:
            return (
                (first, second)[k],
                'prior',
                f'sun side from the prior bearing ({diffs[k]:.1f} deg away)',
            )
        reasons.append(
            f'prior bearing {min(diffs):.1f} deg from the nearer candidate '
            f'(> {knobs["prior_max_diff_deg"]:g})'
        )
    else:
        reasons.append('no prior bearing')
    return first, None, '180 deg ambiguity not resolved: ' + '; '.join(reasons)


def level_sun_candidates(psi_rad: float, altitude_deg: float) -> tuple[Candidate, Candidate]:
    """
    Return the two headings of an axial method with the level-camera sun each implies.

    The two headings psi and psi + 180 deg of an axial method, with the level-camera sun each
    implies.
    """
    h = math.radians(altitude_deg)
    other = psi_rad + math.pi
    return (
        Candidate(psi_rad, sun_from_psi_level(psi_rad, h)),
        Candidate(other, sun_from_psi_level(other, h)),
    )


def sun_side_candidates(f) -> tuple[Candidate, Candidate]:
    """
    Return the two headings of a sun known up to sign, the upper one first.

    The headings of ``+s`` and ``-s`` (psi of the levelled sun ``s_h`` and of ``-s_h``), ordered by
    the sign of the side frame's elevation (``s_sign[2] >= 0`` first): the pair that the sun's side
    rules of the camera methods and of the photodiode arrays choose between.

    Parameters
    ----------
    f : SunFrames
        The fitted sun's frames (:func:`.sun_from_evectors.sun_frames`): ``s``, ``s_h`` and
        ``s_sign`` are read.

    Returns
    -------
    tuple of Candidate
        ``(upper, lower)``: the candidate with the sun above the side frame's horizon, the other.

    """
    s, s_h = f.s, f.s_h
    cands = (Candidate(psi_from_sun_rad(s_h), s), Candidate(psi_from_sun_rad(-s_h), -s))
    return cands if f.s_sign[2] >= 0 else cands[::-1]


def result_from(
    name: str,
    cand: Candidate,
    resolved_by,
    reason: str,
    obs: Observation,
    sigma_deg: float,
    pixels: int,
    nonfinite: int,
    quality: float,
    **kw,
) -> HeadingResult:
    """
    Build the final result: axial unless ``resolved_by`` names what fixed the sun's side.

    An axial result has the status ambiguous.
    """
    extras = dict(kw.pop('extras', {}))
    extras['ambiguity_resolved_by'] = resolved_by
    if nonfinite:
        extras['nonfinite_pixels_ignored'] = int(nonfinite)
        reason = (
            reason + '; ' if reason else ''
        ) + f'ignored {nonfinite} valid pixel(s) with non-finite values'
    return HeadingResult.from_psi(
        name,
        math.degrees(cand.psi_rad),
        float(obs.sun_azimuth_deg),
        sigma_deg,
        int(pixels),
        quality,
        resolved_by is None,
        reason,
        extras=extras,
        **kw,
    )
