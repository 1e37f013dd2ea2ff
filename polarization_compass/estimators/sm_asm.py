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
The SM-ASM approach: the E-vector along the solar and anti-solar meridian is perpendicular to it.

With AOPLM = AoP - xi (eqs 29-30, :mod:`._disc`), pixels on the solar/anti-solar meridian have
|AOPLM| = 90 deg. The meridian is the line through the zenith point along which those pixels lie.

Line fit: a **weighted axial fit through the zenith point**, not a Hough transform. Each pixel's
(sensor-plane) direction from the zenith, written ``z_i = r_y + i r_x`` from its ray, is weighted
by ``W_i = exp((cos 2 delta_i - 1) / (4 tol^2)) * DoP_i^2 * taper_i`` with ``delta_i`` the AOPLM's
distance from 90 deg (a Gaussian of width ``tol`` near the band, periodic and trig-free: ``cos 2
delta = -Re c`` with ``c = exp(2i AOPLM) = exp(2i AoP) (r_y - i r_x)^2 / rho^2``); the line is the
principal axis of ``sum W_i z_i z_i^T``, i.e. ``theta = arg(sum W_i z_i^2) / 2`` (closed form, one
pass). Why: the sky is mirror-symmetric about the meridian, the weights are even in ``delta`` and
the disc is symmetric, so in the continuum the principal axis *is* the meridian -- no angle
quantisation (a Hough accumulator would need 18000 bins for 0.01 deg), no threshold to alias on the
pixel grid, and an analytic first-order sensitivity for the uncertainty. A Hough transform is more
robust to gross outliers (clouds, buildings); the Gaussian band already down-weights pixels far
from 90 deg, and the DoP weights down-weight unpolarized cloud. That plain fit (``DoP_i^2``) is the
start: under broken clouds the DoP is not symmetric about the meridian, so the heading is the
fixed point of the fit on mirror-symmetric pair weights ``DoP(p) DoP(p')`` (:mod:`._mirror`).

The heading: the meridian's image direction ``theta`` (from +y_cam towards +x_cam) points at the
sun's azimuth for a level camera, ``(-sin psi, cos psi)``, so ``psi = -theta`` (mod 180 deg:
axial). Uncertainty: ``d theta = Im(dZ / Z) / 2`` with ``dZ = sum W_i' z_i^2 da_i``; ``da_i`` is
the residual against the level Rayleigh pattern of the fitted heading; cluster-robust sum over
blocks.

