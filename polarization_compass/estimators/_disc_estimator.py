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
The estimator skeleton SM-ASM and Symmetry run on (:class:`DiscEstimator`).

An axis of mirror symmetry through the zenith pixel, fitted on the sky disc (:mod:`._disc`); on
mirror-pair weights about its own axis when part of the disc is unusable (:mod:`._mirror`); the 180
deg ambiguity and the cluster-robust uncertainty from the methods' influence passes.
"""

from __future__ import annotations

import math

import numpy as np

from ._axis_solve import AxisFit, MIN_CONDITIONING, refine_axis, solve_axes
from ._common import (
    brightness_t_from_stats,
    Candidate,
    finish_sigma_deg,
    level_sun_candidates,
    resolve_ambiguity,
    result_from,
)
from ._disc import disc_radius, disc_selection, level_rss_many
from ._disc_sigma import (
    _blocks,
    COARSE_CLUSTER_FACTOR,
    COARSE_MIN_COVERAGE,
    cr1_sigma,
    MIN_COARSE_CLUSTERS,
)
from ._knobs import Knob, KnobbedEstimator
from ._mirror import mirror_map, MirrorMap, view_covers_disc
from ._views import _BadInput, check_sun, select_view, selection_for, view_segments
from .base import Estimator, HeadingResult, Observation, Status
from ..camera import CameraModel, PixelSelection
from ..conventions import fold_axial_rad_float

__all__ = ['DISC_KNOBS', 'DiscEstimator']

DISC_KNOBS = {
    'disc_fraction': Knob(
        1.0,
        'float',
        0.05,
        1.0,
        doc='radius of the sky disc used, as a fraction of the largest disc inside the image',
    ),
    'taper_fraction': Knob(
        0.2, 'float', 0.0, 1.0, doc='outer part of the disc over which weights fall to zero'
    ),
    'min_mirror_coverage': Knob(
        0.1,
        'float',
        0.0,
        1.0,
        doc='part of the disc unusable (occluded, invalid, cut by region): the share of the '
        'disc whose mirror image about the axis is also usable must reach this, else '
        'status insufficient_coverage',
    ),
}

#: Pixel subsampling of the coarse scan for self-consistent axes (``scan_at`` of
#: :func:`._axis_solve.solve_axes`).
SCAN_STEP = 8
#: A self-consistent axis whose level Rayleigh pattern misses the usable pixels by more than this
#: factor times the plain (occlusion-biased) fit's rms residual, plus MIRROR_RESIDUAL_SLACK_DEG, is
#: not the meridian (the false ones we met were 30-80 deg away, with residuals of 20-40 deg against
#: a few degrees).
MAX_MIRROR_RESIDUAL_RATIO = 1.5
#: ... plus this (deg): a fixed point on the DoP-symmetric pair weights may miss the level pattern
#: by a few hundredths of a degree more than the plain fit on a coarse lattice with holes (stride
#: 32, every 7th pixel NaN: 0.012 against 0.0007), far below the false axes' misses.
MIRROR_RESIDUAL_SLACK_DEG = 0.1
#: A root of the occlusion-only scan is refined on the DoP-symmetric pair weights to a fixed point
#: at most this far (deg; clouds moved the occlusion-only roots by up to ~20 deg at 70 % cover),
#: else it is dropped.
MAX_REFINE_MOVE_DEG = 30.0
#: Pixel subsampling of the coarse fit whose difference from the full one measures the lattice
#: error (:meth:`DiscEstimator._lattice_rad`).
LATTICE_STEP = 4
#: How many times the full fit's lattice error the sub-lattice fits differ from it: 3 for an error
#: in proportion to the cell area (Richardson); measured noise-free under bench clouds (coverage
#: 0.3, stride 16, 12 scenes) about 6-9 (the sub-lattices are 4x coarser along the rows only and
#: cloud edges are not smooth), so 6: noise-free err^2 / sigma^2 then averages ~1, and with noise
#: this adds ~ 1/12 of the statistical variance.
LATTICE_RATIO = 6.0
#: Pixel subsampling of the residual passes that compare self-consistent axes.
RESIDUAL_STEP = 3


class DiscEstimator(KnobbedEstimator, Estimator):
    """
    An axis of mirror symmetry through the zenith pixel, fitted on the sky disc (level camera).

    Subclasses implement :meth:`_fit` (pass 1 and the plain axis), :meth:`_gather` and
    :meth:`_mirror_fit` (the axis on mirror-pair weights about a trial axis ``near``; None when
    there is no fit) and :meth:`_influence_terms` (pass 2: per pixel the sensitivity times the
    residual against each candidate sun, and the residual sums of squares; :meth:`_influence` sums
    them over blocks).
    """

    axial = True
    KNOB_DEFAULTS = {'stride': 8, 'min_dop': 0.02}

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
        k = self.knobs
        if k['region'] is not None:
            return selection_for(k, camera)
        return disc_selection(camera, k['disc_fraction'], k['stride'])

    def _rho_lo(self, rho_max: float) -> float:
        return 0.0

    def _fit(
        self, data, rho_lo, rho_max
    ) -> AxisFit | HeadingResult:  # pragma: no cover - interface
        raise NotImplementedError

    def _gather(
        self, data, rho_lo, rho_max, mm: MirrorMap
    ) -> dict:  # pragma: no cover - interface
        raise NotImplementedError

    def _mirror_fit(
        self, g: dict, mirror, near: float, plain: AxisFit, step: int = 1, start: int = 0
    ) -> AxisFit | None:  # pragma: no cover
        raise NotImplementedError

    def _influence_terms(
        self, data, rho_lo, rho_max, mirror, fit: AxisFit, s1, s2
    ):  # pragma: no cover - interface
        raise NotImplementedError

    def _influence(self, data, segs, rho_lo, rho_max, mirror, fit: AxisFit, s1, s2):
        """
        Run pass 2: block sums of the influence against both candidate suns, residual sums.

        (block sums (2, n_blocks) over the segments ``segs`` of :func:`._views.view_segments`,
        rss (2,)) from the per-pixel terms of :meth:`_influence_terms`.
        """
        t0, t1, rss = self._influence_terms(data, rho_lo, rho_max, mirror, fit, s1, s2)
        return _blocks(t0, t1, segs), rss

    def _plain_fit(self, cnt, stats, theta: float, quality: float, state: dict) -> AxisFit:
        n = int(cnt[0])
        return AxisFit(theta, n, n, int(cnt[2]), int(cnt[3]), 1.0, stats, quality, state)

    def _too_few(self, n: int) -> HeadingResult | None:
        if n < self.knobs['min_pixels']:
            return HeadingResult.failed(
                self.name,
                Status.TOO_FEW_PIXELS,
                f'{n} usable pixel(s) in the sky disc < min_pixels {self.knobs["min_pixels"]}',
                pixels=n,
            )
        return None

    def _root_ok(self, fit: AxisFit, lenient: bool = False) -> bool:
        """
        Tell whether a self-consistent axis is acceptable beyond coverage and conditioning.

        Default: yes. ``lenient`` for a fit on the scan's subsample.
        """
        return True

    def _root_why(
        self, fit: AxisFit
    ) -> str:  # pragma: no cover - only with a _root_ok that can say no
        return ''

    def _lattice_rad(self, fit_at, fit: AxisFit) -> float:
        """
        Return the estimated error (rad) of the axis from summing over the pixel lattice.

        The fits are lattice sums standing in for integrals over the disc; where the weights have
        sharp edges (cloud edges, the min_dop cut) the sum's error grows with the cell area. The
        fixed point on every ``LATTICE_STEP``-th pixel (cell area x LATTICE_STEP) differs from the
        full one by about (LATTICE_STEP - 1) times the full fit's lattice error (Richardson); the
        rms of that difference over the ``LATTICE_STEP`` interleaved sub-lattices, /
        ``LATTICE_RATIO``, goes into sigma in quadrature. Noise-free it is the only error term the
        residuals cannot show (they are those of the fitted axis itself: a systematic error of the
        axis is ~ sqrt(# blocks) times the cluster-robust sigma); with noise it adds about 1/12 of
        the statistical variance. Sub-lattices without a fixed point (too few pixels) are left
        out.
        """
        d2 = []
        for start in range(LATTICE_STEP):
            coarse, _, _ = refine_axis(  # only the axis: no finite-difference slope
                lambda t: fit_at(t, LATTICE_STEP, start), fit.theta, tol_rad=1e-7, need_slope=False
            )
            if coarse is not None:
                d2.append(fold_axial_rad_float(coarse.theta - fit.theta) ** 2)
        return math.sqrt(sum(d2) / len(d2)) / LATTICE_RATIO if d2 else 0.0

    def _level_ms_many(self, data, rho_lo, rho_max, thetas, obs, step=RESIDUAL_STEP) -> list:
        """
        Return the mean square AoP residual (rad^2) against the level pattern of each axis.

        For each axis of ``thetas`` the level Rayleigh pattern of its better end, over every
        ``step``-th usable pixel: one pixel pass (:func:`._disc.level_rss_many`).
        """
        suns = []
        for theta in thetas:
            s1, s2 = level_sun_candidates(-theta, float(obs.sun_altitude_deg))
            suns += [s1.sun_cam, s2.sun_cam]
        m = len(suns)
        rss = np.zeros(m + 1)
        level_rss_many(
            data[0],
            data[1],
            data[2],
            data[3],
            self.knobs['min_dop'],
            rho_lo,
            rho_max,
            np.array(suns, dtype=np.float64).reshape(m, 3),
            step,
            rss,
        )
        return [float(min(rss[2 * i], rss[2 * i + 1]) / max(rss[m], 1.0)) for i in range(m // 2)]

    def _solve_mirror(self, obs, view, data, rho_lo, rho_max, plain: AxisFit, extras: dict):
        """
        Solve for the axis on mirror-pair weights.

        The axis on the DoP-symmetric mirror-pair weights Q(p) Q(p') (:mod:`._mirror`): the fixed
        point next to the plain fit; failing that (an incomplete disc, the plain fit far off), the
        global scan on the occlusion-only pair weights DoP(p)^2 S(p) S(p') (smoother in the trial
        axis, the search the occlusion handling was built on) with each root refined on Q(p)
        Q(p'). Returns ((fit, mirror arguments, sigma inflation) list, the fit function of the
        Q(p) Q(p') pairs) or a failed result.
        """
        k = self.knobs
        mm = mirror_map(view, obs.camera, rho_max, k['min_dop'])
        g = self._gather(data, rho_lo, rho_max, mm)
        covers = view_covers_disc(view, obs.camera, rho_max)
        complete = plain.holes == 0 and covers

        def fit_at(theta, step=1, start=0):
            f = self._mirror_fit(g, mm.at(theta), theta, plain, step, start)
            return f if f is not None and f.n_paired * step >= k['min_pixels'] else None

        # the fixed point next to the plain fit: the plain fit's DoP^2 weights are not symmetric
        # about the meridian under clouds, the pair weights are (module doc of ._mirror)
        f0, sl0, used0 = refine_axis(fit_at, plain.theta)
        if (
            f0 is not None
            and f0.coverage >= 0.5
            and abs(sl0) >= MIN_CONDITIONING
            and self._root_ok(f0)
        ):
            extras['mirror_fits'] = used0
            extras['mirror_coverage'] = f0.coverage
            if not complete:  # the residual test of estimate() for axes with unusable pixels
                extras['mirror_axes'] = 1
            return [(f0, mm.at(f0.theta), 1.0 / abs(sl0))], fit_at
        roots, failed, used = self._scan_axes(data, rho_lo, rho_max, mm, plain, fit_at)
        extras['mirror_fits'] = used + used0
        sound = self._sound_roots(roots, failed, plain, covers, complete, extras)
        if isinstance(sound, HeadingResult):
            return sound
        extras['mirror_axes'] = len(sound)
        return [(f, mm.at(f.theta), 1.0 / abs(sl)) for f, sl in sound], fit_at

    def _scan_axes(self, data, rho_lo, rho_max, mm: MirrorMap, plain: AxisFit, fit_at):
        """
        Find the self-consistent axes by the global scan on the occlusion-only pair weights.

        Each root that is sound on the occlusion-only weights is refined on the DoP-symmetric
        pairs (``fit_at``) and kept when it moves at most ``MAX_REFINE_MOVE_DEG``. Returns (roots
        as (fit, h') pairs, reasons why an axis was dropped, fits used).
        """
        k = self.knobs
        gate = k['min_mirror_coverage']
        g_occ = self._gather(data, rho_lo, rho_max, mm, own_dop2=True)

        def occ_at(theta, step=1):
            f = self._mirror_fit(g_occ, mm.occlusion_at(theta), theta, plain, step)
            return f if f is not None and f.n_paired * step >= k['min_pixels'] else None

        found, failed, used = solve_axes(
            occ_at,
            lambda t: occ_at(t, SCAN_STEP),
            lambda f: f.coverage >= 0.8 * gate and self._root_ok(f, lenient=True),
            gate,
        )
        roots = []
        for f, sl in found:
            if not (f.coverage >= gate and self._root_ok(f)):
                roots.append((f, sl))  # not sound on the occlusion-only weights: reported below
                continue
            fr, slr, u = refine_axis(fit_at, f.theta)
            used += u
            if fr is None or abs(fold_axial_rad_float(fr.theta - f.theta)) > math.radians(
                MAX_REFINE_MOVE_DEG
            ):
                failed.append(
                    f'the axis near {math.degrees(f.theta) % 180:.1f} deg has no fixed point on '
                    'DoP-symmetric pair weights'
                )
                continue
            roots.append((fr, slr))
        return roots, failed, used

    def _sound_roots(self, roots, failed, plain: AxisFit, covers, complete, extras: dict):
        """
        Return the roots with enough coverage, conditioning and the method's own test.

        Or, when there is none, the failed result that says why (``insufficient_coverage``, or
        ``poor_fit`` for a complete disc: then the sky is not mirror-symmetric).
        """
        gate = self.knobs['min_mirror_coverage']
        if complete:
            why = 'no self-consistent axis next to the plain fit on DoP-symmetric pair weights'
        else:
            why = f'part of the sky disc is unusable ({plain.holes} pixel(s)'
            why += ')' if covers else ' and the view does not cover the disc)'
        # a complete disc without a symmetric axis: the sky is not mirror-symmetric (model)
        status = Status.POOR_FIT if complete else Status.INSUFFICIENT_COVERAGE
        good = [(f, sl) for f, sl in roots if f.coverage >= gate and abs(sl) >= MIN_CONDITIONING]
        sound = [(f, sl) for f, sl in good if self._root_ok(f)]
        if good and not sound:
            f, sl = max(good, key=lambda r: r[0].quality)
            extras['mirror_coverage'] = f.coverage
            return HeadingResult.failed(
                self.name,
                status,
                f'{why}: no axis about which the usable mirror pairs are symmetric '
                f'({self._root_why(f)})',
                pixels=plain.n,
                **extras,
            )
        if not sound:
            if roots:
                f, sl = max(roots, key=lambda r: r[0].coverage)
                detail = (
                    f'only {f.coverage:.3f} of the disc has a usable mirror image about the best '
                    'axis '
                    f"(min_mirror_coverage {gate:g}; |1 - f'| = {abs(sl):.2g})"
                )
                extras['mirror_coverage'] = f.coverage
            else:
                detail = failed[0] if failed else 'no self-consistent axis'
            return HeadingResult.failed(
                self.name,
                status,
                f'{why}: {detail}',
                pixels=plain.n,
                **extras,
            )
        return sound

    def estimate(self, obs: Observation, sigma: bool = True) -> HeadingResult:
        """
        Estimate one heading from the axis of mirror symmetry through the zenith pixel.

        Pass 1 fits the axis theta (``psi = -theta``, axial); the axis is then re-fitted on
        mirror-symmetric pair weights (the DoP of a pixel and of its mirror image, zero where
        either is unusable) as a fixed point, or reported as ``insufficient_coverage`` /
        ``poor_fit``; an axis that fits the level Rayleigh pattern no better than its perpendicular
        is ``poor_fit``. Pass 2 (the influence kernel) gives the uncertainty (cluster-robust at two
        block sizes, divided by ``|1 - f'|``, and the lattice term of :meth:`_lattice_rad` in
        quadrature) and the Rayleigh residuals of the two ends of the meridian, which may resolve
        the 180 deg ambiguity together with the brightness gradient or a prior.
        ``sigma=False`` skips pass 2: ``sigma_deg`` is None, ``extras`` has no
        ``rms_residual_deg``, and an unresolved (axial) result names the end ``psi = -theta``
        rather than the one the Rayleigh residuals prefer. On the mirror-pair path with re-fitted
        axes, whose acceptance test needs the residuals, pass 2 runs anyway (and
        ``rms_residual_deg`` is reported).

        Parameters
        ----------
        obs : Observation
            AoP [rad, eq 28], DoP, valid mask, camera-frame rays, the sun (azimuth clockwise from
            North and geometric altitude, deg); optional ``prior_bearing_deg`` [deg].
        sigma : bool, default True
            Compute the 1-sigma uncertainty ``sigma_deg`` (cluster-robust over blocks of
            ``block_px``).

        Returns
        -------
        HeadingResult
            psi [deg, (-180, 180]] (eq 21), true bearing of camera +y and REP-103 yaw,
            ``sigma_deg``, pixels used and quality (status ``ambiguous`` when the 180 deg ambiguity
            is unresolved); or a failure status with a reason (sun below the horizon or near the
            zenith, bad input, too few pixels, degenerate data, insufficient coverage), never NaN.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 29-30 (AOPLM) and
           Sec. 3 (SM-ASM and symmetry approaches).

        """
        k = self.knobs
        bad = check_sun(self.name, obs, k)
        if bad is not None:
            return bad
        rho_max = disc_radius(obs.camera) * k['disc_fraction']
        rho_lo = self._rho_lo(rho_max)
        try:
            view = select_view(obs, k)
        except _BadInput as exc:
            return HeadingResult.failed(self.name, Status.BAD_INPUT, str(exc))
        data, segs = view_segments(view, k['block_px'])
        plain = self._fit(data, rho_lo, rho_max)
        if isinstance(plain, HeadingResult):
            return plain
        extras: dict = {}
        solved = self._solve_mirror(obs, view, data, rho_lo, rho_max, plain, extras)
        if isinstance(solved, HeadingResult):
            return solved
        candidates, fit_at = solved
        best = self._best_axis(data, rho_lo, rho_max, candidates, plain, obs, extras)
        if isinstance(best, HeadingResult):
            return best
        fit, mirror, inflation, ms_plain = best
        first, second = level_sun_candidates(-fit.theta, float(obs.sun_altitude_deg))
        j, rms_deg, terms = 0, None, None
        if sigma or 'mirror_axes' in extras:
            terms = self._influence_terms(
                data, rho_lo, rho_max, mirror, fit, first.sun_cam, second.sun_cam
            )
            rss = terms[2]
            j = int(np.argmin(rss))  # the end of the meridian the Rayleigh residuals prefer
            rms_deg = math.degrees(math.sqrt(rss[j] / fit.n))
        extras['mirror_sigma_inflation'] = inflation
        if 'mirror_axes' in extras:
            extras['mirror_coverage'] = fit.coverage
            bad = self._mirror_residual_test(fit, rms_deg, ms_plain, extras)
            if bad is not None:
                return bad
        n = fit.n_paired
        sigma_deg = None
        if sigma:
            lattice = self._lattice_rad(fit_at, fit)
            extras['lattice_sigma_deg'] = math.degrees(lattice)
            suns = (first.sun_cam, second.sun_cam)
            stat = self._cluster_sigma_rad(
                view, segs, terms, j, rho_lo, rho_max, mirror, fit, suns, extras
            )
            sigma_deg = finish_sigma_deg(math.hypot(stat * inflation, lattice), k)
        if j == 1:
            first, second = second, first
        has_i = data[6] is not None
        bt = brightness_t_from_stats(fit.stats if has_i else None, first.sun_cam - second.sun_cam)
        pick, by, reason = resolve_ambiguity(self.name, first, second, bt, obs, k)
        extras.update(fit.state.get('extras', {}))
        if rms_deg is not None:
            extras['rms_residual_deg'] = rms_deg
        return result_from(
            self.name,
            Candidate(pick.psi_rad, pick.sun_cam),
            by,
            reason,
            obs,
            sigma_deg,
            n,
            fit.nonfinite,
            fit.quality,
            extras=extras,
        )

    def _best_axis(self, data, rho_lo, rho_max, candidates, plain: AxisFit, obs, extras: dict):
        """
        Return the candidate axis that fits the level Rayleigh pattern best, if it is the meridian.

        The level-Rayleigh residuals this needs come from one pass: of each candidate axis, of its
        perpendicular, and of the plain fit (for :meth:`_mirror_residual_test`). Returns (fit,
        mirror arguments, sigma inflation, the plain fit's mean square residual or None), or a
        ``poor_fit`` result when the axis fits no better than its perpendicular.
        """
        thetas = [c[0].theta for c in candidates]
        thetas += [t + 0.5 * math.pi for t in thetas]
        if 'mirror_axes' in extras:
            thetas.append(plain.theta)
        ms = self._level_ms_many(data, rho_lo, rho_max, thetas, obs)
        nc = len(candidates)
        best = min(range(nc), key=lambda i: ms[i])  # several self-consistent axes: the best fit
        fit, mirror, inflation = candidates[best]
        ms_axis, ms_perp = ms[best], ms[nc + best]
        if not ms_axis < ms_perp:
            # both axes are mirror axes of a Rayleigh sky's AOPLM map when the sun is low; with
            # most of the disc depolarised (70 % cloud, sensor noise) the fit takes the wrong one
            return HeadingResult.failed(
                self.name,
                Status.POOR_FIT,
                'the axis found fits the level Rayleigh pattern no better than its perpendicular '
                f'({math.degrees(math.sqrt(ms_axis)):.3g} against '
                f'{math.degrees(math.sqrt(ms_perp)):.3g} deg rms): not the solar meridian',
                pixels=fit.n,
                **extras,
            )
        return fit, mirror, inflation, (ms[2 * nc] if 'mirror_axes' in extras else None)

    def _mirror_residual_test(self, fit: AxisFit, rms_deg, ms_plain, extras: dict):
        """
        Refuse a re-fitted axis that misses the level Rayleigh pattern far more than the plain fit.

        The limit is ``MAX_MIRROR_RESIDUAL_RATIO`` times the plain fit's rms residual plus
        ``MIRROR_RESIDUAL_SLACK_DEG``. Returns the failed result, or None when the axis passes.
        """
        limit = (
            MAX_MIRROR_RESIDUAL_RATIO * math.degrees(math.sqrt(ms_plain))
            + MIRROR_RESIDUAL_SLACK_DEG
        )
        if rms_deg > limit:
            return HeadingResult.failed(
                self.name,
                Status.INSUFFICIENT_COVERAGE if fit.holes else Status.POOR_FIT,
                f'part of the sky disc is unusable ({fit.holes} pixel(s)): the '
                'self-consistent axes on the '
                f'usable mirror pairs miss the level Rayleigh pattern by {rms_deg:.2g} deg '
                'rms or more '
                f"(> {limit:.2g}, {MAX_MIRROR_RESIDUAL_RATIO:g} x the plain fit's + "
                f'{MIRROR_RESIDUAL_SLACK_DEG:g}): '
                'none is the solar '
                'meridian',
                pixels=fit.n,
                **extras,
            )
        return None

    def _cluster_sigma_rad(
        self, view, segs, terms, j, rho_lo, rho_max, mirror, fit: AxisFit, suns, extras: dict
    ) -> float:
        """
        Return the cluster-robust sigma (rad) of the axis against sun ``j`` of ``suns``.

        Over blocks of ``block_px`` and, where the disc is paired enough and there are enough of
        them, over blocks ``COARSE_CLUSTER_FACTOR`` times larger (the larger of the two; their
        ratio into ``extras``). ``terms``: the influence pass over ``segs``.
        """
        k = self.knobs
        n = fit.n_paired
        stat = cr1_sigma(_blocks(terms[0], terms[1], segs)[j], n)
        coarse_px = COARSE_CLUSTER_FACTOR * k['block_px']
        data_c, segs_c = view_segments(view, coarse_px)
        if fit.coverage >= COARSE_MIN_COVERAGE and segs_c[3] >= MIN_COARSE_CLUSTERS:
            # errors correlated over more than block_px (cloud edges through a superpixel
            # demosaic): the cluster-robust sigma over coarse blocks sees them
            if view.grid is not None or view.subgrids is not None:
                # the same pixel order at both block sizes: the same terms, other blocks
                coarse = _blocks(terms[0], terms[1], segs_c)
            else:  # a pixel list is reordered per block size: a second pass
                coarse, _ = self._influence(
                    data_c, segs_c, rho_lo, rho_max, mirror, fit, suns[0], suns[1]
                )
            stat_c = cr1_sigma(coarse[j], n)
            extras['coarse_cluster_ratio'] = stat_c / stat if stat > 0.0 else 1.0
            stat = max(stat, stat_c)
        return stat
