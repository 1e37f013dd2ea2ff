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
The compiled passes of SM-ASM (:mod:`.sm_asm`).

The band sums of the plain fit (pass 1), the gather and per-axis fit on mirror pairs, and the
influence pass (pass 2). Shared per-pixel steps: :mod:`._disc`; the gather's shared part:
:mod:`._pair_gather`; pair weights: :mod:`._mirror`. The per-pixel loops ``_band_sums`` and
``_band_terms`` vectorise (``test/test_vecmath.py`` checks their LLVM IR).
"""

from __future__ import annotations

import math

from numba import njit
import numpy as np

from ._disc import _brightness_pass, _exp2i_aoplm, _lane_pixel, _level_resid, _taper1
from ._mirror import _bilinear0_pair, _mirror_consts, _mirror_pos, _pair_weights
from ._pair_gather import GATHER_CHUNK, gather_chunk, gather_scratch, kept_pixel
from ..fastmath import exp_nonpos
from ..fastmath import FM as _FMV

__all__ = ['band_pass1', 'band_gather', 'band_fit', 'band_terms2']


@njit(cache=True, nogil=True, fastmath=_FMV, error_model='numpy')
def _band_sums(
    aop, dop, valid, rays, min_dop, rho_max, taper_frac, inv4tol2, out, cnt
):  # pragma: no cover
    """Accumulate the sums of :func:`band_pass1` (vectorised)."""
    n_ok = n_v = n_bad = n_hole = 0
    Zr = Zi = nrm = 0.0
    for i in range(aop.size):
        ok, v, bad, hole, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(
            aop, dop, valid, rays, i, min_dop, 0.0, rho_max
        )
        n_ok += np.int64(ok)
        n_v += np.int64(v)
        n_bad += np.int64(bad)
        n_hole += np.int64(hole)
        cr, ci = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        W = (
            exp_nonpos((-cr - 1.0) * inv4tol2) * p * p * _taper1(rho, rho_max, taper_frac)
        )  # cos 2 delta = -cr
        Zr += W * (ry * ry - rx * rx)
        Zi += W * 2.0 * rx * ry
        nrm += W * rho * rho
    out[0] += Zr
    out[1] += Zi
    out[2] += nrm
    cnt[0] += n_ok
    cnt[1] += n_v
    cnt[2] += n_bad
    cnt[3] += n_hole


@njit(cache=True, nogil=True)
def band_pass1(view, inten, has_i, ring, inv4tol2, out, cnt, stats):  # pragma: no cover - compiled
    """
    Run the SM-ASM first pass: the weighted sum Z of the pixels' z^2 and the counts.

    SM-ASM: out = (Re Z, Im Z, sum W rho^2) with Z = sum W z^2, W = exp((cos 2 delta - 1) / (4
    tol^2)) DoP^2 taper; cnt = (usable, valid, valid non-finite, unusable inside the disc); with
    ``has_i`` the brightness statistics of the usable pixels into ``stats`` (a second, scalar
    loop). ``view``: (aop, dop, valid, rays, xs, ys); ``ring``: :class:`._disc.DiscRing` (the
    whole disc: its ``rho_lo`` is not read).
    """
    aop, dop, valid, rays, _, _ = view
    md, rho_max = ring.min_dop, ring.rho_max
    _band_sums(aop, dop, valid, rays, md, rho_max, ring.taper_frac, inv4tol2, out, cnt)
    if has_i:
        _brightness_pass(aop, dop, valid, rays, inten, md, 0.0, rho_max, stats)


@njit(cache=True, nogil=True)
def band_gather(
    view, ring, inv4tol2, mirror, own_dop2, g_uv, g_ts, g_val
):  # pragma: no cover - compiled
    """
    Gather the disc's valid pixels for SM-ASM with mirror pairs (step 1).

    SM-ASM with mirror pairs, step 1 (:mod:`._pair_gather`): every valid finite pixel of the disc
    with S(p) > 0, compacted: g_uv[:, j] = offset from the principal point (mm), g_ts[j] = taper
    S(p), g_val[:, j] = (W S(p) z^2 (re, im), W S(p) rho^2) with W = exp((cos 2 delta - 1) / (4
    tol^2)) taper Q(p) / S(p): the pair weight's own factor (Q: :func:`._mirror.mirror_map`), the
    mirror image's Q(p') in :func:`band_fit` (W = 0 for a pixel below min_dop); with ``own_dop2``
    the own factor is DoP(p)^2 S(p) instead (the occlusion-only pair weights, fitted with Q = S).
    Returns the count.
    """
    scratch = gather_scratch()
    n = 0
    for o in range(0, view[0].size, GATHER_CHUNK):
        kept = gather_chunk(view, ring, mirror, own_dop2, o, scratch, g_uv, g_ts, n)
        for k in range(kept):
            usable, tp, q, rx, ry, rho, c2a, s2a = kept_pixel(scratch, k)
            W = 0.0
            if usable:
                cr, ci = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
                W = math.exp((-cr - 1.0) * inv4tol2) * tp * q
            g_val[0, n] = W * (ry * ry - rx * rx)
            g_val[1, n] = W * 2.0 * rx * ry
            g_val[2, n] = W * rho * rho
            n += 1
    return n


@njit(cache=True, nogil=True)
def band_fit(g_uv, g_ts, g_val, n, start, step, mg, mq, mp, out):  # pragma: no cover - compiled
    """
    Fit one trial axis for SM-ASM with mirror pairs (step 2).

    SM-ASM with mirror pairs, step 2 (per trial axis): out = (Re Z, Im Z, sum W rho^2 (each
    gathered term times Q(p'), so the weights Q(p) Q(p') are symmetric about the axis),
    coverage numerator sum taper S(p) S(p'), usable pixels with a pair weight > 0) over every
    ``step``-th gathered pixel from ``start``.
    """
    st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
    Zr = Zi = nrm = cov = 0.0
    n_pair = 0
    for j in range(start, n, step):
        # S(p') and Q(p') at the mirror image (:func:`._mirror._mirror_pos`), one position
        r, c = _mirror_pos(st, ct, kc, kr, c0, r0, g_uv[0, j], g_uv[1, j])
        m, q = _bilinear0_pair(mg, mq, r, c)
        if not m > 0.0:
            continue
        cov += g_ts[j] * m
        Zr += g_val[0, j] * q
        Zi += g_val[1, j] * q
        nrm += g_val[2, j] * q
        n_pair += 1 if g_val[2, j] * q > 0.0 else 0
    out[0] = Zr
    out[1] = Zi
    out[2] = nrm
    out[3] = cov
    out[4] = n_pair


@njit(cache=True, nogil=True, fastmath=_FMV, error_model='numpy')
def _band_terms(
    aop,
    dop,
    valid,
    rays,
    min_dop,
    rho_max,
    taper_frac,
    inv4tol2,
    Zr,
    Zi,
    s1,
    s2,
    wm,
    paired,
    t0,
    t1,
    rss,
):  # pragma: no cover - compiled
    """
    Compute the per-pixel SM-ASM influence terms and residual sums (vectorised).

    Per pixel (vectorised): t_j = (d theta / d a) * residual_j (0 if unusable); rss[j] +=
    residual_j^2. The weight's DoP factors: DoP(p)^2, or with ``paired`` the pair weight wm = Q(p)
    Q(p') (:func:`._mirror._pair_weights`).
    """
    modZ2 = Zr * Zr + Zi * Zi
    a0, a1, a2 = s1[0], s1[1], s1[2]
    b0, b1, b2 = s2[0], s2[1], s2[2]
    q0 = q1 = 0.0
    for i in range(aop.size):
        ok, _, _, _, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(
            aop, dop, valid, rays, i, min_dop, 0.0, rho_max
        )
        cr, ci = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        m = (wm[i] if ok else 0.0) if paired else p * p
        W = exp_nonpos((-cr - 1.0) * inv4tol2) * _taper1(rho, rho_max, taper_frac) * m
        dW = W * ci * 2.0 * inv4tol2  # dW/da: d(cos 2 delta)/da = -2 sin 2 delta = 2 ci
        z2r = ry * ry - rx * rx
        z2i = 2.0 * rx * ry
        sens = 0.5 * dW * (z2i * Zr - z2r * Zi) / modZ2
        r1 = _level_resid(c2a, s2a, rx, ry, rz, a0, a1, a2)
        r2 = _level_resid(c2a, s2a, rx, ry, rz, b0, b1, b2)
        r1 = r1 if ok else 0.0
        r2 = r2 if ok else 0.0
        t0[i] = sens * r1
        t1[i] = sens * r2
        q0 += r1 * r1
        q1 += r2 * r2
    rss[0] += q0
    rss[1] += q1


@njit(cache=True, nogil=True)
def band_terms2(view, ring, inv4tol2, mirror, Z, suns, t0, t1, rss):  # pragma: no cover - compiled
    """
    Compute the per-pixel terms of the SM-ASM influence pass (before the block sums).

    t0[i], t1[i] = (d theta / d a_i) * residual_j(i) for the two candidate suns ``suns`` = (s1,
    s2); rss[j] += residual_j^2 (pair weights Q(p) Q(p') from ``mirror`` = (mg, mq, mp) when
    ``mg`` is not empty, else DoP(p)^2); ``Z`` = (Re Z, Im Z) of the fit. One vectorised loop
    (:mod:`polarization_compass.fastmath`). The block sums (:func:`._disc._block_sums`) can then
    be taken over any blocks of the same pixel order.
    """
    aop, dop, valid, rays, xs, ys = view
    mg, mq, mp = mirror
    _band_terms(
        aop,
        dop,
        valid,
        rays,
        ring.min_dop,
        ring.rho_max,
        ring.taper_frac,
        inv4tol2,
        Z[0],
        Z[1],
        suns[0],
        suns[1],
        _pair_weights(mg, mq, mp, xs, ys),
        mg.shape[0] > 0,
        t0,
        t1,
        rss,
    )
