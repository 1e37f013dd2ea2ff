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
The compiled passes of Symmetry (:mod:`.symmetry`).

The ring coefficients of the plain fit (pass 1), the gather and per-axis fit on mirror pairs, and
the influence pass (pass 2), in chunks of ``_RING_CHUNK`` pixels. Shared per-pixel steps:
:mod:`._disc`; the gather's shared part: :mod:`._pair_gather`; pair weights: :mod:`._mirror`. The
per-pixel loops ``_ring1_terms`` and ``_ring_terms`` vectorise (``test/test_vecmath.py`` checks
their LLVM IR).
"""

from __future__ import annotations

from numba import njit
import numpy as np

from ._disc import _brightness_pass, _exp2i_aoplm, _lane_pixel, _level_resid, _taper1
from ._mirror import _bilinear0_pair, _mirror_consts, _mirror_pos, _pair_weights
from ._pair_gather import GATHER_CHUNK, gather_chunk, gather_scratch, kept_pixel
from ..fastmath import atan2, sincos
from ..fastmath import FM as _FMV

__all__ = ['ring_pass1', 'ring_gather', 'ring_fit', 'ring_terms2']

#: Pixels per chunk of the vectorised Symmetry passes (their scratch arrays stay in L1/L2).
_RING_CHUNK = 512


@njit(inline='always', cache=True, error_model='numpy')
def _ring_t(rho, rho_lo, span, n_rings):  # pragma: no cover - compiled
    """Ring position of radius rho: t in [0, n_rings - 1], rings at the integers (branch-free)."""
    return min(max((rho - rho_lo) / span, 0.0), 1.0) * (n_rings - 1)


@njit(inline='always', cache=True)
def _ring_split(t, n_rings):  # pragma: no cover - compiled
    """
    Split a ring position t >= 0 into ring index j and fraction f.

    Ring index j and the linear split f towards ring j + 1 of a ring position t >= 0 (j + f = t).
    """
    j = min(np.int64(t), n_rings - 1)
    return j, t - j


@njit(inline='always', cache=True)
def _ring_add(a_out, K, n_rings, j, f, c, e):  # pragma: no cover - compiled
    """
    Add a pixel's harmonics to the ring coefficients, split linearly between two rings.

    a_out[k + K, ring] += hat * c * e^k (k = -K..K), split linearly between rings j and j + 1.
    """
    g0 = 1.0 - f
    a_out[K, j] += g0 * c
    if j + 1 < n_rings:
        a_out[K, j + 1] += f * c
    ep = c
    em = c
    ec = e.conjugate()
    for kk in range(1, K + 1):
        ep = ep * e
        em = em * ec
        a_out[K + kk, j] += g0 * ep
        a_out[K - kk, j] += g0 * em
        if j + 1 < n_rings:
            a_out[K + kk, j + 1] += f * ep
            a_out[K - kk, j + 1] += f * em


@njit(cache=True, nogil=True, fastmath=_FMV, error_model='numpy')
def _ring1_terms(
    aop,
    dop,
    valid,
    rays,
    o,
    n,
    min_dop,
    rho_lo,
    rho_max,
    taper_frac,
    n_rings,
    cr,
    ci,
    er,
    ei,
    tr,
    cnt,
):  # pragma: no cover - compiled
    """
    Compute the per-pixel terms of :func:`ring_pass1` (vectorised).

    Pixels o..o+n of :func:`ring_pass1` (vectorised): c = w exp(2i AOPLM) (0 if unusable), e =
    exp(-i xi), ring position tr; counts into cnt.
    """
    span = max(rho_max - rho_lo, 1e-12)
    n_ok = n_v = n_bad = n_hole = 0
    for q in range(n):
        ok, v, bad, hole, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(
            aop, dop, valid, rays, o + q, min_dop, rho_lo, rho_max
        )
        n_ok += np.int64(ok)
        n_v += np.int64(v)
        n_bad += np.int64(bad)
        n_hole += np.int64(hole)
        c_r, c_i = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        w = p * p * _taper1(rho, rho_max, taper_frac)
        cr[q] = c_r * w
        ci[q] = c_i * w
        er[q] = ry / rho
        ei[q] = -rx / rho
        tr[q] = _ring_t(rho, rho_lo, span, n_rings)
    cnt[0] += n_ok
    cnt[1] += n_v
    cnt[2] += n_bad
    cnt[3] += n_hole


@njit(cache=True, nogil=True, error_model='numpy')
def ring_pass1(
    view, inten, has_i, ring, n_rings, K, a_out, cnt, stats
):  # pragma: no cover - compiled
    """
    Run the Symmetry first pass: the ring coefficients of the AoP harmonics.

    Symmetry: a_out[k + K, ring] += hat * w * c * exp(-i k phi), k = -K..K, c = exp(2i AOPLM), w =
    DoP^2 taper, linear split between neighbouring rings; cnt and stats as
    :func:`._sm_asm_kernels.band_pass1`. In chunks: the per-pixel terms (vectorised), then the
    scatter into the rings (scalar). ``view``: (aop, dop, valid, rays, xs, ys); ``ring``:
    :class:`._disc.DiscRing`.
    """
    aop, dop, valid, rays, _, _ = view
    min_dop, rho_lo, rho_max, taper_frac = ring
    CH = _RING_CHUNK
    cr = np.empty(CH)
    ci = np.empty(CH)
    er = np.empty(CH)
    ei = np.empty(CH)
    tr = np.empty(CH)
    for o in range(0, aop.size, CH):
        n = min(CH, aop.size - o)
        _ring1_terms(
            aop,
            dop,
            valid,
            rays,
            o,
            n,
            min_dop,
            rho_lo,
            rho_max,
            taper_frac,
            n_rings,
            cr,
            ci,
            er,
            ei,
            tr,
            cnt,
        )
        for q in range(n):
            if cr[q] == 0.0 and ci[q] == 0.0:
                continue  # unusable (or zero weight: adds nothing)
            j, f = _ring_split(tr[q], n_rings)
            _ring_add(a_out, K, n_rings, j, f, complex(cr[q], ci[q]), complex(er[q], ei[q]))
    if has_i:
        _brightness_pass(aop, dop, valid, rays, inten, min_dop, rho_lo, rho_max, stats)


@njit(cache=True, nogil=True)
def ring_gather(
    view, ring, n_rings, K, mirror, own_dop2, g_uv, g_tp, g_v, g_ring
):  # pragma: no cover - compiled
    """
    Gather the disc's pixels for Symmetry with mirror pairs (step 1).

    Symmetry with mirror pairs, step 1 (:mod:`._pair_gather`): g_uv = offset from the principal
    point (mm), g_tp = taper S(p), g_v[k + K] = w S(p) c exp(-i k phi) for k = -K..K with w =
    taper Q(p) / S(p) (the pair weight's own factor, the mirror image's Q(p') in :func:`ring_fit`;
    0 below min_dop), g_ring = ring position (:func:`_ring_t`); with ``own_dop2`` the own factor is
    DoP(p)^2 S(p) instead (the occlusion-only pair weights, fitted with Q = S). Returns the count.
    """
    span = max(ring.rho_max - ring.rho_lo, 1e-12)
    scratch = gather_scratch()
    n = 0
    for o in range(0, view[0].size, GATHER_CHUNK):
        kept = gather_chunk(view, ring, mirror, own_dop2, o, scratch, g_uv, g_tp, n)
        for k in range(kept):
            usable, tp, q, rx, ry, rho, c2a, s2a = kept_pixel(scratch, k)
            e = complex(ry / rho, -rx / rho)
            c = complex(0.0, 0.0)
            if usable:
                c = complex(c2a, s2a) * e * e * (tp * q)
            g_v[K, n] = c
            ep = c
            em = c
            ec = e.conjugate()
            for kk in range(1, K + 1):
                ep = ep * e
                em = em * ec
                g_v[K + kk, n] = ep
                g_v[K - kk, n] = em
            g_ring[n] = _ring_t(rho, ring.rho_lo, span, n_rings)
            n += 1
    return n


@njit(inline='always', cache=True)
def _k2_load(a, j):  # pragma: no cover - compiled
    """Return the 2K+1 = 5 coefficients of ring j as (re, im) scalars."""
    return (
        a[0, j].real,
        a[0, j].imag,
        a[1, j].real,
        a[1, j].imag,
        a[2, j].real,
        a[2, j].imag,
        a[3, j].real,
        a[3, j].imag,
        a[4, j].real,
        a[4, j].imag,
    )


@njit(cache=True, nogil=True)
def _ring_fit_k2(
    g_uv, g_tp, g_v, g_ring, n, start, step, n_rings, mg, mq, mp, a_out, out
):  # pragma: no cover - compiled
    """
    Run :func:`ring_fit` for K = 2 with the two rings a pixel adds to held in registers.

    Consecutive pixels mostly fall between the same two rings: their coefficients stay in scalars
    and go back to ``a_out`` when the ring changes, so each coefficient receives the same additions
    in the same order as :func:`ring_fit`'s scatter (the same values), without a load and store
    per addition. ``w * v`` for real w and complex v is written out as its two products (complex
    multiplication by w + 0i gives exactly these).
    """
    st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
    cov = 0.0
    n_pair = 0
    cur = -1
    has1 = False
    a0r = a0i = a1r = a1i = a2r = a2i = a3r = a3i = a4r = a4i = 0.0
    b0r = b0i = b1r = b1i = b2r = b2i = b3r = b3i = b4r = b4i = 0.0
    for q in range(start, n, step):
        r, c = _mirror_pos(st, ct, kc, kr, c0, r0, g_uv[0, q], g_uv[1, q])
        m, w = _bilinear0_pair(mg, mq, r, c)
        if not m > 0.0:
            continue
        cov += g_tp[q] * m
        if (g_v[2, q].real == 0.0 and g_v[2, q].imag == 0.0) or not w > 0.0:
            continue
        n_pair += 1
        j, f = _ring_split(g_ring[q], n_rings)
        if j != cur:
            if cur >= 0:
                a_out[0, cur] = complex(a0r, a0i)
                a_out[1, cur] = complex(a1r, a1i)
                a_out[2, cur] = complex(a2r, a2i)
                a_out[3, cur] = complex(a3r, a3i)
                a_out[4, cur] = complex(a4r, a4i)
                if has1:
                    a_out[0, cur + 1] = complex(b0r, b0i)
                    a_out[1, cur + 1] = complex(b1r, b1i)
                    a_out[2, cur + 1] = complex(b2r, b2i)
                    a_out[3, cur + 1] = complex(b3r, b3i)
                    a_out[4, cur + 1] = complex(b4r, b4i)
            cur = j
            has1 = j + 1 < n_rings
            a0r, a0i, a1r, a1i, a2r, a2i, a3r, a3i, a4r, a4i = _k2_load(a_out, j)
            if has1:
                b0r, b0i, b1r, b1i, b2r, b2i, b3r, b3i, b4r, b4i = _k2_load(a_out, j + 1)
        w0 = (1.0 - f) * w
        v0 = g_v[0, q]
        v1 = g_v[1, q]
        v2 = g_v[2, q]
        v3 = g_v[3, q]
        v4 = g_v[4, q]
        a0r += w0 * v0.real
        a0i += w0 * v0.imag
        a1r += w0 * v1.real
        a1i += w0 * v1.imag
        a2r += w0 * v2.real
        a2i += w0 * v2.imag
        a3r += w0 * v3.real
        a3i += w0 * v3.imag
        a4r += w0 * v4.real
        a4i += w0 * v4.imag
        if has1:
            w1 = f * w
            b0r += w1 * v0.real
            b0i += w1 * v0.imag
            b1r += w1 * v1.real
            b1i += w1 * v1.imag
            b2r += w1 * v2.real
            b2i += w1 * v2.imag
            b3r += w1 * v3.real
            b3i += w1 * v3.imag
            b4r += w1 * v4.real
            b4i += w1 * v4.imag
    if cur >= 0:
        a_out[0, cur] = complex(a0r, a0i)
        a_out[1, cur] = complex(a1r, a1i)
        a_out[2, cur] = complex(a2r, a2i)
        a_out[3, cur] = complex(a3r, a3i)
        a_out[4, cur] = complex(a4r, a4i)
        if has1:
            a_out[0, cur + 1] = complex(b0r, b0i)
            a_out[1, cur + 1] = complex(b1r, b1i)
            a_out[2, cur + 1] = complex(b2r, b2i)
            a_out[3, cur + 1] = complex(b3r, b3i)
            a_out[4, cur + 1] = complex(b4r, b4i)
    out[0] = cov
    out[1] = n_pair


@njit(cache=True, nogil=True)
def ring_fit(
    g_uv, g_tp, g_v, g_ring, n, start, step, n_rings, K, mg, mq, mp, a_out, out
):  # pragma: no cover - compiled
    """
    Fit one trial axis for Symmetry with mirror pairs (step 2).

    Symmetry with mirror pairs, step 2 (per trial axis): the ring coefficients a_out of the
    gathered pixels weighted by Q(p') (pair weights Q(p) Q(p') symmetric about the axis); out
    = (coverage numerator sum taper S(p) S(p'), usable pixels with a pair weight > 0); every
    ``step``-th gathered pixel from ``start``.
    """
    if K == 2:  # the default: the same sums with the coefficients in registers
        _ring_fit_k2(g_uv, g_tp, g_v, g_ring, n, start, step, n_rings, mg, mq, mp, a_out, out)
        return
    st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
    cov = 0.0
    n_pair = 0
    for q in range(start, n, step):
        # S(p') and Q(p') at the mirror image (:func:`._mirror._mirror_pos`), one position
        r, c = _mirror_pos(st, ct, kc, kr, c0, r0, g_uv[0, q], g_uv[1, q])
        m, w = _bilinear0_pair(mg, mq, r, c)
        if not m > 0.0:
            continue
        cov += g_tp[q] * m
        if (g_v[K, q].real == 0.0 and g_v[K, q].imag == 0.0) or not w > 0.0:
            continue
        n_pair += 1
        j, f = _ring_split(g_ring[q], n_rings)
        w0 = (1.0 - f) * w
        w1 = f * w
        for k in range(2 * K + 1):
            v = g_v[k, q]
            a_out[k, j] += w0 * v
            if j + 1 < n_rings:
                a_out[k, j + 1] += w1 * v
    out[0] = cov
    out[1] = n_pair


@njit(cache=True, nogil=True, fastmath=_FMV, error_model='numpy')
def _ring_terms(
    aop,
    dop,
    valid,
    rays,
    o,
    n,
    min_dop,
    rho_lo,
    rho_max,
    taper_frac,
    n_rings,
    s1,
    s2,
    wm,
    paired,
    cr,
    ci,
    xi,
    tr,
    r1,
    r2,
    rss,
):  # pragma: no cover - compiled
    """
    Compute the per-pixel Symmetry influence terms and residuals (vectorised).

    Pixels o..o+n (vectorised): c = w exp(2i AOPLM) (w = DoP^2 taper, or with ``paired`` taper
    Q(p) Q(p'); 0 if unusable) into cr, ci; xi = atan2(r_x, r_y); tr = ring position in [0,
    n_rings - 1]; the residuals r_j (0 if unusable); rss[j] += r_j^2.
    """
    span = max(rho_max - rho_lo, 1e-12)
    a0, a1, a2 = s1[0], s1[1], s1[2]
    b0, b1, b2 = s2[0], s2[1], s2[2]
    q0 = q1 = 0.0
    for q in range(n):
        i = o + q
        ok, _, _, _, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(
            aop, dop, valid, rays, i, min_dop, rho_lo, rho_max
        )
        c_r, c_i = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        m = (wm[i] if ok else 0.0) if paired else p * p
        w = _taper1(rho, rho_max, taper_frac) * m
        cr[q] = c_r * w
        ci[q] = c_i * w
        xi[q] = atan2(rx, ry)
        tr[q] = _ring_t(rho, rho_lo, span, n_rings)
        u1 = _level_resid(c2a, s2a, rx, ry, rz, a0, a1, a2)
        u2 = _level_resid(c2a, s2a, rx, ry, rz, b0, b1, b2)
        u1 = u1 if ok else 0.0
        u2 = u2 if ok else 0.0
        r1[q] = u1
        r2[q] = u2
        q0 += u1 * u1
        q1 += u2 * u2
    rss[0] += q0
    rss[1] += q1


@njit(cache=True, nogil=True, fastmath=_FMV, error_model='numpy')
def _ring_harmonic(
    n, kk, n_rings, cr, ci, xi, tr, Bpr, Bpi, Bmr, Bmi, acc
):  # pragma: no cover - compiled
    """
    Accumulate harmonic kk of the derivative of F' by the AoP.

    Harmonic kk of d F' / d a: acc += Re(c E B+(ring)) + Re(c conj(E) B-(ring)), E = e^kk = exp(-i
    kk xi), B+- linear between the rings (tables padded by a zero ring).
    """
    for q in range(n):
        s, c = sincos(kk * xi[q])
        pr = cr[q] * c + ci[q] * s  # c E
        pi_ = ci[q] * c - cr[q] * s
        mr = cr[q] * c - ci[q] * s  # c conj(E)
        mi = ci[q] * c + cr[q] * s
        j, f = _ring_split(tr[q], n_rings)
        g = 1.0 - f
        acc[q] += (
            pr * (g * Bpr[kk, j] + f * Bpr[kk, j + 1])
            - pi_ * (g * Bpi[kk, j] + f * Bpi[kk, j + 1])
            + mr * (g * Bmr[kk, j] + f * Bmr[kk, j + 1])
            - mi * (g * Bmi[kk, j] + f * Bmi[kk, j + 1])
        )


@njit(cache=True, nogil=True, error_model='numpy')
def ring_terms2(
    view, ring, n_rings, K, mirror, a_in, rot, F2, suns, t0, t1, rss
):  # pragma: no cover - compiled
    """
    Compute the per-pixel terms of the Symmetry influence pass (before the block sums).

    t0[i], t1[i] = (d theta / d a_i) * residual_j(i) for the two candidate suns ``suns`` = (s1,
    s2), d theta / d a_i = -(d F'/d a_i) / F'' with d F'/d a_i = Re sum_k (-8k) e^{2ik theta} w_i
    c_i e_i^k A_k(i) (A_k: a_k interpolated at the pixel's ring); rss[j] += residual_j^2 (pair
    weights as :func:`._sm_asm_kernels.band_terms2`). In chunks: the per-pixel terms
    (vectorised), one loop per harmonic. The block sums (:func:`._disc._block_sums`) can then be
    taken over any blocks of the same pixel order.
    """
    aop, dop, valid, rays, xs, ys = view
    min_dop, rho_lo, rho_max, taper_frac = ring
    mg, mq, mp = mirror
    s1, s2 = suns
    N = aop.size
    wm = _pair_weights(mg, mq, mp, xs, ys)
    paired = mg.shape[0] > 0
    Bpr = np.zeros((K + 1, n_rings + 1))
    Bpi = np.zeros((K + 1, n_rings + 1))
    Bmr = np.zeros((K + 1, n_rings + 1))
    Bmi = np.zeros((K + 1, n_rings + 1))
    for kk in range(1, K + 1):
        for j in range(n_rings):
            bp = (-8.0 * kk) * rot[K + kk] * a_in[K + kk, j]
            bm = (8.0 * kk) * rot[K - kk] * a_in[K - kk, j]
            Bpr[kk, j] = bp.real
            Bpi[kk, j] = bp.imag
            Bmr[kk, j] = bm.real
            Bmi[kk, j] = bm.imag
    CH = _RING_CHUNK
    cr = np.empty(CH)
    ci = np.empty(CH)
    xi = np.empty(CH)
    tr = np.empty(CH)
    r1 = np.empty(CH)
    r2 = np.empty(CH)
    acc = np.empty(CH)
    for o in range(0, N, CH):
        n = min(CH, N - o)
        _ring_terms(
            aop,
            dop,
            valid,
            rays,
            o,
            n,
            min_dop,
            rho_lo,
            rho_max,
            taper_frac,
            n_rings,
            s1,
            s2,
            wm,
            paired,
            cr,
            ci,
            xi,
            tr,
            r1,
            r2,
            rss,
        )
        acc[:n] = 0.0
        for kk in range(1, K + 1):
            _ring_harmonic(n, kk, n_rings, cr, ci, xi, tr, Bpr, Bpi, Bmr, Bmi, acc)
        for q in range(n):
            sens = -acc[q] / F2
            t0[o + q] = sens * r1[q]
            t1[o + q] = sens * r2[q]
