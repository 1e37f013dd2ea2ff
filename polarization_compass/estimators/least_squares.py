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
Least-squares sun from E-vectors (the paper's fourth approach) and its exact tilt-aware variant.

Each AoP is lifted to the unit 3-D E-vector ``e_i`` perpendicular to its pixel's ray
(:func:`~polarization_compass.conventions.evector_cam_from_aop`). Under the Rayleigh model every
``e_i`` is perpendicular to the sun, so the camera-frame sun is the eigenvector of the smallest
eigenvalue of ``M = sum_i w_i e_i e_i^T`` (a total least-squares fit), defined up to sign.

``least_squares`` assumes a level camera: ``psi = -atan2(s_x, s_y)``. Under tilt this reproduces
the paper's tilt error. ``tilt_aware`` levels the solution with the known pitch and roll first:
``s_lev = Rx(pitch) Ry(roll) s_cam`` (the same eigenvector: levelling is a rotation, so M need not
be rebuilt) and ``psi = -atan2(s_lev_x, s_lev_y)``: exact at any tilt under the Rayleigh model.
The solve and the steps after it (levelling, eigen-gap check, the sun's side) are those of
:mod:`.sun_from_evectors`, shared with the photodiode arrays; the jackknife sigmas are in
:mod:`.jackknife`.

Sign: the sun is above the horizon. ``tilt_aware`` (and ``least_squares`` when the observation
carries pitch/roll) choose the sign whose *levelled* elevation is positive, if it exceeds
``sign_margin_sigma`` standard deviations. ``least_squares`` without tilt knows only that the
camera is tilted by at most ``max_tilt_deg``: the sign is certain only when the camera-frame
elevation exceeds that plus the margin. Otherwise the brightness gradient or a prior bearing
decide, or the result is axial (ambiguous).

Sampling: an even ``stride`` on a full-resolution observation reads the four phases of the 2 x 2
polarizer mosaic equally (``select_view(..., balance_phases=True)``). A bilinear demosaic gives
each phase anisotropic Stokes noise and so an AoP bias of O(sigma^2) with a phase-dependent sign; a
plain stride reads one phase, and on a full frame that bias (~0.001-0.002 deg) exceeded the
statistical sigma (mean(err^2 / sigma^2) 2-3.5 at stride 2-4, 1.0 with the balanced stride).

Uncertainty: first-order eigenvector perturbation. With residuals ``r_i = s . e_i`` (the noise
projected on the sun), ``d s = -sum_{k=2,3} u_k (u_k^T dM s) / (lambda_k - lambda_1)`` and ``dM s =
sum_i w_i e_i r_i``, so pixel i moves psi by ``phi_i = -sum_k (g . u_k)(u_k . e_i) w_i r_i /
(lambda_k - lambda_1)`` with ``g = d psi / d s``; the variance is the cluster-robust sum of
``phi_i`` over blocks (see ``_common``). Errors correlated beyond a block (the IFOV error of a DoFP
sensor at soft cloud edges) are invisible to it; a delete-a-group jackknife over 16 angular
sectors of blocks (:func:`.jackknife.jackknife_sigma_rad`: 16 refits of 3 x 3 matrices from the
same block sums, no pixel read again) and one over the four mosaic phases of a DoFP sensor
(:func:`.jackknife.phase_jackknife_sigma_rad`, from per-phase sums of the same pass: the IFOV error
differs between the phases) each replace it when significantly larger
(:func:`.jackknife.jackknife_exceeds`, a 5 % chi-square test each; the largest that passes). psi
and status never depend on sigma.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ._block_layout import grid_parities
from ._common import (
    _BadInput,
    check_sun,
    finish_sigma_deg,
    Knob,
    KnobbedEstimator,
    result_from,
    select_view,
    selection_for,
    view_grid_layout,
    view_segments,
)
from ._kernels import full_pass, sub_pass
from ._ls_sigma import _attitude_sigma_deg, _block_sigmas
from ._outlier_trim import _consensus_sun, _trim_outliers
from .base import Estimator, HeadingResult, Observation, Status
from .jackknife import (
    _block_centres_px,
    jackknife_exceeds,
    jackknife_groups,
    jackknife_sigma_rad,
    phase_jackknife_sigma_rad,
)
from .sun_from_evectors import (
    fit_quality,
    levelling_rotation,
    pick_side,
    sensitivity_vectors,
    solve_checked,
    solve_sun,
    sun_frames,
    SunFrames,
    tilt_sensitivity,
)
from ..camera import CameraModel
from ..camera_pixels import PixelSelection
from ..runtime import kernel_array

__all__ = ['LeastSquaresEstimator', 'TiltAwareEstimator']

_NEEDS_TILT = 'tilt_aware needs the camera pitch and roll (Observation.pitch_deg/roll_deg)'


_FIRST_LOOK = 4096  # pixels of the first, noise-scale subsample


def _noise_scale_sq(sub, bias_correction: bool) -> float:
    """
    Return sigma0^2 (rad^2), the AoP noise variance at DoP 1, from subsample sums.

    Under the 1/DoP^2 noise model; 0 when the subsample has no weight or no solution.
    """
    if not np.trace(sub['M']) > 0.0:
        return 0.0
    try:
        _, U, s0sq = solve_sun(sub['M'], sub['B'], sub['C'], bias_correction)
    except np.linalg.LinAlgError:
        return 0.0
    if not bias_correction:
        s = U[:, 0]
        den = float(s @ sub['C'] @ s)
        s0sq = float(s @ sub['M'] @ s) / den if den > 0 else 0.0
    return max(s0sq, 0.0)


class _LSBase(KnobbedEstimator, Estimator):
    axial = False
    accepts_units = True  # the same eigen-solve runs on a photodiode array's unit E-vectors
    OWN_KNOBS = {
        'weighting': Knob(
            'dop2',
            'choice',
            choices=('dop2', 'uniform'),
            doc='pixel weights: DoP^2 (AoP noise ~ 1/DoP) or uniform',
        ),
        'sign_margin_sigma': Knob(
            5.0,
            'float',
            0.0,
            100.0,
            doc="elevation margin, in sigmas, before the sun's side is trusted",
        ),
        'min_eigen_gap': Knob(
            1e-9,
            'float',
            0.0,
            1.0,
            doc='(lambda2 - lambda1) / lambda3 below this: status degenerate',
        ),
        'noise_model': Knob(
            'dop',
            'choice',
            choices=('dop', 'dop_intensity', 'uniform'),
            doc='relative AoP noise variance per pixel for the bias correction: 1/DoP^2, '
            '1/(DoP^2 I) (shot noise, needs intensity) or constant',
        ),
        'bias_correction': Knob(
            True, 'bool', doc='remove the O(sigma^2) noise bias of the eigenvector'
        ),
        'max_aop_noise_deg': Knob(
            5.0,
            'float',
            0.1,
            90.0,
            doc='drop pixels whose estimated AoP noise (sigma0 / DoP) exceeds this',
        ),
        'outlier_deg': Knob(
            0.0,
            'float',
            0.0,
            90.0,
            doc='robust refit (real skies: clouds, flare, obstacles): pixels whose AoP is further '
            'than this from the fitted sky are dropped and the sun refitted, twice; 0 = off',
        ),
    }
    level_with_tilt = False

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        """
        Tell a renderer which pixels the method reads, so sweeps render only those.

        Parameters
        ----------
        camera : CameraModel
            The camera the frames come from.

        Returns
        -------
        PixelSelection
            The pixels that ``stride`` and ``region`` select.

        """
        return selection_for(self.knobs, camera)

    # ------------------------------------------------------------------------------------------
    def estimate(self, obs: Observation, sigma: bool = True) -> HeadingResult:
        """
        Estimate one heading from the smallest eigenvector of ``M = sum w e e^T`` (the sun).

        Each AoP is lifted to its 3-D E-vector, the sun is fitted by total least squares
        (optionally noise-debiased, :func:`.sun_from_evectors.solve_sun`; optionally refitted on
        the pixels that agree with it, ``outlier_deg``), levelled with the known pitch and roll
        when the method does so (``tilt_aware``), and its sign is chosen by the elevation rule, the
        brightness gradient or a prior (:func:`.sun_from_evectors.pick_side`). ``sigma=False``
        (error-map sweeps): ``sigma_deg`` None and no ``rms_residual_deg``; the sun-elevation sigma
        of the sign rule is computed either way, so psi and status are the same.

        Parameters
        ----------
        obs : Observation
            AoP [rad, eq 28], DoP, valid mask, camera-frame rays, the sun (azimuth clockwise from
            North and geometric altitude, deg); known ``pitch_deg``/``roll_deg`` [deg, eq 21]
            (required by ``tilt_aware``) and an optional ``prior_bearing_deg`` [deg].
        sigma : bool, default True
            Compute the 1-sigma uncertainty ``sigma_deg`` (first-order eigenvector perturbation,
            cluster-robust).

        Returns
        -------
        HeadingResult
            psi [deg, (-180, 180]] (eq 21), true bearing of camera +y and REP-103 yaw,
            ``sigma_deg``, pixels used and quality, ``sun_altitude_deg`` implied by the data (a
            consistency check); or a failure status with a reason (sun below the horizon or near
            the zenith, bad input, too few pixels, degenerate data, missing tilt), never NaN.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 21 and 28; Sec. 3
           (the least-square approach, after its refs [33-35]).
        .. [2] Y. Wang, J. Chu, R. Zhang et al., "Orthogonal vector algorithm to obtain the solar
           vector using the single-scattering Rayleigh model", Appl Opt 57(4): 594-601, 2018.

        """
        k = self.knobs
        bad = check_sun(self.name, obs, k)
        if bad is not None:
            return bad
        R_lev = levelling_rotation(
            self.name, obs.pitch_deg, obs.roll_deg, self.level_with_tilt, _NEEDS_TILT
        )
        if isinstance(R_lev, HeadingResult):
            return R_lev
        try:
            view = select_view(obs, k, balance_phases=True)
        except _BadInput as exc:
            return HeadingResult.failed(self.name, Status.BAD_INPUT, str(exc))
        fit = self._fit(view)
        if isinstance(fit, HeadingResult):
            return fit
        if k['outlier_deg'] > 0:
            fit = self._robust_refit(fit, obs)
        f = sun_frames(
            self.name, fit.U, R_lev, self.level_with_tilt, k['max_sun_altitude_deg'], fit.n
        )
        if isinstance(f, HeadingResult):
            return f
        sigmas = self._sigmas(fit, f, sigma)
        sigma_el = float(sigmas[0])
        pick, by, reason = pick_side(
            self.name, f, sigma_el, fit.acc['stats'], obs, k, 'camera-frame'
        )
        extras = {
            'eigenvalues': [float(v / fit.wsum) for v in fit.lam],
            'sigma_sun_elevation_deg': math.degrees(sigma_el),
            'sun_altitude_ephemeris_deg': float(obs.sun_altitude_deg),
            'noise_scale_deg': math.degrees(math.sqrt(fit.sigma0_sq)),
            'min_dop_used': fit.min_dop,
            'sun_cam': [float(v) for v in pick.sun_cam],
            'outliers_dropped': int(fit.trimmed),
        }
        sigma_deg = self._sigma_deg(fit, f, float(sigmas[1]), obs, extras) if sigma else None
        return result_from(
            self.name,
            pick,
            by,
            reason,
            obs,
            sigma_deg,
            fit.n,
            fit.acc['nonfinite'],
            fit_quality(fit.lam),
            sun_altitude_deg=f.implied_altitude_deg(pick.sun_cam),
            extras=extras,
        )

    def _fit(self, view, trimmed: int = 0):
        """
        Fit the sun to a view: the compiled passes, then the checked eigen-solve.

        Returns a :class:`_Fit`, or a failed result (too few pixels, degenerate E-vectors);
        ``trimmed`` is how many outliers the view already lacks (:meth:`_robust_refit`).
        """
        acc, sub, min_dop = self._accumulate(view)
        n = acc['n']
        if n < self.knobs['min_pixels']:
            return self._too_few(n, acc['nonfinite'], min_dop)
        sol = self._solve(acc, sub, n)
        if isinstance(sol, HeadingResult):
            return sol
        return _Fit(view, acc, min_dop, n, *sol, trimmed=trimmed)

    def _robust_refit(self, fit: '_Fit', obs: Observation) -> '_Fit':
        """
        Refit on the pixels that agree with the sky (the ``outlier_deg`` consensus), twice.

        First against the robust whole-view sun (candidate suns over the circle, Cauchy loss: a
        fit pulled by clouds or flare cannot seed it, :func:`_consensus_sun`), then against the
        refitted sun; each round trims the full view. Keeps the last fit that succeeded.
        """
        view = fit.view
        for it in range(2):
            sun0 = _consensus_sun(view, obs) if it == 0 else fit.U[:, 0]
            if sun0 is None:
                break
            view2, dropped = _trim_outliers(view, sun0, self.knobs['outlier_deg'])
            if dropped == fit.trimmed:
                break
            fit2 = self._fit(view2, dropped)
            if isinstance(fit2, HeadingResult):
                break
            fit = fit2
        return fit

    def _sigma_deg(self, fit: '_Fit', f: SunFrames, sigma_fit: float, obs, extras: dict):
        """
        Return the heading's 1-sigma [deg]; its parts go into ``extras``.

        The cluster-robust sigma, replaced by a jackknife's when that is significantly larger
        (:meth:`_jackknife`), the ``sigma_floor_deg`` in quadrature and, for ``tilt_aware``, the
        known tilt's uncertainty (:func:`_attitude_sigma_deg`).
        """
        s, M = f.s, fit.M
        extras['rms_residual_deg'] = math.degrees(math.sqrt(max(float(s @ M @ s) / fit.wsum, 0.0)))
        extras['sigma_cluster_deg'] = math.degrees(sigma_fit)
        sigma_deg = finish_sigma_deg(self._jackknife(fit, f, sigma_fit, extras), self.knobs)
        att = _attitude_sigma_deg(obs, s) if self.level_with_tilt else None
        if att is not None:
            extras['sigma_fit_deg'] = sigma_deg
            extras['sigma_attitude_deg'] = att
            sigma_deg = math.hypot(sigma_deg, att)
        return sigma_deg

    def _jackknife(self, fit: '_Fit', f: SunFrames, sigma_cr: float, extras: dict) -> float:
        """
        Return the fit's sigma of psi [rad]: the cluster-robust one or a larger jackknife's.

        The delete-a-sector jackknife (:func:`.jackknife.jackknife_sigma_rad`) and the
        delete-a-phase one (:func:`.jackknife.phase_jackknife_sigma_rad`) each replace
        ``sigma_cr`` when significantly larger (:func:`.jackknife.jackknife_exceeds`, its own 5 %
        test each); their values go into ``extras``.
        """
        acc, M, s, R = fit.acc, fit.M, f.s, f.R
        jk = None
        centres = _block_centres_px(fit.view, self.knobs['block_px'], acc['block_m'].shape[0])
        if centres is not None:
            groups = jackknife_groups(centres[0], centres[1], acc['block_w'])
            jk = jackknife_sigma_rad(M, acc['B'], acc['block_m'], groups, s, R, fit.sigma0_sq)
        extras['sigma_jackknife_deg'] = None if jk is None else math.degrees(jk[0])
        extras['jackknife_groups'] = 0 if jk is None else jk[1]
        jp = phase_jackknife_sigma_rad(M, acc['B'], acc['phase_m'], s, R, fit.sigma0_sq)
        extras['sigma_phase_jackknife_deg'] = None if jp is None else math.degrees(jp[0])
        extras['phase_jackknife_groups'] = 0 if jp is None else jp[1]
        sigma_fit = sigma_cr
        for j in (jk, jp):  # each its own 5 % test against the cluster-robust sigma
            if j is not None and jackknife_exceeds(j[0], sigma_cr, j[1]):
                sigma_fit = max(sigma_fit, j[0])
        return sigma_fit

    @classmethod
    def tilt_sensitivity(cls, result: HeadingResult, pitch_deg: float, roll_deg: float):
        """
        Return ``(d psi / d pitch, d psi / d roll)`` [deg/deg] of a levelled result, else None.

        :func:`tilt_sensitivity` of the result's camera-frame sun (``extras["sun_cam"]``) for the
        tilt-aware variant; None for ``least_squares`` (it does not level) or a result without a
        sun.

        Parameters
        ----------
        result : HeadingResult
            An ok result of this method.
        pitch_deg, roll_deg : float
            The camera pitch and roll [deg] (eq 21) it was levelled with.

        Returns
        -------
        tuple of float or None
            The sensitivities [deg/deg], or None.

        """
        sun = result.extras.get('sun_cam') if result.extras else None
        if not cls.level_with_tilt or sun is None:
            return None
        return tilt_sensitivity(sun, pitch_deg, roll_deg)

    def _accumulate(self, view):
        """
        Run the compiled passes over a view: (full-pass block sums, subsample sums, min_dop used).

        Noise scale first, on a sparse subsample: pixels whose AoP noise sigma0 / DoP exceeds
        max_aop_noise_deg are dropped (raised min_dop), because there the second-order bias model
        (and the Gaussian picture of AoP noise) breaks down and they add bias, not information.
        """
        k = self.knobs
        flat, segs = view_segments(view, k['block_px'])
        arrs = flat[:4] + flat[6:]
        var_mode = {'uniform': 0, 'dop': 1, 'dop_intensity': 2}[k['noise_model']]
        if var_mode == 2 and arrs[4] is None:
            var_mode = 1
        wmode = 1 if k['weighting'] == 'dop2' else 0
        min_dop = k['min_dop']
        sigma_max = math.radians(k['max_aop_noise_deg'])
        sub = sub_pass(
            *arrs, min_dop, wmode, var_mode, sub_pixels=_FIRST_LOOK
        )  # a first look at the noise
        if var_mode == 1:
            s0sq = _noise_scale_sq(sub, k['bias_correction'])
            min_dop = min(max(k['min_dop'], math.sqrt(s0sq) / sigma_max), 0.99)
        if not (
            min_dop == k['min_dop'] and sub['every_pixel']
        ):  # else the first look read what this would
            sub = sub_pass(*arrs, min_dop, wmode, var_mode)
        keys = (view.grid,) if view.grid is not None else view.subgrids
        acc = full_pass(
            *arrs[:4],
            segs,
            min_dop,
            wmode,
            view_grid_layout(view, k['block_px']),
            None if keys is None else grid_parities(tuple(keys)),
        )
        return acc, sub, min_dop

    def _too_few(self, n: int, nonfinite: int, min_dop: float) -> HeadingResult:
        k = self.knobs
        why = f' (min_dop raised to {min_dop:.3f} by the noise)' if min_dop > k['min_dop'] else ''
        return HeadingResult.failed(
            self.name,
            Status.TOO_FEW_PIXELS,
            f'{n} usable pixel(s) < min_pixels {k["min_pixels"]}{why}'
            + (f' ({nonfinite} valid pixel(s) had non-finite values)' if nonfinite else ''),
            pixels=n,
        )

    def _solve(self, acc: dict, sub: dict, n: int):
        """
        Solve the noise-debiased eigenproblem for the sun direction.

        Returns (M, lambdas ascending, U, sigma0^2), or a failed result when the E-vectors do not
        single out a sun direction (:func:`.sun_from_evectors.solve_checked`). Scales the
        subsample's bias matrices to the full pass first (into ``acc``: B, C, stats).
        """
        k = self.knobs
        M = acc['block_m'].sum(axis=0)
        msub_tr = float(np.trace(sub['M']))
        scale = float(np.trace(M)) / msub_tr if msub_tr > 0 else 0.0
        acc['B'], acc['C'], acc['stats'] = sub['B'] * scale, sub['C'] * scale, sub['stats']
        sol = solve_checked(
            self.name, M, acc['B'], acc['C'], k['bias_correction'], k['min_eigen_gap'], n
        )
        if isinstance(sol, HeadingResult):
            return sol
        return (M, *sol)

    @staticmethod
    def _sigmas(fit: '_Fit', f: SunFrames, with_psi: bool) -> np.ndarray:
        """
        Return the cluster-robust sigmas (rad) of the sun's elevation and (``with_psi``) of psi.

        The first-order sensitivities of :func:`.sun_from_evectors.sensitivity_vectors`
        propagated over the pass's blocks (module doc).
        """
        c_el, c_psi = sensitivity_vectors(f, fit.lam, fit.U)
        cs = np.stack([c_el, c_psi]) if with_psi else c_el[None, :]
        acc = fit.acc
        return _block_sigmas(
            kernel_array(acc['block_m'], np.float64),
            kernel_array(acc['block_w'], np.float64),
            fit.n,
            kernel_array(f.s, np.float64),
            kernel_array(cs, np.float64),
        )


@dataclass
class _Fit:
    """One least-squares fit of the sun to a view (:meth:`_LSBase._fit`)."""

    view: object  # the PixelView fitted
    acc: dict  # the pass's sums (block_m, block_w, phase_m, stats, n, nonfinite; B, C scaled)
    min_dop: float  # the min_dop used (raised by the noise)
    n: int  # pixels used
    M: np.ndarray  # sum w e e^T (3, 3)
    lam: np.ndarray  # eigenvalues, ascending (3,)
    U: np.ndarray  # eigenvectors as columns (3, 3)
    sigma0_sq: float  # AoP noise scale [rad^2]
    trimmed: int = 0  # outliers dropped by the robust refit

    @property
    def wsum(self) -> float:
        """Return the total weight, the trace of ``M``."""
        return float(np.trace(self.M))


class LeastSquaresEstimator(_LSBase):
    """
    Estimate the heading by the paper's least-squares approach (level-camera assumption).

    The camera-frame sun is the eigenvector of the smallest eigenvalue of ``sum w e e^T`` of the
    lifted E-vectors; ``psi = -atan2(s_x, s_y)`` assumes a level camera, so it reproduces the
    paper's tilt error.

    Parameters
    ----------
    **knobs
        Validated against :meth:`knob_specs`: ``weighting``, ``sign_margin_sigma`` [sigmas],
        ``min_eigen_gap``, ``noise_model``, ``bias_correction``, ``max_aop_noise_deg`` [deg],
        ``max_tilt_deg`` [deg, assumed tilt bound for the sign rule] and the common knobs
        (``stride``, ``region`` [sensor pixels], ``min_dop``, ...).

    Raises
    ------
    EstimatorError
        A knob is unknown or out of range.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3 (the least-square
       approach, after its refs [33-35]).
    .. [2] Y. Wang, J. Chu, R. Zhang et al., "Orthogonal vector algorithm to obtain the solar
       vector using the single-scattering Rayleigh model", Appl Opt 57(4): 594-601, 2018.

    """

    name = 'least_squares'
    label = 'Least-squares'
    style = ('tab:red', ':')
    paper_method = True
    sweep_knobs = {'stride': 64}
    relative_cost = 3.0

    OWN_KNOBS = dict(
        _LSBase.OWN_KNOBS,
        max_tilt_deg=Knob(
            30.0, 'float', 0.0, 89.0, doc='assumed bound on the tilt, for the sign rule'
        ),
    )
    level_with_tilt = False


class TiltAwareEstimator(_LSBase):
    """
    Estimate the heading by least squares after levelling with the known pitch and roll.

    ``s_lev = Rx(pitch) Ry(roll) s_cam`` (the transpose of eq 21's tilt part applied to the fitted
    sun) and ``psi = -atan2(s_lev_x, s_lev_y)``: exact under the Rayleigh model at any tilt.

    Parameters
    ----------
    **knobs
        Validated against :meth:`knob_specs`: the least-squares knobs (``weighting``,
        ``sign_margin_sigma`` [sigmas], ``min_eigen_gap``, ``noise_model``, ``bias_correction``,
        ``max_aop_noise_deg`` [deg]) and the common knobs (``stride``, ``region`` [sensor pixels],
        ...).

    Raises
    ------
    EstimatorError
        A knob is unknown or out of range.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 21; Sec. 3 (the
       least-square approach, after its refs [33-35]).
    .. [2] Y. Wang, J. Chu, R. Zhang et al., "Orthogonal vector algorithm to obtain the solar
       vector using the single-scattering Rayleigh model", Appl Opt 57(4): 594-601, 2018.

    """

    name = 'tilt_aware'
    label = 'Tilt-aware LS'
    style = ('tab:purple', '-')
    needs_tilt = True
    sweep_knobs = {'stride': 64}
    relative_cost = 2.6

    level_with_tilt = True
