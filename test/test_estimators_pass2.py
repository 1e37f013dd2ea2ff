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
The pass-2 (uncertainty) kernels of SM-ASM and Symmetry against independent computations.

Each pixel is its own block, so block_sum[j, i] = (d theta / d a_i) * residual_j(i). The
sensitivity is checked by central finite differences of the axis each method fits (SM-ASM: theta =
arg(sum W z^2) / 2 in numpy; Symmetry: F'(theta) from the compiled pass 1's ring coefficients), the
residual against numpy's Rayleigh pattern (_common.rayleigh_aop_rad), with invalid, non-finite and
out-of-disc pixels planted.
"""

import math

import numpy as np
from polarization_compass.estimators._common import axial_residual_rad, rayleigh_aop_rad
from polarization_compass.estimators._disc import DiscRing, taper
from polarization_compass.estimators._disc_sigma import _blocks
from polarization_compass.estimators._mirror import NO_MIRROR
from polarization_compass.estimators._sm_asm_kernels import band_terms2
from polarization_compass.estimators._symmetry_kernels import ring_pass1, ring_terms2
import pytest

N = 160
RHO_MAX = 0.6
TAPER = 0.2
MIN_DOP = 0.05
SUNS = (np.array([0.3, 0.5, 0.81]), np.array([-0.3, -0.5, 0.81]))


def _pixels(seed: int):
    """
    Draw float32 pixels, some outside the disc, with NaN/inf/invalid planted.

    float32 AoP, DoP, validity and unit rays (3, N), some outside the disc; NaN/inf/invalid
    planted.
    """
    rng = np.random.default_rng(seed)
    aop = rng.uniform(-math.pi / 2, math.pi / 2, N).astype(np.float32)
    dop = rng.uniform(0.0, 1.0, N).astype(np.float32)
    rho = RHO_MAX * np.sqrt(rng.uniform(0.0, 1.15, N))
    phi = rng.uniform(-math.pi, math.pi, N)
    rays = np.stack([rho * np.sin(phi), rho * np.cos(phi), np.sqrt(1.0 - rho**2)]).astype(
        np.float32
    )
    valid = rng.uniform(size=N) > 0.1
    aop[3] = np.nan
    dop[5] = np.inf
    rays[0, 7] = np.nan
    return aop, dop, valid, rays


def _usable(aop, dop, valid, rays, rho_lo):
    rho = np.hypot(rays[0].astype(float), rays[1].astype(float))
    with np.errstate(invalid='ignore'):
        return (
            valid
            & np.isfinite(aop)
            & np.isfinite(dop)
            & np.all(np.isfinite(rays), axis=0)
            & (dop >= MIN_DOP)
            & (rho >= rho_lo)
            & (rho <= RHO_MAX)
            & (rho > 0)
        )


def _own_blocks():
    idx = np.arange(N, dtype=np.int64)
    return idx, idx + 1, idx


def _pass2(terms2, args, segs, n_blocks):
    """Run pass 2 as the estimators do: the per-pixel terms, then the block sums over ``segs``."""
    n = args[0][0].size  # args[0]: the view (aop, dop, valid, rays, xs, ys)
    t0, t1, rss = np.empty(n), np.empty(n), np.zeros(2)
    terms2(*args, t0, t1, rss)
    return _blocks(t0, t1, (*segs, n_blocks)), rss


def _residuals(aop, rays, use):
    out = np.zeros((2, N))
    for j, s in enumerate(SUNS):
        out[j, use] = axial_residual_rad(
            aop[use].astype(float), rayleigh_aop_rad(s, rays[:, use].astype(float))
        )
    return out


def _fd(f, aop, use, h=1e-4):
    """
    Return central differences of f(aop) in each usable pixel's AoP.

    Each difference is divided by the float32 step actually taken.
    """
    d = np.zeros(N)
    for i in np.nonzero(use)[0]:
        up, dn = aop.copy(), aop.copy()
        up[i] = np.float32(aop[i] + h)
        dn[i] = np.float32(aop[i] - h)
        d[i] = (f(up) - f(dn)) / (float(up[i]) - float(dn[i]))
    return d


@pytest.mark.parametrize('seed', [0, 1])
def test_sm_asm_pass2_is_the_derivative_of_the_sm_asm_axis(seed):
    (
        aop,
        dop,
        valid,
        rays,
    ) = _pixels(seed)
    use = _usable(aop, dop, valid, rays, 0.0)
    r = rays.astype(float)
    rho = np.hypot(r[0], r[1])
    inv4tol2 = 1.0 / (4.0 * math.radians(10.0) ** 2)

    def Z(a):
        a = a.astype(float)[use]
        c = np.exp(2j * a) * ((r[1, use] - 1j * r[0, use]) / rho[use]) ** 2  # exp(2i AOPLM)
        w = (
            np.exp((-c.real - 1.0) * inv4tol2)
            * dop[use].astype(float) ** 2
            * taper(rho[use], RHO_MAX, TAPER)
        )
        return np.sum(w * (r[1, use] + 1j * r[0, use]) ** 2)

    def theta(a):
        return 0.5 * np.angle(Z(a))

    z0 = Z(aop)
    block_sum, rss = _pass2(
        band_terms2,
        (
            (aop, dop, valid, rays, r[0].copy(), r[1].copy()),
            DiscRing(MIN_DOP, 0.0, RHO_MAX, TAPER),
            inv4tol2,
            NO_MIRROR,
            (z0.real, z0.imag),
            SUNS,
        ),
        _own_blocks(),
        N,
    )
    res = _residuals(aop, rays, use)
    want = _fd(theta, aop, use) * res
    assert use.sum() > 100 and np.all(block_sum[:, ~use] == 0.0)
    np.testing.assert_allclose(block_sum, want, rtol=1e-5, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(rss, (res**2).sum(axis=1), rtol=1e-12)


@pytest.mark.parametrize('K', [1, 2, 3])
def test_symmetry_pass2_is_the_derivative_of_the_symmetry_axis(K):
    aop, dop, valid, rays = _pixels(10 + K)
    rho_lo = 0.05 * RHO_MAX
    use = _usable(aop, dop, valid, rays, rho_lo)
    n_rings = 7
    theta = 0.4
    ks = np.arange(-K, K + 1)

    def coeffs(a):
        out = np.zeros((2 * K + 1, n_rings), np.complex128)
        ring_pass1(
            (a, dop, valid, rays, np.zeros(N), np.zeros(N)),
            np.zeros(1, np.float32),
            False,
            DiscRing(MIN_DOP, rho_lo, RHO_MAX, TAPER),
            n_rings,
            K,
            out,
            np.zeros(4, np.int64),
            np.zeros(18),
        )
        return out

    def dF(a, order):
        """
        Return the derivative of the given order of F at theta.

        F^(order)(theta), F = Re sum_{k != 0} b_k exp(2ik theta), b_k = sum over rings of a_k^2.
        """
        b = (coeffs(a) ** 2).sum(axis=1)
        t = b * np.exp(2j * ks * theta) * (2j * ks) ** order
        return t[ks != 0].real.sum()

    F2 = dF(aop, 2)
    block_sum, rss = _pass2(
        ring_terms2,
        (
            (aop, dop, valid, rays, np.zeros(N), np.zeros(N)),
            DiscRing(MIN_DOP, rho_lo, RHO_MAX, TAPER),
            n_rings,
            K,
            NO_MIRROR,
            coeffs(aop),
            np.exp(2j * ks * theta),
            F2,
            SUNS,
        ),
        _own_blocks(),
        N,
    )
    res = _residuals(aop, rays, use)
    want = -_fd(lambda a: dF(a, 1), aop, use) / F2 * res
    assert use.sum() > 100 and np.all(block_sum[:, ~use] == 0.0)
    np.testing.assert_allclose(block_sum, want, rtol=1e-5, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(rss, (res**2).sum(axis=1), rtol=1e-12)


def test_pass2_chunks_and_blocks_add_up():
    """
    Pass 2 chunks and blocks add up to the per-pixel terms.

    More pixels than one chunk of the Symmetry pass (512), in blocks of several pixels: the block
    sums equal the per-pixel terms summed by block (each pixel its own block).
    """
    from polarization_compass.estimators import _symmetry_kernels

    rng = np.random.default_rng(4)
    n = 3 * _symmetry_kernels._RING_CHUNK + 77
    aop = rng.uniform(-1.5, 1.5, n).astype(np.float32)
    dop = rng.uniform(0.0, 1.0, n).astype(np.float32)
    rho = 0.6 * np.sqrt(rng.uniform(0.0, 1.0, n))
    phi = rng.uniform(-math.pi, math.pi, n)
    rays = np.stack([rho * np.sin(phi), rho * np.cos(phi), np.sqrt(1.0 - rho**2)]).astype(
        np.float32
    )
    valid = np.ones(n, bool)
    a = rng.normal(size=(5, 6)) + 1j * rng.normal(size=(5, 6))
    blocks = rng.integers(0, 40, n // 10 + 1)
    starts = np.arange(0, n, 10, dtype=np.int64)
    ends = np.minimum(starts + 10, n)

    def run(seg):
        return _pass2(
            ring_terms2,
            (
                (aop, dop, valid, rays, np.zeros(n), np.zeros(n)),
                DiscRing(0.05, 0.03, 0.6, 0.2),
                6,
                2,
                NO_MIRROR,
                a,
                np.exp(2j * np.arange(-2, 3) * 0.3),
                -5.0,
                SUNS,
            ),
            seg,
            n,
        )

    per_px, rss1 = run(
        (np.arange(n, dtype=np.int64), np.arange(1, n + 1, dtype=np.int64), np.arange(n))
    )
    by_block, rss2 = run((starts, ends, blocks))
    want = np.zeros((2, n))
    np.add.at(want, (slice(None), np.repeat(blocks, ends - starts)), per_px)
    np.testing.assert_allclose(by_block, want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(rss1, rss2, rtol=1e-12)
