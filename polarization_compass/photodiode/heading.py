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
Heading from a photodiode array: the least-squares sun of the units' E-vectors (eqs 18, 25-27).

Each usable unit gives one 3-D E-vector (its measured angle of polarization lifted into the body
frame by :func:`~..conventions.unit_evector_body`); under single scattering every E-vector is
perpendicular to the sun, so the sun is the smallest eigenvector of ``M = sum_u w_u e_u e_u^T`` --
the same solve as the camera's :class:`~..estimators.least_squares.LeastSquaresEstimator`, on a
handful of units instead of thousands of pixels. The steps after the solve (levelling, eigen-gap
check, the fitted sun near the zenith, the sun's side by its elevation, the brightness gradient's t
statistic or a prior) are the camera's too: :mod:`~..estimators.sun_from_evectors`. The body frame
is read as the default-mounted camera's (camera +y = body front,
:data:`~..conventions.R_BODY_CAM_DEFAULT`), so psi, bearing and REP-103 yaw are those of the body's
front, and pitch/roll are the paper's (about camera +x = body right, camera +y = body front).
``least_squares`` reads the heading in the body frame (level assumption); ``tilt_aware`` levels the
E-vectors with the known pitch and roll first (exact under Rayleigh at any tilt).

Uncertainty: first-order eigenvector perturbation, as in the camera method. An angle error eps_u of
unit u turns its E-vector about the unit's axis p_u, moving ``e_u . s`` by ``eps_u * l_u`` with
``l_u = (p_u x e_u) . s``, and psi by ``-w_u l_u (e_u . c) eps_u`` (c the sensitivity vector). The
angle errors are taken as independent with variance ``sigma_eps^2 / w_u``; ``sigma_eps^2`` comes
from the units' angle residuals against the fitted sun (so the misfit of a real sky to the model
counts), pooled, because a few units pin it down poorly, with a prior angle noise
(``aop_noise_prior_deg`` worth ``prior_dof`` degrees of freedom): ``sigma_eps^2 = (sum w eps^2 +
nu0 eps0^2) / (n - 2 + nu0)``, ``Var psi = sigma_eps^2 sum (w l (e . c))^2 / w``.

Statuses besides the camera's: ``too_few_units`` (fewer usable units than ``min_units``) and
``poor_fit`` (the rms angle residual exceeds ``max_misfit_deg``, or the fitted sun's elevation is
more than ``max_sun_elevation_diff_deg`` from the ephemeris). Which methods run on units is each
estimator class's fact ``accepts_units`` (the registry); the others (zenith, sm_asm, symmetry) need
an image, and :func:`make_array_estimator` refuses them with that reason.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import math

import numpy as np

from .knobs import ARRAY_KNOBS
from .side import pick_array_side
from .stokes import fit_stokes
from ..conventions import fold_axial_rad, R_BODY_CAM_DEFAULT, unit_angle_from_evector_body_rad
from ..errors import CompassError
from ..estimators import registry
from ..estimators._common import check_sun, result_from
from ..estimators.base import HeadingResult, Status
from ..estimators.sun_from_evectors import (
    fit_quality,
    levelling_rotation,
    sensitivity_vectors,
    solve_checked,
    sun_frames,
)

__all__ = [
    'array_methods',
    'ArrayMethodError',
    'ArrayHeadingEstimator',
    'make_array_estimator',
    'axes_spread_deg',
    'estimate_recording',
    'warm_up_array',
]


def array_methods() -> tuple[str, ...]:
    """
    Name the registered methods that run on a photodiode array's units.

    Returns
    -------
    tuple of str
        The methods whose class fact ``accepts_units`` is true, in the registry's order.

    """
    return tuple(n for n in registry.names() if registry.get(n).accepts_units)


_NEEDS_TILT = 'tilt_aware needs the pitch and roll'


class ArrayMethodError(CompassError):
    """A method or knob a photodiode array cannot use."""


@dataclass
class _Sky:
    """What :func:`resolve_ambiguity` and :func:`check_sun` read of an observation."""

    sun_azimuth_deg: float
    sun_altitude_deg: float
    prior_bearing_deg: float | None = None


