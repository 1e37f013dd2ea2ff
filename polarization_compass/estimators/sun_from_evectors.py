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
The sun from E-vectors: the core shared by the camera methods and the photodiode arrays.

Every E-vector ``e_i`` (a camera pixel's or a photodiode unit's, lifted to 3-D) is perpendicular to
the sun under the Rayleigh model, so the sun is the eigenvector of the smallest eigenvalue of ``M =
sum_i w_i e_i e_i^T`` (:func:`solve_sun`), up to sign. The steps after the pass over the data are
the same for a camera (``least_squares``, ``tilt_aware``) and a photodiode array
(:mod:`polarization_compass.photodiode.heading`), and live here once:

1. :func:`levelling_rotation`: ``Rx(pitch) Ry(roll)`` of the known tilt (``tilt_aware`` needs it).
2. :func:`solve_checked`: the eigen-solve and its eigen-gap check (status ``degenerate``).
3. :func:`sun_frames`: the fitted sun in the frame the heading is read in (levelled or not) and in
   the frame its side is decided in (levelled whenever the tilt is known); a sun near the zenith is
   refused.
4. :func:`sensitivity_vectors`: first-order sensitivities of the heading and of the sun's elevation
   to ``M`` (the camera propagates them over pixel blocks, the array over its units).
5. :func:`pick_side`: the 180 deg side from the sun's elevation (:func:`sign_rule`), the
   brightness gradient (one t statistic, :func:`~._common.brightness_t_from_stats`, fed by
   :func:`unit_brightness_stats` for the units) or a prior bearing.

:func:`tilt_sensitivity` tells how the heading read after levelling moves with the pitch and roll.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from numba import njit
import numpy as np

from ._common import (
    brightness_t_from_stats,
    Candidate,
    resolve_ambiguity,
    sun_side_candidates,
)
from .base import HeadingResult, Observation, Status
from ..conventions import rot_x, rot_y

__all__ = [
    'fit_quality',
    'levelling_rotation',
    'pick_side',
    'sensitivity_vectors',
    'sign_rule',
    'solve_checked',
    'solve_sun',
    'sun_frames',
    'SunFrames',
    'tilt_sensitivity',
    'unit_brightness_stats',
]


@njit(cache=True, nogil=True)
def _solve_sun_kernel(M, B, C, bias_correction, iterations):  # pragma: no cover - compiled
    lam, U = np.linalg.eigh(M)
    sigma0_sq = 0.0
    if bias_correction:
        for _ in range(iterations):
            s = U[:, 0].copy()
            den = s @ (C @ s)
            if not den > 0.0:
                break
            sigma0_sq = max((s @ (M @ s)) / den, 0.0)
            lam, U = np.linalg.eigh(M - sigma0_sq * B)
    return lam, U, sigma0_sq


def solve_sun(M, B, C, bias_correction=True, iterations=3):
    """
    Find the smallest eigenvector of ``sum w e e^T`` of lifted E-vectors, optionally debiased.

    AoP noise makes ``E[M] = M_true + sigma0^2 B``: a pixel's E-vector turns about its ray, adding
    ``g^2 (t t^T - e e^T)`` per unit AoP variance, which tilts the smallest eigenvector by
    O(sigma^2) -- a bias that does not average out with more pixels. The noise scale is estimated
    from the data, ``sigma0^2 = s^T M s / s^T C s`` (the weighted residual sum over its expectation
    per unit variance), and ``sigma0^2 B`` subtracted; fixed-point iterations (Kanatani-style
    renormalisation: the debiased matrix M - sigma0^2 B ends with a zero smallest eigenvalue; it
    converges in two). Compiled (LAPACK's symmetric eigensolver through numba): numpy's per-call
    overhead made the four 3 x 3 solves cost more than the whole pass over 5 000 pixels.

    Parameters
    ----------
    M : numpy.ndarray
        ``sum_i w_i e_i e_i^T`` of the unit camera-frame E-vectors, (3, 3) float64, symmetric.
    B : array_like
        Expected increase of M per unit AoP variance [1/rad^2], (3, 3).
    C : array_like
        Expected residual ``s^T M s`` per unit AoP variance as a quadratic form, (3, 3).
    bias_correction : bool, default True
        Subtract the estimated noise term ``sigma0^2 B``.
    iterations : int, default 3
        Number of fixed-point iterations of the noise scale.

    Returns
    -------
    lambdas : numpy.ndarray
        Eigenvalues, ascending, (3,).
    U : numpy.ndarray
        Eigenvectors as columns, (3, 3); ``U[:, 0]`` is the camera-frame sun up to sign.
    sigma0_sq : float
        Estimated AoP noise scale sigma0^2 [rad^2]; 0 without bias correction.

    Raises
    ------
    LinAlgError
        ``M`` has non-finite entries (``numpy.linalg.LinAlgError``).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3 (the least-square
       approach, after its refs [33-35]).
    .. [2] Y. Wang, J. Chu, R. Zhang et al., "Orthogonal vector algorithm to obtain the solar
       vector using the single-scattering Rayleigh model", Appl Opt 57(4): 594-601, 2018.

    """
    M = np.ascontiguousarray(M, dtype=np.float64)
    if not np.all(np.isfinite(M)):
        raise np.linalg.LinAlgError('the E-vector matrix has non-finite entries')
    return _solve_sun_kernel(
        M,
        np.ascontiguousarray(B, dtype=np.float64),
        np.ascontiguousarray(C, dtype=np.float64),
        bool(bias_correction),
        int(iterations),
    )