An incomplete disc (occluders, invalid pixels) breaks the symmetry the fit relies on; the pair
weights also vanish where a pixel or its mirror image is unusable, or the status is
``insufficient_coverage``: see :mod:`._mirror`.
"""

from __future__ import annotations

import math

import numpy as np

from ._axis_solve import AxisFit
from ._disc import disc_cells, DiscRing
from ._disc_estimator import DISC_KNOBS, DiscEstimator
from ._kernels import N_STATS
from ._knobs import Knob
from ._sm_asm_kernels import band_fit, band_gather, band_pass1, band_terms2
from .base import HeadingResult, Status

__all__ = ['SmAsmEstimator']


class SmAsmEstimator(DiscEstimator):
    """
    Estimate the heading by the SM-ASM approach: the meridian of pixels with |AOPLM| ~ 90 deg.

    A weighted axial line fit through the zenith pixel (not a Hough transform; see the module
    docstring); level-camera assumption, axial result (:meth:`DiscEstimator.estimate`).

    Parameters
    ----------
    **knobs
        Validated against :meth:`knob_specs`: ``aoplm_tol_deg`` [deg, 1-sigma width of the band
        around |AOPLM| = 90 deg], the disc knobs and the common knobs (``stride``, ``region``
        [sensor pixels], ``min_dop``, ...).

    Raises
    ------
    EstimatorError
        A knob is unknown or out of range.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 29-30 (AOPLM) and Sec. 3
       (the SM-ASM approach, after its refs [26-29]).
    .. [2] H. Lu, K. Zhao, Z. You et al., "Angle algorithm based on Hough transform for imaging
       polarization navigation sensor", Opt Express 23(6): 7248-62, 2015.

    """

    name = 'sm_asm'
    label = 'SM-ASM'
    style = ('tab:orange', '--')
    paper_method = True
    sweep_knobs = {'stride': 64}
    relative_cost = 7.0

    OWN_KNOBS = dict(
        DISC_KNOBS,
        aoplm_tol_deg=Knob(
            10.0,
            'float',
            0.5,
            45.0,
            doc='width (1 sigma) of the Gaussian band around |AOPLM| = 90 deg',
        ),
    )

    def _inv4tol2(self) -> float:
        tol = math.radians(self.knobs['aoplm_tol_deg'])
        return 1.0 / (4.0 * tol * tol)

    def _axis(self, Zr, Zi, norm, n):
        """Theta = arg(Z) / 2, quality |Z| / sum W rho^2; a failed result without a band."""
        modZ2 = Zr * Zr + Zi * Zi
        if not (norm > 0.0) or modZ2 <= (1e-12 * norm) ** 2:
            return HeadingResult.failed(
                self.name,
                Status.DEGENERATE,
                'no meridian band: no pixel with |AOPLM| near 90 deg and enough DoP',
                pixels=n,
            )
        return 0.5 * math.atan2(Zi, Zr), math.sqrt(modZ2) / norm

    def _ring(self, rho_lo, rho_max):
        k = self.knobs
        return DiscRing(k['min_dop'], rho_lo, rho_max, k['taper_fraction'])

    def _fit(self, data, rho_lo, rho_max):
        inten = data[6]
        has_i = inten is not None
        out = np.zeros(3)
        cnt = np.zeros(4, np.int64)
        stats = np.zeros(N_STATS)
        band_pass1(
            data[:6],
            inten if has_i else np.zeros(1, np.float32),
            has_i,
            self._ring(rho_lo, rho_max),
            self._inv4tol2(),
            out,
            cnt,
            stats,
        )
        n = int(cnt[0])
        few = self._too_few(n)
        if few is not None:
            return few
        Zr, Zi, norm = out
        ax = self._axis(Zr, Zi, norm, n)
        if isinstance(ax, HeadingResult):
            return ax
        return self._plain_fit(cnt, stats, ax[0], ax[1], {'Z': (Zr, Zi)})

    def _gather(self, data, rho_lo, rho_max, mm, own_dop2=False):
        k = self.knobs
        N = data[0].size
        g_uv = np.empty((2, N))
        g_ts = np.empty(N)
        g_val = np.empty((3, N))
        ring = self._ring(rho_lo, rho_max)
        mirror = (mm.grid, mm.weight, mm.params)
        n = band_gather(data[:6], ring, self._inv4tol2(), mirror, own_dop2, g_uv, g_ts, g_val)
        disc = disc_cells(mm.camera, *mm.lattice, rho_lo, rho_max, k['taper_fraction'])
        return {'uv': g_uv, 'ts': g_ts, 'val': g_val, 'n': n, 'disc': disc}

    def _mirror_fit(self, g, mirror, near, plain, step=1, start=0):
        out = np.zeros(5)
        band_fit(g['uv'], g['ts'], g['val'], g['n'], start, step, *mirror, out)
        Zr, Zi, norm, cov, n_pair = out
        ax = self._axis(Zr, Zi, norm, plain.n)
        if isinstance(ax, HeadingResult):
            return None
        return AxisFit(
            ax[0],
            plain.n,
            int(n_pair),
            plain.nonfinite,
            plain.holes,
            cov * step / g['disc'] if g['disc'] > 0.0 else 0.0,
            plain.stats,
            ax[1],
            {'Z': (Zr, Zi)},
        )

    def _influence_terms(self, data, rho_lo, rho_max, mirror, fit, s1, s2):
        N = data[0].size
        t0 = np.empty(N)
        t1 = np.empty(N)
        rss = np.zeros(2)
        band_terms2(
            data[:6],
            self._ring(rho_lo, rho_max),
            self._inv4tol2(),
            tuple(mirror),
            fit.state['Z'],
            (s1, s2),
            t0,
            t1,
            rss,
        )
        return t0, t1, rss
