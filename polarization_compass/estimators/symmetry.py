"""The symmetry approach: the AOPLM map is antisymmetric about the solar meridian.

Mirroring the sky about the meridian plane mirrors every E-vector, so with ``c = exp(2i AOPLM)`` (an
axial quantity as a unit complex number) and polar angle ``phi`` about the zenith pixel (from +y_cam
towards +x_cam), the axis ``theta`` satisfies ``c(rho, 2 theta - phi) = conj(c(rho, phi))``.

Polar-coordinate correlation, without resampling: write each ring's ``c`` as a Fourier series in
``phi``, ``c = sum_k a_k(rho) e^{i k phi}``. The antisymmetry is ``a_k e^{2ik theta} = conj(a_k)`` for every
k and ring, so the correlation

    F(theta) = Re sum_k sum_rings a_k^2 e^{2ik theta},   k = +-1 .. +-K

is at most ``sum |a_k|^2`` and reaches it exactly at the symmetry axis. F is the polar correlation of
the AOPLM map with its own mirror image at axis theta (what a warpPolar + FFT correlation computes),
restricted to K harmonics; because it is a short trigonometric polynomial it is evaluated on a fine grid
(coarse search) and refined by Newton's method (fine step), exactly, with no interpolation of the image.
The ring coefficients are direct pixel sums (linear split between neighbouring rings, smooth taper,
one compiled pass). Why not warpPolar: resampling the AoP image onto a polar grid interpolates an axial
angle field and breaks the exact symmetry at the level we test (0.01 deg).

The heading is ``psi = -theta`` (mod 180 deg: axial; the mirror symmetry says nothing about which end
holds the sun). When the sun lies on the camera's horizon (camera-frame elevation 0: a low sun and a
camera tilted away from it) the pattern is also antisymmetric about the perpendicular axis, and F ties.
The tie is broken by the fact the SM-ASM method uses: along the meridian the E-vector is perpendicular
to it (|AOPLM| = 90 deg), along the perpendicular axis it is parallel (AOPLM = 0); among the near-best
peaks of F the best one with ``S(theta) = -Re sum_even a_k e^{ik theta} > 0`` is kept.
``extras['second_axis_score']`` reports how close the best other axis comes (1 = tie).
Uncertainty: implicit-function sensitivity ``d theta / d a_i = -(d F'/d a_i) / F''``, times the residual
against the level Rayleigh pattern, cluster-robust over blocks.
"""
from __future__ import annotations

import math

import numpy as np

from ..camera import CameraModel, PixelSelection
from .base import Estimator, HeadingResult, Observation, Status, register_estimator
from ._aoplm import DISC_KNOBS, cr1_sigma, disc_radius, disc_selection, ring_pass1, ring_pass2
from ._common import (Candidate, Knob, KnobbedEstimator, _BadInput, brightness_t_from_stats, check_sun,
                      finish_sigma_deg, level_sun_candidates, resolve_ambiguity, result_from, select_view,
                      view_segments)

__all__ = ["SymmetryEstimator"]


def _F_derivs(b, K, theta):
    """F, F', F'' at theta for b[k + K] = sum_rings a_k^2 (k = -K..K, k = 0 excluded)."""
    ks = np.arange(-K, K + 1)
    ks_nz = ks != 0
    ph = np.exp(2j * ks * theta)
    t = b * ph
    F = float(np.sum(t[ks_nz]).real)
    F1 = float(np.sum((2j * ks * t)[ks_nz]).real)
    F2 = float(np.sum((-4.0 * ks * ks * t)[ks_nz]).real)
    return F, F1, F2


