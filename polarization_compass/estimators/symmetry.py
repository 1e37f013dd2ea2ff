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
The symmetry approach: the AOPLM map is antisymmetric about the solar meridian.

Mirroring the sky about the meridian plane mirrors every E-vector, so with ``c = exp(2i AOPLM)``
(an axial quantity as a unit complex number) and polar angle ``phi`` about the zenith pixel (from
+y_cam towards +x_cam), the axis ``theta`` satisfies ``c(rho, 2 theta - phi) = conj(c(rho, phi))``.

Polar-coordinate correlation, without resampling: write each ring's ``c`` as a Fourier series in
``phi``, ``c = sum_k a_k(rho) e^{i k phi}``. The antisymmetry is ``a_k e^{2ik theta} = conj(a_k)``
for every k and ring, so the correlation

    F(theta) = Re sum_k sum_rings a_k^2 e^{2ik theta},   k = +-1 .. +-K

is at most ``sum |a_k|^2`` and reaches it exactly at the symmetry axis. F is the polar correlation
of the AOPLM map with its own mirror image at axis theta (what a warpPolar + FFT correlation
computes), restricted to K harmonics; because it is a short trigonometric polynomial it is
evaluated on a fine grid (coarse search) and refined by Newton's method (fine step), exactly, with
no interpolation of the image. The ring coefficients are direct pixel sums (linear split between
neighbouring rings, smooth taper, one compiled pass). Why not warpPolar: resampling the AoP image
onto a polar grid interpolates an axial angle field and breaks the exact symmetry at the level we
test (0.01 deg).