class ArrayHeadingEstimator:
    """
    Heading of a photodiode array from one sample of per-unit angles of polarization.

    ``name`` one of :func:`array_methods` (``needs_tilt`` classes level with the known pitch and
    roll); ``geometry`` an :class:`~.geometry.ArrayGeometry`; knobs from :data:`ARRAY_KNOBS`.
    """

    def __init__(self, name: str, geometry, **knobs):
        cls = registry.find(name)
        if cls is None or not cls.accepts_units:
            raise ArrayMethodError(_method_message(name))
        self.name = name
        self.level_with_tilt = bool(cls.needs_tilt)
        self.geometry = geometry
        unknown = sorted(set(knobs) - set(ARRAY_KNOBS))
        if unknown:
            raise ArrayMethodError(
                f'unknown array knob(s) {", ".join(unknown)}; known: {", ".join(ARRAY_KNOBS)}'
            )
        self.knobs = {
            k: spec.check(k, knobs.get(k, spec.default)) for k, spec in ARRAY_KNOBS.items()
        }
        if self.knobs['min_sun_altitude_deg'] >= self.knobs['max_sun_altitude_deg']:
            raise ArrayMethodError('min_sun_altitude_deg must be below max_sun_altitude_deg')
        g = geometry
        self._az = np.array([u.azimuth_deg for u in g.units])
        self._el = np.array([u.elevation_deg for u in g.units])
        self._enabled = np.array([u.enabled for u in g.units])
        self._axes_cam = g.axes_body() @ R_BODY_CAM_DEFAULT  # rows: R_BODY_CAM^T p_body

    # ------------------------------------------------------------------------------------------
    def estimate(
        self,
        aop_rad,
        dop,
        s0,
        valid,
        sun_azimuth_deg: float,
        sun_altitude_deg: float,
        pitch_deg: float | None = None,
        roll_deg: float | None = None,
        prior_bearing_deg: float | None = None,
        unusable: dict | None = None,
    ) -> HeadingResult:
        """
        Estimate one heading from one sample of per-unit angles of polarization.

        Parameters
        ----------
        aop_rad : array_like
            (U,) angle of polarization of each unit [rad] in the units' convention.
        dop : array_like
            (U,) degree of polarization of each unit.
        s0 : array_like
            (U,) brightness (gain-corrected S0) of each unit, for the 180 deg ambiguity.
        valid : array_like of bool
            (U,) units with a usable fit in this sample.
        sun_azimuth_deg : float
            Sun azimuth [deg], clockwise from true North (ephemeris).
        sun_altitude_deg : float
            Sun altitude [deg] (ephemeris).
        pitch_deg : float, optional
            Known pitch [deg] (paper's alpha, about body right); tilt_aware needs it, least_squares
            uses it for the sign rule.
        roll_deg : float, optional
            Known roll [deg] (paper's beta, about body front).
        prior_bearing_deg : float, optional
            Prior bearing of the front [deg]: it resolves the 180 deg ambiguity when nothing
            else does.
        unusable : dict, optional
            Units whose readings were not measurements in this sample, per reason
            (:meth:`~.stokes.UnitStokes.unusable_counts`): reported in ``extras['units_unusable']``
            and the reason, whatever the status.

        Returns
        -------
        HeadingResult
            psi, bearing and REP-103 yaw of the body front, sigma [deg], status with the reason;
            ``pixels`` is the number of units used. Never NaN: a case without an answer gets a
            status instead.

        References
        ----------
        The paper's eqs 18 and 25-27 (least-squares sun from E-vectors); Lambrinos et al. 2000,
        Robot. Auton. Syst. 30 (POL-OP units).

        """
        sky = _Sky(sun_azimuth_deg, sun_altitude_deg, prior_bearing_deg)
        res = self._estimate(aop_rad, dop, s0, valid, sky, pitch_deg, roll_deg)
        return _with_unusable(res, unusable)

    def _estimate(self, aop_rad, dop, s0, valid, sky, pitch_deg, roll_deg) -> HeadingResult:
        """Estimate one heading (:meth:`estimate`), before the unusable units are reported."""
        k = self.knobs
        bad = check_sun(self.name, sky, k)
        if bad is not None:
            return bad
        R_lev = levelling_rotation(
            self.name, pitch_deg, roll_deg, self.level_with_tilt, _NEEDS_TILT, True
        )
        if isinstance(R_lev, HeadingResult):
            return R_lev
        u = self._usable_units(aop_rad, dop, s0, valid)
        if isinstance(u, HeadingResult):
            return u
        spread = axes_spread_deg(u.axes_cam)
        if spread < k['min_axes_spread_deg']:
            return HeadingResult.failed(
                self.name,
                Status.DEGENERATE,
                f"the {u.n} units' view axes spread only {spread:.1f} deg (< min_axes_spread_deg "
                f'{k["min_axes_spread_deg"]:g}): units looking one way cannot fix the sun',
                pixels=u.n,
            )
        fit = self._fit(u, R_lev, float(sky.sun_altitude_deg))
        if isinstance(fit, HeadingResult):
            return fit
        f, lam, sigma_deg, sigma_el, extras = fit
        pick, by, reason, evidence = pick_array_side(
            self.name, f, sigma_el, u.s0, u.axes_cam, sky, k
        )
        extras.update(evidence)
        extras['sun_body'] = [float(v) for v in R_BODY_CAM_DEFAULT @ pick.sun_cam]
        return result_from(
            self.name,
            pick,
            by,
            reason,
            sky,
            sigma_deg,
            u.n,
            0,
            fit_quality(lam),
            sun_altitude_deg=f.implied_altitude_deg(pick.sun_cam),
            extras=extras,
        )

    def _fit(self, u: '_Units', R_lev, sun_altitude_deg: float):
        """
        Fit the sun to the usable units; check the fit.

        Returns ``(frames, eigenvalues, sigma_deg, sigma_el_rad, extras)`` or a failed result
        (``degenerate``, ``sun_near_zenith``, ``poor_fit``).
        """
        k = self.knobs
        zero = np.zeros((3, 3))
        sol = solve_checked(
            self.name, u.M, zero, zero, False, k['min_eigen_gap'], u.n, "the units' E-vectors"
        )
        if isinstance(sol, HeadingResult):
            return sol
        lam, U, _ = sol
        f = sun_frames(self.name, U, R_lev, self.level_with_tilt, k['max_sun_altitude_deg'], u.n)
        if isinstance(f, HeadingResult):
            return f
        resid_rad = self._residuals_rad(u, f.s)
        misfit_deg = math.degrees(
            math.sqrt(float(np.sum(u.w * resid_rad**2)) / float(np.sum(u.w)))
        )
        sigma_psi, sigma_el = self._sigmas_rad(u, f, lam, U, resid_rad)
        sigma_deg = max(math.hypot(math.degrees(sigma_psi), k['sigma_floor_deg']), 1e-9)
        extras = {
            'units_used': u.n,
            'misfit_rms_deg': misfit_deg,
            'unit_residuals_deg': [float(v) for v in np.degrees(resid_rad)],
            'eigenvalues': [float(v) for v in lam / float(np.trace(u.M))],
            'sigma_sun_elevation_deg': math.degrees(sigma_el),
            'sun_altitude_ephemeris_deg': float(sun_altitude_deg),
        }
        poor = self._poor_fit(misfit_deg, f.elevation_deg, sun_altitude_deg, u.n, extras)
        if poor is not None:
            return poor
        return f, lam, sigma_deg, sigma_el, extras

    def _usable_units(self, aop_rad, dop, s0, valid):
        """
        Select the usable units and build ``M = sum w e e^T`` of their E-vectors.

        Returns the :class:`_Units`, or a ``too_few_units`` result.
        """
        k = self.knobs
        aop = np.asarray(aop_rad, dtype=float)
        dop = np.asarray(dop, dtype=float)
        s0 = np.asarray(s0, dtype=float)
        use = (
            np.asarray(valid, dtype=bool)
            & self._enabled
            & np.isfinite(aop)
            & np.isfinite(dop)
            & np.isfinite(s0)
            & (dop >= k['min_dop'])
        )
        n = int(use.sum())
        if n < k['min_units']:
            low = int(np.sum(np.asarray(valid, dtype=bool) & self._enabled & (dop < k['min_dop'])))
            why = f' ({low} with DoP < min_dop {k["min_dop"]:g})' if low else ''
            return HeadingResult.failed(
                self.name,
                Status.TOO_FEW_UNITS,
                f'{n} usable unit(s) < min_units {k["min_units"]}{why}',
                pixels=n,
            )
        e_body = self.geometry.evectors_body(aop)[use]
        e = e_body @ R_BODY_CAM_DEFAULT  # camera-equivalent frame, rows
        w = dop[use] ** 2 if k['weighting'] == 'dop2' else np.ones(n)
        w = w / w.mean()
        M = np.einsum('u,ui,uj->ij', w, e, e)
        return _Units(use, n, aop[use], s0[use], e, self._axes_cam[use], w, M)

    def _residuals_rad(self, u: '_Units', s) -> np.ndarray:
        """
        Return each unit's angle residual [rad] against the fitted sun, in its own convention.

        The model angle is that of ``E = s x p`` (eq 18) for the unit's axis ``p``.
        """
        s_body = R_BODY_CAM_DEFAULT @ s
        pred = unit_angle_from_evector_body_rad(
            self.geometry.sensor_from_body(np.cross(s_body, self.geometry.axes_body()[u.use])),
            self._az[u.use],
            self._el[u.use],
            self.geometry.angle_zero,
            self.geometry.angle_sense,
        )
        return fold_axial_rad(u.aop - pred)

    def _sigmas_rad(self, u: '_Units', f, lam, U, resid_rad):
        """
        Return the 1-sigmas [rad] of psi and of the sun's elevation (module doc).

        A unit's angle error eps turns its E-vector about its axis p: ``d e = eps (p x e)``, so
        ``d(e . s) = eps * lever``; ``Var(eps_u) = sigma_eps^2 / w_u`` with ``sigma_eps^2`` pooled
        from the angle residuals and the prior; the sensitivities of
        :func:`~..estimators.sun_from_evectors.sensitivity_vectors`.
        """
        k = self.knobs
        c_el, c_psi = sensitivity_vectors(f, lam, U)
        w, e = u.w, u.e
        lever = np.einsum('ui,i->u', np.cross(u.axes_cam, e), f.s)
        nu0 = k['prior_dof']
        dof = (u.n - 2) + nu0
        eps0_sq = math.radians(k['aop_noise_prior_deg']) ** 2
        sigma_eps_sq = (float(np.sum(w * resid_rad**2)) + nu0 * eps0_sq) / dof if dof > 0 else 0.0
        infl_psi = w * lever * (e @ c_psi)  # d psi / d eps_u (up to sign)
        infl_el = w * lever * (e @ c_el)
        sigma_psi = math.sqrt(max(sigma_eps_sq * float(np.sum(infl_psi**2 / w)), 0.0))
        sigma_el = math.sqrt(max(sigma_eps_sq * float(np.sum(infl_el**2 / w)), 0.0))
        return sigma_psi, sigma_el

    def _poor_fit(self, misfit_deg: float, el_fit: float, el_ref: float, n: int, extras: dict):
        """
        Return a ``poor_fit`` result when the units do not fit one sun at the ephemeris, else None.

        The rms angle residual above ``max_misfit_deg``, or the fitted sun's elevation more than
        ``max_sun_elevation_diff_deg`` from the ephemeris.
        """
        k = self.knobs
        if misfit_deg > k['max_misfit_deg']:
            return HeadingResult.failed(
                self.name,
                Status.POOR_FIT,
                f'rms angle residual {misfit_deg:.1f} deg > max_misfit_deg '
                f'{k["max_misfit_deg"]:g} over {n} unit(s)',
                pixels=n,
                **extras,
            )
        if abs(el_fit - el_ref) > k['max_sun_elevation_diff_deg']:
            return HeadingResult.failed(
                self.name,
                Status.POOR_FIT,
                f'fitted sun elevation {el_fit:.1f} deg vs ephemeris {el_ref:.1f} deg '
                f'(> {k["max_sun_elevation_diff_deg"]:g} apart)',
                pixels=n,
                **extras,
            )
        return None