#: Generators of rot_x and rot_y: d/da rot_x(a) = rot_x(a) @ _KX (right-handed, active).
_KX = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_KY = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])


def tilt_sensitivity(s_cam, pitch_deg: float, roll_deg: float):
    """
    Return how the levelled heading of a camera-frame sun moves with the pitch and roll.

    ``psi = -atan2(s_x, s_y)`` of ``s_lev = Rx(pitch) Ry(roll) s_cam``, so ``d psi / d pitch = g .
    (Rx(pitch) K_x Ry(roll) s_cam)`` and ``d psi / d roll = g . (Rx(pitch) Ry(roll) K_y s_cam)``
    with ``g = (-s_lev_y, s_lev_x, 0) / rho^2`` (``rho`` the horizontal norm of ``s_lev``). The
    fitted ``s_cam`` does not depend on the tilt (levelling is applied after the fit), so this is
    the exact first-order sensitivity of a re-estimate at a perturbed tilt (the sign choice
    aside).

    Parameters
    ----------
    s_cam : array_like
        Camera-frame sun direction (3,), unit.
    pitch_deg, roll_deg : float
        Camera pitch alpha and roll beta [deg] (eq 21) used for levelling.

    Returns
    -------
    tuple of float
        ``(d psi / d pitch, d psi / d roll)`` [deg/deg]; (0, 0) for a sun at the levelled zenith.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21.

    """
    s = np.asarray(s_cam, dtype=float)
    Rx, Ry = rot_x(math.radians(pitch_deg)), rot_y(math.radians(roll_deg))
    s_lev = Rx @ Ry @ s
    rho2 = float(s_lev[0] ** 2 + s_lev[1] ** 2)
    if rho2 < 1e-18:
        return 0.0, 0.0
    g = np.array([-s_lev[1], s_lev[0], 0.0]) / rho2
    return float(g @ (Rx @ _KX @ Ry @ s)), float(g @ (Rx @ Ry @ _KY @ s))


def levelling_rotation(
    name: str,
    pitch_deg,
    roll_deg,
    level_with_tilt: bool,
    missing_reason: str,
    refuse_unusable: bool | None = None,
):
    """
    Return the levelling rotation ``Rx(pitch) Ry(roll)`` of a known tilt.

    Parameters
    ----------
    name : str
        The method, for a failed result.
    pitch_deg, roll_deg : float or None
        The known pitch alpha and roll beta [deg] (eq 21), or None when not known.
    level_with_tilt : bool
        The method reads the heading after levelling (``tilt_aware``): the tilt is required.
    missing_reason : str
        The reason of the failed result when a required tilt is missing.
    refuse_unusable : bool, optional
        A given tilt that is not usable (non-finite, ``|pitch| >= 90``): a ``bad_input`` result
        when true, else ignored (None). Default: ``level_with_tilt``.

    Returns
    -------
    numpy.ndarray or None or HeadingResult
        The rotation (3, 3); None without a usable tilt; or a ``bad_input`` result.

    """
    if pitch_deg is None or roll_deg is None:
        R_lev = None
    else:
        p, r = float(pitch_deg), float(roll_deg)
        if math.isfinite(p) and math.isfinite(r) and abs(p) < 90.0 and abs(r) <= 180.0:
            R_lev = rot_x(math.radians(p)) @ rot_y(math.radians(r))
        elif level_with_tilt if refuse_unusable is None else refuse_unusable:
            return HeadingResult.failed(
                name,
                Status.BAD_INPUT,
                f'pitch/roll must be finite, |pitch| < 90: got {p}, {r}',
            )
        else:
            R_lev = None
    if level_with_tilt and R_lev is None:
        return HeadingResult.failed(name, Status.BAD_INPUT, missing_reason)
    return R_lev


