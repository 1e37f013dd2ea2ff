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
The self-consistent axes of the disc methods: fixed points ``theta = f(theta)`` of a paired fit.

With mirror-pair weights (:mod:`._mirror`) the axis fit about a trial axis ``theta`` returns
``f(theta)``; the axis is a fixed point. :func:`refine_axis` finds the one next to a start (secant,
with plain iterations when the secant overshoots); :func:`solve_axes` scans ``h = f(theta) -
theta`` over 180 deg and refines every sign change. :class:`AxisFit` is one fit.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..conventions import fold_axial_rad_float

__all__ = ['AxisFit', 'refine_axis', 'solve_axes', 'MIN_CONDITIONING']


#: Secant steps of the refinement of one fixed point before giving up.
MAX_SOLVE_STEPS = 25
#: Plain fixed-point iterations of :func:`refine_axis` when the secant from the start fails.
PICARD_STEPS = 30
#: Trial axes of the coarse scan for fixed points (over 180 deg).
SCAN_AXES = 18
#: A sign change of h between neighbouring scan axes larger than this (rad) is a jump, not a root.
MAX_BRACKET_JUMP = 0.75
#: |1 - f'| below this: the usable pairs do not determine the axis (insufficient_coverage).
MIN_CONDITIONING = 1e-3


# The self-consistent axes
# --------------------------------------------------------------------------------------------
@dataclass
class AxisFit:
    """
    One axis fit on (possibly mirror-weighted) pixels.

    ``theta`` rad from +y_cam towards +x_cam (axial).
    """

    theta: float
    n: int  # usable pixels
    n_paired: int  # usable pixels with a non-zero pair weight
    nonfinite: int
    holes: int  # unusable pixels inside the disc
    coverage: float  # sum taper * m over valid pixels / sum taper over the disc
    stats: np.ndarray
    quality: float
    state: dict  # method specific (for the influence pass)


def _refine(fit_at, t0: float, slope: float, tol_rad: float, max_steps: int):
    """
    Secant iteration on h(t) = fold(fit_at(t).theta - t) from t0 with a first slope estimate.

    Returns (fit at the fixed point or None, the last secant slope, its step length, fits used).
    """
    steps = 0

    def h(x):
        nonlocal steps
        steps += 1
        f = fit_at(x)
        return (None, None) if f is None else (fold_axial_rad_float(f.theta - x), f)

    hb, fb = h(t0)
    tb, ta = t0, t0
    while fb is not None and abs(hb) > tol_rad and steps < max_steps:
        step = max(-0.2, min(0.2, -hb / slope))
        ta, ha = tb, hb
        tb = tb + step
        hb, fb = h(tb)
        if fb is not None and tb != ta and abs((hb - ha) / (tb - ta)) > MIN_CONDITIONING:
            slope = (hb - ha) / (tb - ta)
    if fb is None or abs(hb) > tol_rad:
        return None, slope, 0.0, steps
    fb.theta = tb + hb
    return fb, slope, abs(tb - ta), steps


def refine_axis(
    fit_at,
    t0: float,
    tol_rad: float = 1e-8,
    max_steps: int = MAX_SOLVE_STEPS,
    need_slope: bool = True,
):
    """
    Return the self-consistent axis ``theta = fit_at(theta).theta`` nearest ``t0`` (secant).

    Parameters
    ----------
    fit_at : callable
        Trial axis [rad] -> the fit on pair weights about it (``.theta`` rad), or None.
    t0 : float
        Start [rad], e.g. the plain fit's axis (the pair-weighted fit moves little from it: h'
        starts at -1).
    tol_rad, max_steps
        Convergence |h| [rad] and the most fits.
    need_slope : bool, default True
        False: skip the extra fit of the finite difference (the fit is the same; the returned
        ``h'`` is then the last secant slope, whatever its step length).

    Returns
    -------
    tuple
        (fit at the fixed point, h' = f' - 1 there, fits used); fit None when the iteration does
        not converge. ``h'`` is the last secant slope, or a finite difference over 2e-3 rad when
        the last step was too short (as :func:`solve_axes`).

    Notes
    -----
    Where h is nearly flat at ``t0`` (f' ~ 1: under broken clouds the pairs that survive change
    with the trial axis) the secant steps overshoot; then up to ``PICARD_STEPS`` plain iterations
    ``t <- f(t)`` (they converge where 0 < f' < 1, as at the meridian under clouds: f' ~ 0.7) bring
    the start closer, and the secant runs again from there.

    """
    fit, slope, last, used = _refine(fit_at, t0, -1.0, tol_rad, max_steps)
    if fit is None:
        t, f = t0, fit_at(t0)
        used += 1
        for _ in range(PICARD_STEPS):
            if f is None or abs(fold_axial_rad_float(f.theta - t)) < 1e-3:
                break
            t = t + fold_axial_rad_float(f.theta - t)
            f = fit_at(t)
            used += 1
        if f is None:
            return None, slope, used
        fit, slope, last, n = _refine(fit_at, t, -1.0, tol_rad, max_steps)
        used += n
    if fit is None:
        return None, slope, used
    if need_slope and not last >= 1e-6:
        fd = fit_at(fit.theta + 2e-3)
        used += 1
        if fd is None:
            return None, slope, used
        slope = fold_axial_rad_float(fd.theta - fit.theta - 2e-3) / 2e-3
    return fit, slope, used