@dataclass
class _Units:
    """The usable units of one sample (:meth:`ArrayHeadingEstimator._usable_units`)."""

    use: np.ndarray  # bool (U,): the units used
    n: int  # how many
    aop: np.ndarray  # their angles [rad], in the units' convention (n,)
    s0: np.ndarray  # their brightness (n,)
    e: np.ndarray  # their E-vectors, camera-equivalent frame, rows (n, 3)
    axes_cam: np.ndarray  # their viewing axes, camera-equivalent frame, rows (n, 3)
    w: np.ndarray  # their weights, mean 1 (n,)
    M: np.ndarray  # sum w e e^T (3, 3)


def _method_message(name: str) -> str:
    ok = ', '.join(array_methods())
    if registry.find(name) is not None:
        return (
            f"method {name} needs an image (a camera's sky pattern); a photodiode array supports "
            f'{ok}'
        )
    return f'unknown method {name!r} for a photodiode array; supported: {ok}'


def make_array_estimator(name: str, geometry, **knobs) -> ArrayHeadingEstimator:
    """
    Build an array estimator, refusing image-only or unknown methods.

    Parameters
    ----------
    name : str
        Method name (one of :func:`array_methods`).
    geometry : ArrayGeometry
        The sensor description.
    **knobs
        Array knobs (:data:`ARRAY_KNOBS`).

    Returns
    -------
    ArrayHeadingEstimator
        The estimator.

    """
    return ArrayHeadingEstimator(name, geometry, **knobs)