def solve_checked(
    name: str,
    M,
    B,
    C,
    bias_correction: bool,
    min_eigen_gap: float,
    pixels: int,
    what: str = 'E-vectors',
):
    """
    Solve for the sun (:func:`solve_sun`) and check that the E-vectors single it out.

    Parameters
    ----------
    name : str
        The method, for a failed result.
    M, B, C : array_like
        As for :func:`solve_sun`, (3, 3).
    bias_correction : bool
        Subtract the estimated noise term (:func:`solve_sun`).
    min_eigen_gap : float
        ``(lambda2 - lambda1) / lambda3`` at or below this: status ``degenerate``.
    pixels : int
        Pixels or units in ``M``, for a failed result.
    what : str, default 'E-vectors'
        What the E-vectors are, in the reason of a degenerate result.

    Returns
    -------
    tuple or HeadingResult
        ``(lambdas, U, sigma0_sq)`` as :func:`solve_sun` returns them, or a ``degenerate`` result.

    """
    lam, U, sigma0_sq = solve_sun(M, B, C, bias_correction)
    if not np.all(np.isfinite(lam)) or lam[2] <= 0.0:
        return HeadingResult.failed(
            name, Status.DEGENERATE, 'no usable E-vector weight', pixels=pixels
        )
    gap = (lam[1] - lam[0]) / lam[2]
    if gap <= min_eigen_gap:
        return HeadingResult.failed(
            name,
            Status.DEGENERATE,
            f'{what} do not single out a sun direction (eigen gap {gap:.2e})',
            pixels=pixels,
        )
    return lam, U, sigma0_sq


def fit_quality(lam) -> float:
    """
    Return the fit quality ``1 - lambda1 / lambda2`` in [0, 1] (1: the E-vectors fit one sun).

    Parameters
    ----------
    lam : numpy.ndarray
        Eigenvalues, ascending (3,).

    Returns
    -------
    float
        The quality; 0 when ``lambda2`` is not positive.

    """
    return 1.0 - lam[0] / lam[1] if lam[1] > 0 else 0.0


@dataclass(frozen=True)
class SunFrames:
    """
    The fitted sun (up to sign) in the frames the heading and its side are read in.

    Attributes
    ----------
    s : numpy.ndarray
        Camera-frame sun, unit (3,), the smallest eigenvector (either sign).
    R : numpy.ndarray
        Rotation into the frame the heading is read in (levelling for ``tilt_aware``, else the
        identity), (3, 3).
    s_h : numpy.ndarray
        ``R s`` (3,).
    rho : float
        Horizontal norm of ``s_h``.
    R_sign : numpy.ndarray
        Rotation into the frame the sun's side is decided in (levelling whenever the tilt is known,
        else the identity), (3, 3).
    s_sign : numpy.ndarray
        ``R_sign s`` (3,).
    levelled : bool
        The side frame is levelled (the tilt is known).

    """

    s: np.ndarray
    R: np.ndarray
    s_h: np.ndarray
    rho: float
    R_sign: np.ndarray
    s_sign: np.ndarray
    levelled: bool

    @property
    def elevation_deg(self) -> float:
        """Return the sun's elevation [deg] above the side frame's horizon, either sign."""
        return math.degrees(math.asin(min(1.0, abs(self.s_sign[2]))))

    def implied_altitude_deg(self, sun_cam) -> float:
        """
        Return the altitude of a camera-frame sun above the side frame's horizon.

        Parameters
        ----------
        sun_cam : numpy.ndarray
            The chosen candidate's camera-frame sun, unit (3,).

        Returns
        -------
        float
            Its altitude [deg] in the side frame (levelled when the tilt is known).

        """
        alt_frame = self.R_sign @ sun_cam
        return math.degrees(math.asin(float(np.clip(alt_frame[2], -1.0, 1.0))))