The heading is ``psi = -theta`` (mod 180 deg: axial; the mirror symmetry says nothing about which
end holds the sun). When the sun lies on the camera's horizon (camera-frame elevation 0: a low sun
and a camera tilted away from it) the pattern is also antisymmetric about the perpendicular axis,
and F ties. The tie is broken by the fact the SM-ASM method uses: along the meridian the E-vector
is perpendicular to it (|AOPLM| = 90 deg), along the perpendicular axis it is parallel (AOPLM = 0);
among the near-best peaks of F the best one with ``S(theta) = -Re sum_even a_k e^{ik theta} > 0``
is kept. ``extras['second_axis_score']`` reports how close the best other axis comes (1 = tie).
Uncertainty: implicit-function sensitivity ``d theta / d a_i = -(d F'/d a_i) / F''``, times the
residual against the level Rayleigh pattern, cluster-robust over blocks.

The plain correlation (weights ``DoP_i^2``) is the start; the heading is the axis computed on
mirror-pair weights ``DoP(p) DoP(p')`` about itself (a fixed point; in that iteration the peak of F
is followed locally from the trial axis, so the map stays continuous): broken clouds make the DoP
asymmetric about the meridian while the AoP stays symmetric. An incomplete disc (occluders, invalid
pixels) gets zero pair weights where a pixel or its image is unusable, or the status is
``insufficient_coverage``: see :mod:`._mirror`.
"""

from __future__ import annotations

from functools import lru_cache
import math

from numba import njit
import numpy as np

from ._axis_solve import AxisFit
from ._disc import disc_cells, DiscRing
from ._disc_estimator import DISC_KNOBS, DiscEstimator
from ._kernels import N_STATS
from ._knobs import Knob
from ._symmetry_kernels import ring_fit, ring_gather, ring_pass1, ring_terms2
from .base import HeadingResult, Status

__all__ = ['SymmetryEstimator', 'MIN_MIRROR_SYMMETRY']

#: With part of the disc unusable: F / sum |a_k|^2 an axis found on mirror pairs needs (1 = exactly
#: symmetric).
MIN_MIRROR_SYMMETRY = 0.95


@njit(cache=True, nogil=True)
def _F_derivs(b, K, theta):  # pragma: no cover - compiled
    """F, F', F'' at theta for b[k + K] = sum_rings a_k^2 (k = -K..K, k = 0 excluded)."""
    F = F1 = F2 = 0.0
    for k in range(-K, K + 1):
        if k == 0:
            continue
        t = b[k + K] * complex(math.cos(2.0 * k * theta), math.sin(2.0 * k * theta))
        F += t.real
        F1 -= 2.0 * k * t.imag  # Re(2ik t)
        F2 -= 4.0 * k * k * t.real
    return F, F1, F2


@njit(cache=True, nogil=True)
def _newton(b, K, theta, step):  # pragma: no cover - compiled
    """Newton on F'(theta) = 0 from a grid peak, steps limited to the grid spacing."""
    for _ in range(30):
        F, F1, F2 = _F_derivs(b, K, theta)
        if not F2 < 0.0:
            break
        dt = max(-step, min(step, -F1 / F2))
        theta += dt
        if abs(dt) < 1e-14:
            break
    return theta


@njit(cache=True, nogil=True)
def _climb(Fg, i):  # pragma: no cover - compiled
    """Return the local maximum of the periodic grid function Fg reached uphill from index i."""
    n = Fg.size
    for _ in range(n):
        up, down = Fg[(i + 1) % n], Fg[(i - 1) % n]
        if up > Fg[i] and up >= down:
            i = (i + 1) % n
        elif down > Fg[i]:
            i = (i - 1) % n
        else:
            break
    return i


@lru_cache(maxsize=16)
def _tables(K: int, steps: int):
    """
    Return the exp(ik theta) tables on the coarse grid of axes.

    exp(2ik theta) (odd and even k != 0) and exp(ik theta) (even k) on the coarse grid of axes.
    """
    ks = np.arange(-K, K + 1)
    grid = np.arange(steps) * (math.pi / steps)
    out = (
        grid,
        np.exp(2j * np.outer(grid, ks[ks != 0])),
        np.exp(1j * np.outer(grid, ks[ks % 2 == 0])),
    )
    for x in out:
        x.setflags(write=False)
    return out


@njit(cache=True, nogil=True)
def _axis_solve(a, K, grid, e2, e1, near_i):  # pragma: no cover - compiled
    """
    Search the axis after building the tables.

    :func:`_axis_search` after the tables: (theta, F, F2, second-axis score, energy sum |a_k|^2 (k
    != 0)).

    ``b_k = sum_rings a_k^2``; ``Fg[t] = Re sum_{k != 0} e2[t, k] b_k`` on the grid; with ``near_i
    < 0`` the start is the best near-best peak of Fg (at least half the maximum) with ``S > 0``
    (else the best peak), ``S[t] = -Re sum_{even k} e1[t, k] sum_rings a_k``; else the peak reached
    by climbing from ``near_i``. Then Newton on F' = 0 and the best grid value more than 10 deg
    from the axis over F.
    """
    n_k = 2 * K + 1
    n_r = a.shape[1]
    b = np.zeros(n_k, np.complex128)
    energy = 0.0
    for k in range(n_k):
        acc = 0j
        for r in range(n_r):
            v = a[k, r]
            acc += v * v
            if k != K:
                energy += v.real * v.real + v.imag * v.imag
        b[k] = acc
    steps = grid.size
    Fg = np.empty(steps)
    for t in range(steps):
        acc = 0.0
        q = 0
        for k in range(n_k):
            if k == K:
                continue
            acc += (e2[t, q] * b[k]).real
            q += 1
        Fg[t] = acc
    if near_i >= 0:
        i = _climb(Fg, near_i)
    else:
        asum = np.zeros(n_k, np.complex128)
        for k in range(n_k):
            if (k - K) % 2 == 0:
                acc = 0j
                for r in range(n_r):
                    acc += a[k, r]
                asum[k] = acc
        fmax = Fg.max()
        best_good = -1
        best_peak = -1
        for t in range(steps):
            f = Fg[t]
            if not (f >= Fg[(t - 1) % steps] and f >= Fg[(t + 1) % steps] and f >= 0.5 * fmax):
                continue
            if best_peak < 0 or f > Fg[best_peak]:
                best_peak = t
            S = 0.0
            q = 0
            for k in range(n_k):
                if (k - K) % 2 == 0:
                    S -= (e1[t, q] * asum[k]).real
                    q += 1
            if S > 0.0 and (best_good < 0 or f > Fg[best_good]):
                best_good = t
        i = best_good if best_good >= 0 else best_peak
    theta = _newton(b, K, grid[i], math.pi / steps)
    F, F1, F2 = _F_derivs(b, K, theta)
    far_max = -np.inf
    far = False
    lim = math.radians(10.0)
    for t in range(steps):
        x = grid[t] - theta + 0.5 * math.pi
        if (
            abs((x - math.pi * math.floor(x / math.pi)) - 0.5 * math.pi) > lim
        ):  # axial distance (Python %)
            far = True
            far_max = max(far_max, Fg[t])
    second = far_max / F if far and F > 0 else 0.0
    return theta, F, F2, second, energy


def _axis_search(a, K, steps, near=None):
    """
    Return the axis from the ring coefficients a (2K+1, rings).

    Returns (theta, F, F2, second-axis score, energy).

    Coarse search of F on ``steps`` points over [0, pi), then Newton on F' = 0. ``near`` None: the
    best near-best peak on the meridian side: the meridian carries |AOPLM| = 90 deg along itself (E
    perpendicular to it), the perpendicular axis AOPLM = 0 -- and when the sun lies on the camera's
    horizon the pattern is antisymmetric about both. S(theta) = -Re c averaged along the axis (even
    harmonics: both ends) is > 0 on the meridian: among the near-best peaks of F, keep the best one
    with S > 0. Else the peak reached by climbing F on the grid from ``near``. One compiled call
    (:func:`_axis_solve`).
    """
    grid, e2, e1 = _tables(K, steps)
    near_i = -1 if near is None else int(round((near % math.pi) / (math.pi / steps))) % steps
    return _axis_solve(np.ascontiguousarray(a), K, grid, e2, e1, near_i)


class SymmetryEstimator(DiscEstimator):
    """
    Estimate the heading by the symmetry approach: the axis of antisymmetry of the AOPLM map.

    A polar correlation of the map with its mirror image from ring Fourier coefficients, coarse
    grid then Newton (see the module docstring); level-camera assumption, axial result
    (:meth:`DiscEstimator.estimate`).

    Parameters
    ----------
    **knobs
        Validated against :meth:`knob_specs`: ``harmonics`` (K), ``rings``, ``inner_fraction`` (of
        the disc radius), ``search_steps`` (over 180 deg), the disc knobs and the common knobs
        (``stride``, ``region`` [sensor pixels], ``min_dop``, ...).

    Raises
    ------
    EstimatorError
        A knob is unknown or out of range.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 29-30 (AOPLM) and Sec. 3
       (the symmetry approach, after its refs [30-32]).
    .. [2] Z. Huijie, X. Wujian, Z. Ying et al., "Polarization patterns under different sky
       conditions and a navigation method based on the symmetry of the AOP map of skylight", Optics
       Express 26(22), 2018.

    """

    name = 'symmetry'
    label = 'Symmetry'
    style = ('tab:green', '-.')
    paper_method = True
    sweep_knobs = {
        'stride': 48,
        'search_steps': 90,
    }  # 2 deg coarse grid; Newton refines to the same optimum
    relative_cost = 11.5

    OWN_KNOBS = dict(
        DISC_KNOBS,
        harmonics=Knob(2, 'int', 1, 32, doc='circular harmonics K used in the correlation'),
        rings=Knob(24, 'int', 2, 4096, doc='radial rings of the polar decomposition'),
        inner_fraction=Knob(
            0.05,
            'float',
            0.0,
            0.9,
            doc="ignore the disc's centre (AOPLM is singular at the zenith pixel)",
        ),
        search_steps=Knob(
            720, 'int', 8, 100000, doc='grid points of the coarse axis search over 180 deg'
        ),
    )

    def _root_ok(self, fit: AxisFit, lenient: bool = False) -> bool:
        """
        Tell whether a self-consistent axis is the true one (antisymmetry ratio).

        On the pairs about the true axis the map is exactly antisymmetric (F / sum |a_k|^2 = 1 up
        to noise); a self-consistent axis of a thin wedge of pairs elsewhere is not (0.1-0.8 in our
        scenes).
        """
        return fit.quality >= (0.8 if lenient else MIN_MIRROR_SYMMETRY) and fit.state['F2'] < 0.0

    def _root_why(self, fit: AxisFit) -> str:
        return f'best F / sum |a_k|^2 = {fit.quality:.3f} < {MIN_MIRROR_SYMMETRY:g}'

    def _rho_lo(self, rho_max: float) -> float:
        return max(rho_max * self.knobs['inner_fraction'], 1e-9)

    def _axis(
        self, a, n, near, base: AxisFit | None, cnt=None, stats=None, n_pair=0, coverage=1.0
    ):
        K = self.knobs['harmonics']
        theta, F, F2, second, energy = _axis_search(a, K, self.knobs['search_steps'], near)
        if not energy > 0.0:
            return HeadingResult.failed(
                self.name, Status.DEGENERATE, 'no circular structure in the AOPLM map', pixels=n
            )
        state = {'a': a, 'F2': F2, 'extras': {'second_axis_score': second}}
        quality = max(0.0, F / energy)
        if base is None:
            return self._plain_fit(cnt, stats, theta, quality, state)
        return AxisFit(
            theta, base.n, n_pair, base.nonfinite, base.holes, coverage, base.stats, quality, state
        )

    def _ring(self, rho_lo, rho_max):
        k = self.knobs
        return DiscRing(k['min_dop'], rho_lo, rho_max, k['taper_fraction'])

    def _fit(self, data, rho_lo, rho_max):
        k = self.knobs
        inten = data[6]
        has_i = inten is not None
        K, NR = k['harmonics'], k['rings']
        a = np.zeros((2 * K + 1, NR), dtype=np.complex128)
        cnt = np.zeros(4, np.int64)
        stats = np.zeros(N_STATS)
        ring_pass1(
            data[:6],
            inten if has_i else np.zeros(1, np.float32),
            has_i,
            self._ring(rho_lo, rho_max),
            NR,
            K,
            a,
            cnt,
            stats,
        )
        few = self._too_few(int(cnt[0]))
        if few is not None:
            return few
        return self._axis(a, int(cnt[0]), None, None, cnt, stats)

    def _gather(self, data, rho_lo, rho_max, mm, own_dop2=False):
        k = self.knobs
        N = data[0].size
        K = k['harmonics']
        g = {
            'uv': np.empty((2, N)),
            'tp': np.empty(N),
            'v': np.empty((2 * K + 1, N), np.complex128),
            'ring': np.empty(N),
        }
        ring = self._ring(rho_lo, rho_max)
        mirror = (mm.grid, mm.weight, mm.params)
        g['n'] = ring_gather(
            data[:6], ring, k['rings'], K, mirror, own_dop2, g['uv'], g['tp'], g['v'], g['ring']
        )
        g['disc'] = disc_cells(mm.camera, *mm.lattice, rho_lo, rho_max, k['taper_fraction'])
        return g

    def _mirror_fit(self, g, mirror, near, plain, step=1, start=0):
        k = self.knobs
        K, NR = k['harmonics'], k['rings']
        a = np.zeros((2 * K + 1, NR), dtype=np.complex128)
        out = np.zeros(2)
        ring_fit(
            g['uv'],
            g['tp'],
            g['v'],
            g['ring'],
            g['n'],
            start,
            step,
            NR,
            K,
            mirror[0],
            mirror[1],
            mirror[2],
            a,
            out,
        )
        f = self._axis(
            a,
            plain.n,
            near,
            plain,
            n_pair=int(out[1]),
            coverage=out[0] * step / g['disc'] if g['disc'] > 0.0 else 0.0,
        )
        return None if isinstance(f, HeadingResult) else f

    def _influence_terms(self, data, rho_lo, rho_max, mirror, fit, s1, s2):
        k = self.knobs
        N = data[0].size
        K, NR = k['harmonics'], k['rings']
        t0 = np.zeros(N)
        t1 = np.zeros(N)
        rss = np.zeros(2)
        F2 = fit.state['F2']
        if F2 < 0.0:
            rot = np.exp(2j * np.arange(-K, K + 1) * fit.theta)
            ring_terms2(
                data[:6],
                self._ring(rho_lo, rho_max),
                NR,
                K,
                tuple(mirror),
                fit.state['a'],
                rot,
                F2,
                (s1, s2),
                t0,
                t1,
                rss,
            )
        return t0, t1, rss