def solve_axes(
    fit_at,
    scan_at,
    keep,
    min_coverage: float,
    n_scan: int = SCAN_AXES,
    tol_rad: float = 1e-8,
    max_steps: int = MAX_SOLVE_STEPS,
):
    """
    Every self-consistent axis ``theta = fit_at(theta).theta`` (axial, rad) worth keeping.

    ``h(theta) = fold(f(theta) - theta)`` is scanned on ``n_scan`` axes with ``scan_at`` (a cheaper
    fit on a subsample); each interval where h changes sign (either way: the true axis may repel a
    plain iteration, f' > 1; a jump of h across the fold is not a root) and whose mirror coverage
    reaches ``min_coverage / 2`` at an end (not the degenerate fixed point on an occluder's edge,
    where the pairs shrink to a sliver) is refined by the secant method, first with ``scan_at`` to
    1e-4 rad; roots that ``keep(fit)`` accepts are then refined with ``fit_at`` to ``tol_rad``.
    ``h'`` (= f' - 1) is the last secant slope, or a finite difference over 2e-3 rad when the last
    step was too short. Returns (list of (fit, h'), reasons why no root was found, fits used).
    """
    dt = math.pi / n_scan
    fs = [scan_at(i * dt) for i in range(n_scan)]
    hs = [None if f is None else fold_axial_rad_float(f.theta - i * dt) for i, f in enumerate(fs)]
    used = n_scan
    coarse, failed = [], []
    dropped = -1.0
    best = max([f.coverage for f in fs if f is not None], default=0.0)
    if best < 0.5 * min_coverage:
        failed.append(
            f'at most {best:.3f} of the disc has a usable mirror image about any axis '
            f'(min_mirror_coverage {min_coverage:g})'
        )
    for i in range(n_scan):
        j = (i + 1) % n_scan
        h0, h1 = hs[i], hs[j]
        if h0 is None or h1 is None or (h0 < 0.0) == (h1 < 0.0) or abs(h0 - h1) > MAX_BRACKET_JUMP:
            continue
        if max(fs[i].coverage, fs[j].coverage) < 0.5 * min_coverage:
            dropped = max(dropped, fs[i].coverage, fs[j].coverage)
            continue
        fit, slope, _, n = _refine(
            scan_at, i * dt + dt * h0 / (h0 - h1), (h1 - h0) / dt, 1e-4, max_steps
        )
        used += n
        if fit is not None and not keep(fit):
            dropped = max(dropped, fit.coverage)
        elif fit is not None and all(
            abs(fold_axial_rad_float(fit.theta - c[0].theta)) > 1e-3 for c in coarse
        ):
            coarse.append((fit, slope))
    roots = []
    for fc, slope in coarse:
        fit, slope, last, n = _refine(fit_at, fc.theta, slope, tol_rad, max_steps)
        used += n
        if fit is None:
            failed.append(
                f'no self-consistent axis near {math.degrees(fc.theta) % 180:.1f} deg at full '
                'resolution'
            )
            continue
        if not last >= 1e-6:  # the last secant step is too short for a derivative
            fd = fit_at(fit.theta + 2e-3)
            used += 1
            if fd is None:
                continue
            slope = fold_axial_rad_float(fd.theta - fit.theta - 2e-3) / 2e-3
        roots.append((fit, slope))
    if not roots and not failed and dropped >= 0.0:
        failed.append(
            f'the self-consistent axes have at most {dropped:.3f} of the disc with a usable '
            'mirror image '
            f'or are not symmetric (min_mirror_coverage {min_coverage:g})'
        )
    return roots, failed, used