def sun_frames(
    name: str, U, R_lev, level_with_tilt: bool, max_sun_altitude_deg: float, pixels: int
):
    """
    Read the fitted sun in the heading's frame and the side's frame; refuse a sun near the zenith.

    Parameters
    ----------
    name : str
        The method, for a failed result.
    U : numpy.ndarray
        Eigenvectors as columns (:func:`solve_sun`), (3, 3).
    R_lev : numpy.ndarray or None
        Levelling rotation (:func:`levelling_rotation`), None without a tilt.
    level_with_tilt : bool
        The heading is read after levelling (``tilt_aware``).
    max_sun_altitude_deg : float
        A fitted sun closer to the heading frame's zenith than ``90 - max_sun_altitude_deg`` deg
        is refused (the solar meridian is ill-conditioned).
    pixels : int
        Pixels or units of the fit, for a failed result.

    Returns
    -------
    SunFrames or HeadingResult
        The frames, or a ``sun_near_zenith`` result.

    """
    s = U[:, 0].copy()
    R = R_lev if (level_with_tilt and R_lev is not None) else np.eye(3)
    s_h = R @ s  # the frame the heading is read in
    rho = math.hypot(s_h[0], s_h[1])
    if rho < math.cos(math.radians(max_sun_altitude_deg)):
        return HeadingResult.failed(
            name,
            Status.SUN_NEAR_ZENITH,
            f'the fitted sun is {math.degrees(math.acos(min(rho, 1.0))):.2f} deg from '
            'the zenith: the solar meridian is ill-conditioned',
            pixels=pixels,
        )
    R_sign = R_lev if R_lev is not None else np.eye(3)
    s_sign = R_sign @ s  # the frame the sun's side is decided in
    return SunFrames(s, R, s_h, rho, R_sign, s_sign, R_lev is not None)


def sensitivity_vectors(f: SunFrames, lam, U):
    """
    Return the first-order sensitivities of the sun's elevation and of psi to ``M``.

    Through the eigenvector perturbation ``d s = -sum_k u_k (u_k . dM s) / d_k``: ``d psi = -s^T
    dM c_psi`` and ``d elevation = -s^T dM c_el`` with ``c = sum_k (g . u_k) u_k / d_k``, ``g``
    the gradient of psi (in the heading frame) or of the elevation (in the side frame) with
    respect to ``s``.

    Parameters
    ----------
    f : SunFrames
        The fitted sun's frames.
    lam : numpy.ndarray
        Eigenvalues, ascending (3,).
    U : numpy.ndarray
        Eigenvectors as columns (3, 3).

    Returns
    -------
    tuple of numpy.ndarray
        ``(c_el, c_psi)``, each (3,) [rad per unit of ``M``].

    """
    s_h, rho, R, s_sign, R_sign = f.s_h, f.rho, f.R, f.s_sign, f.R_sign
    g_psi = R.T @ (np.array([-s_h[1], s_h[0], 0.0]) / (rho * rho))
    rho_s = max(math.hypot(s_sign[0], s_sign[1]), 1e-12)
    g_el = R_sign.T @ ((np.array([0.0, 0.0, 1.0]) - s_sign[2] * s_sign) / rho_s)
    d2, d3 = lam[1] - lam[0], lam[2] - lam[0]
    c_psi = (g_psi @ U[:, 1]) / d2 * U[:, 1] + (g_psi @ U[:, 2]) / d3 * U[:, 2]
    c_el = (g_el @ U[:, 1]) / d2 * U[:, 1] + (g_el @ U[:, 2]) / d3 * U[:, 2]
    return c_el, c_psi