@register_estimator("symmetry")
class SymmetryEstimator(KnobbedEstimator, Estimator):
    """Axis of antisymmetry of the AOPLM map (level-camera assumption)."""

    axial = True
    OWN_KNOBS = dict(DISC_KNOBS,
                     harmonics=Knob(2, "int", 1, 32, doc="circular harmonics K used in the correlation"),
                     rings=Knob(24, "int", 2, 4096, doc="radial rings of the polar decomposition"),
                     inner_fraction=Knob(0.05, "float", 0.0, 0.9,
                                         doc="ignore the disc's centre (AOPLM is singular at the zenith pixel)"),
                     search_steps=Knob(720, "int", 8, 100000, doc="grid points of the coarse axis search over 180 deg"))
    KNOB_DEFAULTS = {"stride": 8, "min_dop": 0.02}

    def __init__(self, **knobs):
        super().__init__(**knobs)
        self.knobs = self._validate_knobs(knobs)

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        k = self.knobs
        if k["region"] is not None:
            x0, y0, w, h = k["region"]
            return PixelSelection.rect(x0, y0, w, h, k["stride"])
        return disc_selection(camera, k["disc_fraction"], k["stride"])

    def estimate(self, obs: Observation) -> HeadingResult:
        k = self.knobs
        bad = check_sun(self.name, obs, k)
        if bad is not None:
            return bad
        rho_max = disc_radius(obs.camera) * k["disc_fraction"]
        rho_lo = max(rho_max * k["inner_fraction"], 1e-9)
        try:
            view = select_view(obs, k)
        except _BadInput as exc:
            return HeadingResult.failed(self.name, Status.BAD_INPUT, str(exc))
        (aop, dop, valid, rays, _, _, inten), segs = view_segments(view, k["block_px"])
        has_i = inten is not None
        ib = inten if has_i else np.zeros(1, np.float32)
        K, NR = k["harmonics"], k["rings"]
        a = np.zeros((2 * K + 1, NR), dtype=np.complex128)
        cnt = np.zeros(3, np.int64)
        stats = np.zeros(15)
        ring_pass1(aop, dop, valid, rays, ib, has_i, k["min_dop"], rho_lo, rho_max, k["taper_fraction"], NR, K,
                   a, cnt, stats)
        n, nonfinite = int(cnt[0]), int(cnt[2])
        if n < k["min_pixels"]:
            return HeadingResult.failed(self.name, Status.TOO_FEW_PIXELS,
                                        f"{n} usable pixel(s) in the sky disc < min_pixels {k['min_pixels']}",
                                        pixels=n)
        ks = np.arange(-K, K + 1)
        nz = ks != 0
        b = np.sum(a * a, axis=1)
        energy = float(np.sum(np.abs(a[nz]) ** 2))
        if not energy > 0.0:
            return HeadingResult.failed(self.name, Status.DEGENERATE, "no circular structure in the AOPLM map",
                                        pixels=n)
        # coarse search over theta in [0, pi), then Newton on F'(theta) = 0
        grid = np.arange(k["search_steps"]) * (math.pi / k["search_steps"])
        Fg = (np.exp(2j * np.outer(grid, ks[nz])) @ b[nz]).real
        # Which axis: the meridian carries |AOPLM| = 90 deg along itself (E perpendicular to it), the
        # perpendicular axis AOPLM = 0 -- and when the sun lies on the camera's horizon the pattern is
        # antisymmetric about both. S(theta) = -Re c averaged along the axis (even harmonics: both ends)
        # is > 0 on the meridian: among the near-best peaks of F, keep the best one with S > 0.
        even = (ks % 2 == 0)
        a_sum = a.sum(axis=1)
        Sg = -(np.exp(1j * np.outer(grid, ks[even])) @ a_sum[even]).real
        peak = (Fg >= np.roll(Fg, 1)) & (Fg >= np.roll(Fg, -1)) & (Fg >= 0.5 * Fg.max())
        good = peak & (Sg > 0.0)
        pool = np.nonzero(good)[0] if good.any() else np.nonzero(peak)[0]
        theta = float(grid[pool[int(np.argmax(Fg[pool]))]])
        step = math.pi / k["search_steps"]
        for _ in range(30):
            F, F1, F2 = _F_derivs(b, K, theta)
            if not F2 < 0.0:
                break
            dt = max(-step, min(step, -F1 / F2))
            theta += dt
            if abs(dt) < 1e-14:
                break
        F, F1, F2 = _F_derivs(b, K, theta)
        far = np.abs(((grid - theta + math.pi / 2) % math.pi) - math.pi / 2) > math.radians(10.0)
        second = float(Fg[far].max()) / F if far.any() and F > 0 else 0.0
        psi = -theta
        first, other = level_sun_candidates(psi, float(obs.sun_altitude_deg))
        block_sum = np.zeros((2, segs[3]))
        rss = np.zeros(2)
        if F2 < 0.0:
            rot = np.exp(2j * ks * theta)
            ring_pass2(aop, dop, valid, rays, segs[0], segs[1], segs[2], k["min_dop"], rho_lo, rho_max,
                       k["taper_fraction"], NR, K, a, rot, F2, first.sun_cam, other.sun_cam, block_sum, rss)
        j = int(np.argmin(rss))
        sigma = cr1_sigma(block_sum[j], n)
        if j == 1:
            first, other = other, first
        bt = brightness_t_from_stats(stats if has_i else None, first.sun_cam - other.sun_cam)
        pick, by, reason = resolve_ambiguity(self.name, first, other, bt, obs, k)
        quality = max(0.0, F / energy)
        extras = {"second_axis_score": second, "rms_residual_deg": math.degrees(math.sqrt(rss[j] / n))}
        return result_from(self.name, Candidate(pick.psi_rad, pick.sun_cam), by, reason, obs,
                           finish_sigma_deg(sigma, k), n, nonfinite, quality, extras=extras)