def estimate_recording(
    estimator: ArrayHeadingEstimator,
    intensities,
    sun_azimuth_deg,
    sun_altitude_deg,
    pitch_deg=None,
    roll_deg=None,
    prior_bearing_deg=None,
    progress=None,
) -> list:
    """
    Estimate a heading for every sample of a recording.

    Parameters
    ----------
    estimator : ArrayHeadingEstimator
        The estimator (its geometry fits the readings).
    intensities : array_like
        (S, U, C) readings.
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], a scalar or (S,).
    sun_altitude_deg : float or array_like
        Sun altitude [deg], a scalar or (S,).
    pitch_deg : float or array_like, optional
        Known pitch [deg], scalar or (S,); None: not known.
    roll_deg : float or array_like, optional
        Known roll [deg], scalar or (S,).
    prior_bearing_deg : float or array_like, optional
        Prior bearing of the front [deg], scalar or (S,).
    progress : callable, optional
        ``progress(samples_done, samples_total)`` every 1000 samples and after the last.

    Returns
    -------
    list of HeadingResult
        One per sample.

    """
    st = fit_stokes(intensities, estimator.geometry)
    S = st.aop_rad.shape[0]

    def per(v):
        if v is None:
            return [None] * S
        a = np.broadcast_to(np.asarray(v, dtype=float), (S,))
        return [float(x) for x in a]

    az, alt, p, r, pr = (
        per(sun_azimuth_deg),
        per(sun_altitude_deg),
        per(pitch_deg),
        per(roll_deg),
        per(prior_bearing_deg),
    )
    out = []
    for i in range(S):
        out.append(
            estimator.estimate(
                st.aop_rad[i],
                st.dop[i],
                st.s0[i],
                st.valid[i],
                az[i],
                alt[i],
                p[i],
                r[i],
                pr[i],
                st.unusable_counts(i),
            )
        )
        if progress is not None and ((i + 1) % 1000 == 0 or i + 1 == S):
            progress(i + 1, S)
    return out


