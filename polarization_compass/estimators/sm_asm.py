"""The SM-ASM approach: the E-vector along the solar and anti-solar meridian is perpendicular to it.

With AOPLM = AoP - xi (eqs 29-30, :mod:`._aoplm`), pixels on the solar/anti-solar meridian have
|AOPLM| = 90 deg. The meridian is the line through the zenith point along which those pixels lie.

Line fit: a **weighted axial fit through the zenith point**, not a Hough transform. Each pixel's
(sensor-plane) direction from the zenith, written ``z_i = r_y + i r_x`` from its ray, is weighted by
``W_i = exp((cos 2 delta_i - 1) / (4 tol^2)) * DoP_i^2 * taper_i`` with ``delta_i`` the AOPLM's distance
from 90 deg (a Gaussian of width ``tol`` near the band, periodic and trig-free: ``cos 2 delta = -Re c``
with ``c = exp(2i AOPLM) = exp(2i AoP) (r_y - i r_x)^2 / rho^2``); the line is the principal axis of ``sum W_i z_i z_i^T``, i.e. ``theta = arg(sum W_i z_i^2) / 2``
(closed form, one pass). Why: the sky is mirror-symmetric about the meridian, the weights are even in
``delta`` and the disc is symmetric, so in the continuum the principal axis *is* the meridian -- no angle
quantisation (a Hough accumulator would need 18000 bins for 0.01 deg), no threshold to alias on the
pixel grid, and an analytic first-order sensitivity for the uncertainty. A Hough transform is more
robust to gross outliers (clouds, buildings); the Gaussian band already down-weights pixels far from
90 deg, and DoP^2 down-weights unpolarized cloud.

The heading: the meridian's image direction ``theta`` (from +y_cam towards +x_cam) points at the sun's
azimuth for a level camera, ``(-sin psi, cos psi)``, so ``psi = -theta`` (mod 180 deg: axial).
Uncertainty: ``d theta = Im(dZ / Z) / 2`` with ``dZ = sum W_i' z_i^2 da_i``; ``da_i`` is the residual
against the level Rayleigh pattern of the fitted heading; cluster-robust sum over blocks.
"""
from __future__ import annotations

import math

import numpy as np

from ..camera import CameraModel, PixelSelection
from .base import Estimator, HeadingResult, Observation, Status, register_estimator
from ._aoplm import DISC_KNOBS, band_pass1, band_pass2, cr1_sigma, disc_radius, disc_selection
from ._common import (Candidate, Knob, KnobbedEstimator, _BadInput, brightness_t_from_stats, check_sun,
                      finish_sigma_deg, level_sun_candidates, resolve_ambiguity, result_from, select_view,
                      view_segments)

__all__ = ["SmAsmEstimator"]


@register_estimator("sm_asm")
class SmAsmEstimator(KnobbedEstimator, Estimator):
    """Solar/anti-solar meridian from |AOPLM| ~ 90 deg pixels (level-camera assumption)."""

    axial = True
    OWN_KNOBS = dict(DISC_KNOBS, aoplm_tol_deg=Knob(10.0, "float", 0.5, 45.0,
                                                   doc="width (1 sigma) of the Gaussian band around |AOPLM| = 90 deg"))
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
        try:
            view = select_view(obs, k)
        except _BadInput as exc:
            return HeadingResult.failed(self.name, Status.BAD_INPUT, str(exc))
        (aop, dop, valid, rays, _, _, inten), segs = view_segments(view, k["block_px"])
        has_i = inten is not None
        ib = inten if has_i else np.zeros(1, np.float32)
        tol = math.radians(k["aoplm_tol_deg"])
        inv4tol2 = 1.0 / (4.0 * tol * tol)
        out = np.zeros(3)
        cnt = np.zeros(3, np.int64)
        stats = np.zeros(15)
        band_pass1(aop, dop, valid, rays, ib, has_i, k["min_dop"], rho_max, k["taper_fraction"], inv4tol2, out,
                   cnt, stats)
        n, nonfinite = int(cnt[0]), int(cnt[2])
        if n < k["min_pixels"]:
            return HeadingResult.failed(self.name, Status.TOO_FEW_PIXELS,
                                        f"{n} usable pixel(s) in the sky disc < min_pixels {k['min_pixels']}",
                                        pixels=n)
        Zr, Zi, norm = out
        modZ2 = Zr * Zr + Zi * Zi
        if not (norm > 0.0) or modZ2 <= (1e-12 * norm) ** 2:
            return HeadingResult.failed(self.name, Status.DEGENERATE,
                                        "no meridian band: no pixel with |AOPLM| near 90 deg and enough DoP", pixels=n)
        theta = 0.5 * math.atan2(Zi, Zr)
        psi = -theta
        first, second = level_sun_candidates(psi, float(obs.sun_altitude_deg))
        block_sum = np.zeros((2, segs[3]))
        rss = np.zeros(2)
        band_pass2(aop, dop, valid, rays, segs[0], segs[1], segs[2], k["min_dop"], rho_max, k["taper_fraction"],
                   inv4tol2, Zr, Zi, first.sun_cam, second.sun_cam, block_sum, rss)
        j = int(np.argmin(rss))                     # the end of the meridian the Rayleigh residuals prefer
        sigma = cr1_sigma(block_sum[j], n)
        if j == 1:
            first, second = second, first
        bt = brightness_t_from_stats(stats if has_i else None, first.sun_cam - second.sun_cam)
        pick, by, reason = resolve_ambiguity(self.name, first, second, bt, obs, k)
        quality = math.sqrt(modZ2) / norm
        extras = {"rms_residual_deg": math.degrees(math.sqrt(rss[j] / n))}
        return result_from(self.name, Candidate(pick.psi_rad, pick.sun_cam), by, reason, obs,
                           finish_sigma_deg(sigma, k), n, nonfinite, quality, extras=extras)