def sign_rule(first: Candidate, f: SunFrames, sigma_el: float, knobs: dict, frame: str):
    """
    Return the sun-elevation rule of :func:`._common.resolve_ambiguity`.

    ``first`` (the candidate with the sun above the horizon of the side frame) when its elevation
    exceeds the margin of ``sign_margin_sigma`` sigmas, plus ``max_tilt_deg`` when the side frame
    is the sensor's own, not levelled.

    Parameters
    ----------
    first : Candidate
        The candidate with the sun above the side frame's horizon.
    f : SunFrames
        The fitted sun's frames.
    sigma_el : float
        1-sigma of the sun's elevation [rad].
    knobs : dict
        ``sign_margin_sigma`` and ``max_tilt_deg`` (read only without levelling).
    frame : str
        The sensor's frame in the reasons, e.g. ``"camera-frame"`` or ``"body-frame"``.

    Returns
    -------
    callable
        ``() -> (Candidate or None, reason)``.

    """
    el_deg = f.elevation_deg
    margin_deg = knobs['sign_margin_sigma'] * math.degrees(sigma_el)
    levelled = f.levelled

    def sun_rule():
        if levelled:
            if el_deg > margin_deg:
                return first, (
                    f'sun side from the levelled sun elevation ({el_deg:.2f} deg > '
                    f'{margin_deg:.3f} deg margin)'
                )
            return (
                None,
                f'levelled sun elevation {el_deg:.2f} deg within the {margin_deg:.3f} deg margin',
            )
        lim = knobs['max_tilt_deg'] + margin_deg
        if el_deg > lim:
            return first, (
                f'sun side from the {frame} sun elevation ({el_deg:.2f} deg > '
                'max_tilt_deg '
                f'{knobs["max_tilt_deg"]:g} + {margin_deg:.3f} deg margin)'
            )
        return None, (
            f'{frame} sun elevation {el_deg:.2f} deg <= max_tilt_deg '
            f'{knobs["max_tilt_deg"]:g} '
            f"+ margin: the sun's side is unknown without the tilt"
        )

    return sun_rule


def pick_side(
    name: str,
    f: SunFrames,
    sigma_el: float,
    brightness_stats,
    obs: Observation,
    knobs: dict,
    frame: str,
    min_brightness_samples: int = 10,
):
    """
    Pick the sun's side: its elevation, else the brightness gradient, else a prior bearing.

    The two candidates are the headings of ``+s`` and ``-s``; ``first`` has the sun above the side
    frame's horizon (:func:`._common.sun_side_candidates`). :func:`sign_rule` decides when the
    elevation is clear; else the t statistic of brightness against ``r . (s_first - s_second)``
    (:func:`._common.brightness_t_from_stats`), else the prior
    (:func:`._common.resolve_ambiguity`).

    Parameters
    ----------
    name : str
        The method.
    f : SunFrames
        The fitted sun's frames.
    sigma_el : float
        1-sigma of the sun's elevation [rad].
    brightness_stats : numpy.ndarray or None
        Sufficient statistics of the brightness regression (the pass's, or
        :func:`unit_brightness_stats`); None without intensity.
    obs : Observation
        ``sun_azimuth_deg`` and ``prior_bearing_deg`` are read.
    knobs : dict
        ``sign_margin_sigma``, ``max_tilt_deg`` (without levelling), ``brightness_min_t``,
        ``prior_max_diff_deg``.
    frame : str
        The sensor's frame in the reasons (:func:`sign_rule`).
    min_brightness_samples : int, default 10
        Fewer samples in the statistics: no brightness test.

    Returns
    -------
    tuple
        ``(Candidate, resolved_by or None, reason)`` as :func:`._common.resolve_ambiguity`.

    """
    first, second = sun_side_candidates(f)
    sun_rule = sign_rule(first, f, sigma_el, knobs, frame)
    bt = brightness_t_from_stats(
        brightness_stats, first.sun_cam - second.sun_cam, min_brightness_samples
    )
    return resolve_ambiguity(name, first, second, bt, obs, knobs, sun_rule)


def unit_brightness_stats(brightness, axes) -> np.ndarray:
    """
    Return the sufficient statistics of the brightness regression over a sensor's units.

    The layout :func:`._common.brightness_t_from_stats` reads (that of the camera pass): n, sum I,
    sum I^2, sum r (3), sum I r (3), sum r r^T (6: 00 01 02 11 12 22), with ``r`` a unit's viewing
    axis.

    Parameters
    ----------
    brightness : array_like
        Brightness (S0) of each unit, (U,).
    axes : array_like
        Viewing axes of the units in the camera-equivalent frame, unit rows (U, 3).

    Returns
    -------
    numpy.ndarray
        The statistics (15,), float64.

    """
    inten = np.asarray(brightness, dtype=float)
    r = np.asarray(axes, dtype=float)
    rr = r.T @ r
    return np.concatenate(
        [
            [inten.size, inten.sum(), float(inten @ inten)],
            r.sum(axis=0),
            inten @ r,
            [rr[0, 0], rr[0, 1], rr[0, 2], rr[1, 1], rr[1, 2], rr[2, 2]],
        ]
    )