def warm_up_array(estimator: ArrayHeadingEstimator) -> float:
    """
    Estimate one simulated sample so that the estimator's numba kernels are compiled (or loaded).

    The camera node's :func:`~polarization_compass.pipeline.front_end.warm_up` for arrays: without
    it the first real sample waits for the compilation (about 3 s on an empty cache) while the
    samples behind it pile up in the node's readers.

    Parameters
    ----------
    estimator : ArrayHeadingEstimator
        The estimator, with its geometry.

    Returns
    -------
    float
        Seconds it took.

    """
    import time

    from .simulate import simulate_readings

    t0 = time.perf_counter()
    # a level body facing 30 deg under a sun at 180 deg, 35 deg up: a sample every method reads
    x = simulate_readings(estimator.geometry, 180.0, 35.0, [30.0])
    estimate_recording(estimator, x, 180.0, 35.0, 0.0, 0.0)
    return time.perf_counter() - t0


def axes_spread_deg(axes) -> float:
    """
    Return how widely view axes spread: asin of the root of their scatter's middle eigenvalue.

    Parameters
    ----------
    axes : array_like
        (n, 3) unit view axes.

    Returns
    -------
    float
        [deg]: 0 when every axis is the same (the E-vectors then all lie in one plane and its
        normal, the common axis, is the "sun" whatever the sky), about 45 for two axes at right
        angles, 30 for the 8-unit POL-OP ring at 45 deg elevation.

    """
    p = np.asarray(axes, dtype=float)
    lam = np.linalg.eigvalsh(p.T @ p / max(len(p), 1))
    return math.degrees(math.asin(math.sqrt(min(max(float(lam[1]), 0.0), 1.0))))


def _with_unusable(res: HeadingResult, unusable: dict | None) -> HeadingResult:
    """Report the units that were not measurements in a result's extras and reason."""
    if not unusable:
        return res
    counts = {str(k): int(v) for k, v in unusable.items() if v}
    if not counts:
        return res
    note = 'units not measuring: ' + ', '.join(f'{k} {v}' for k, v in counts.items())
    extras = dict(res.extras)
    extras['units_unusable'] = counts
    reason = f'{res.reason}; {note}' if res.reason else note
    return dataclasses.replace(res, reason=reason, extras=extras)
