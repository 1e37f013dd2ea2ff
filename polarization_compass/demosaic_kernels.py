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
The numba kernels of the demosaic: from raw DoFP samples to Stokes, AoP, DoP and validity.

Fused kernels, parallel over rows, for the superpixel and bilinear methods, with the IFOV check's
redundancy test inside (``lim``), and the sampler of the redundancy noise. The methods, the
conventions and the measured costs are in :mod:`.demosaic`'s docstring.
"""

from __future__ import annotations

import math

from numba import njit, prange
import numpy as np

from .fastmath import axial_atan2_f32

# fastmath without 'nnan'/'ninf': the kernels rely on NaN comparisons being false.
_FM = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}
_PI32 = np.float32(math.pi)
_HALF_PI32 = np.float32(math.pi / 2)


# ------------------------------------------------------------------------------------------------
# Kernels
# ------------------------------------------------------------------------------------------------
@njit(inline='always', fastmath=_FM, cache=True)
def _finish(s0, s1, s2, ok):  # pragma: no cover - compiled
    """(aop, dop, valid) from camera-frame Stokes; branch-free so that row loops vectorise."""
    c = -s1
    ax = axial_atan2_f32(s2, c)  # atan2(S2, -S1) folded to [-pi/2, pi/2)
    full = ax + (_PI32 if ax <= np.float32(0.0) else -_PI32)
    # unfold to (-pi, pi]; on the c = 0 line the fold gives -pi/2 for both signs of S2, so S2 > 0
    # (true angle +pi/2, AoP +45 deg) unfolds too
    unfold = (c < np.float32(0.0)) | ((c == np.float32(0.0)) & (s2 > np.float32(0.0)))
    ax = full if unfold else ax
    a = np.float32(0.5) * ax
    a = -_HALF_PI32 if a >= _HALF_PI32 else a
    lin = math.sqrt(s1 * s1 + s2 * s2)
    ok = ok & (s0 > np.float32(0.0)) & (lin > np.float32(0.0))
    d = min(lin / max(s0, np.float32(1e-30)), np.float32(1.0))
    return (a if ok else np.float32(0.0)), (d if ok else np.float32(0.0)), ok


@njit(inline='always', fastmath=_FM, cache=True)
def _good(v, sat):  # pragma: no cover - compiled
    """Finite (NaN/inf comparisons are false) and below saturation."""
    return (v < sat) & (v > np.float32(-np.inf))


@njit(inline='always', fastmath=_FM, cache=True)
def _u(w, r, c):  # pragma: no cover - compiled
    """Redundancy weight cos(4 phi) (+1 for 0/90, -1 for 45/135) from the Stokes weights."""
    return w[r, c, 0] * w[r, c, 0] - w[r, c, 1] * w[r, c, 1]


@njit(inline='always', fastmath=_FM, cache=True)
def _consistent(ok, s0, r, lim):  # pragma: no cover - compiled
    """
    Apply the redundancy check ``(r - mu S0)^2 <= A S0 + B + C S0^2``, ``lim = (A, B, C, mu)``.

    ``lim = (inf, inf, inf, 0)`` switches it off (a NaN ``r`` comes only from a sample already
    invalid).
    """
    e = r - lim[3] * s0
    return ok & (e * e <= (lim[0] * s0 + lim[1]) + lim[2] * (s0 * s0))


@njit(inline='always', fastmath=_FM, cache=True)
def _superpixel_pixel(m, i, j, w, sat):  # pragma: no cover - compiled
    """
    Compute the Stokes vector of the 2 x 2 block whose top-left sample is (i, j).

    ``w``: the (2, 2, 2) Stokes weights.
    """
    a = np.float32(m[i, j])
    b = np.float32(m[i, j + 1])
    c = np.float32(m[i + 1, j])
    d = np.float32(m[i + 1, j + 1])
    ok = _good(a, sat) & _good(b, sat) & _good(c, sat) & _good(d, sat)
    s0 = np.float32(0.5) * ((a + b) + (c + d))
    s1 = (w[0, 0, 0] * a + w[0, 1, 0] * b) + (w[1, 0, 0] * c + w[1, 1, 0] * d)
    s2 = (w[0, 0, 1] * a + w[0, 1, 1] * b) + (w[1, 0, 1] * c + w[1, 1, 1] * d)
    # redundancy (I0 + I90) - (I45 + I135): weight cos(4 phi) = cos^2(2 phi) - sin^2(2 phi)
    r = (_u(w, 0, 0) * a + _u(w, 0, 1) * b) + (_u(w, 1, 0) * c + _u(w, 1, 1) * d)
    return s0, s1, s2, ok, r


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _superpixel_kernel(m, w, sat, lim, aop, dop, valid):  # pragma: no cover - compiled
    """One (aop, dop, valid) per 2 x 2 block."""
    H2, W2 = aop.shape
    for k in prange(H2):
        for col in range(W2):
            s0, s1, s2, ok, r = _superpixel_pixel(m, 2 * k, 2 * col, w, sat)
            ok = _consistent(ok, s0, r, lim)
            aop[k, col], dop[k, col], valid[k, col] = _finish(s0, s1, s2, ok)


@njit(inline='always', fastmath=_FM, cache=True)
def _stokes_or_zero(s0, s1, s2, ok):  # pragma: no cover - compiled
    """
    Return the Stokes output (S0, S1, S2) of one pixel, or zeros when unusable.

    The Stokes output of one pixel: (S0, S1, S2) when its samples are usable (``ok``), S0 > 0 and
    S1, S2 not both 0; else zeros. Branch-free (selects), so that row loops vectorise.
    """
    z = np.float32(0.0)
    ok = ok & (s0 > z) & ((s1 != z) | (s2 != z))
    return (s0 if ok else z), (s1 if ok else z), (s2 if ok else z)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _superpixel_stokes_kernel(m, w, sat, lim, s0o, s1o, s2o):  # pragma: no cover - compiled
    """One Stokes vector per 2 x 2 block; zeros where invalid."""
    H2, W2 = s0o.shape
    for k in prange(H2):
        for col in range(W2):
            s0, s1, s2, ok, r = _superpixel_pixel(m, 2 * k, 2 * col, w, sat)
            ok = _consistent(ok, s0, r, lim)
            s0o[k, col], s1o[k, col], s2o[k, col] = _stokes_or_zero(s0, s1, s2, ok)


@njit(inline='always', fastmath=_FM, cache=True)
def _bilinear_pixel(m, rows, cols, w, v, sat):  # pragma: no cover - compiled
    """
    Return the Stokes vector at (i, j) from its 3 x 3 neighbourhood (compiled, inlined).

    ``rows`` = (i - 1, i, i + 1) and ``cols`` = (j - 1, j, j + 1), mirrored at the edges; ``w``
    and ``v`` (4-tuples): the S1 and S2 weights of the channels at the centre, the horizontal
    pair, the vertical pair and the diagonal four.
    """
    im, i, ip = rows
    jm, j, jp = cols
    w0, w1, w2, w3 = w
    v0, v1, v2, v3 = v
    vc = np.float32(m[i, j])
    a = np.float32(m[i, jm])
    b = np.float32(m[i, jp])
    c = np.float32(m[im, j])
    d = np.float32(m[ip, j])
    e = np.float32(m[im, jm])
    f = np.float32(m[im, jp])
    g = np.float32(m[ip, jm])
    h = np.float32(m[ip, jp])
    ih = np.float32(0.5) * (a + b)
    iv = np.float32(0.5) * (c + d)
    idg = np.float32(0.25) * ((e + f) + (g + h))
    s0 = np.float32(0.5) * ((vc + ih) + (iv + idg))
    s1 = (w0 * vc + w1 * ih) + (w2 * iv + w3 * idg)
    s2 = (v0 * vc + v1 * ih) + (v2 * iv + v3 * idg)
    # redundancy (I0 + I90) - (I45 + I135) of the interpolated channels, weights cos(4 phi)
    r = ((w0 * w0 - v0 * v0) * vc + (w1 * w1 - v1 * v1) * ih) + (
        (w2 * w2 - v2 * v2) * iv + (w3 * w3 - v3 * v3) * idg
    )
    ok = (
        _good(vc, sat)
        & _good(a, sat)
        & _good(b, sat)
        & _good(c, sat)
        & _good(d, sat)
        & _good(e, sat)
        & _good(f, sat)
        & _good(g, sat)
        & _good(h, sat)
    )
    return s0, s1, s2, ok, r


@njit(inline='always', fastmath=_FM, cache=True)
def _bilinear_at(m, i, im, ip, j, W, r, rw, sat):  # pragma: no cover - compiled
    """Stokes at an edge column j (0 or W - 1), mirrored like BORDER_REFLECT_101."""
    jm = j - 1 if j > 0 else 1
    jp = j + 1 if j < W - 1 else W - 2
    q = j & 1
    w = (rw[r, q, 0], rw[r, q, 1], rw[r, q, 2], rw[r, q, 3])
    v = (rw[r, q, 4], rw[r, q, 5], rw[r, q, 6], rw[r, q, 7])
    return _bilinear_pixel(m, (im, i, ip), (jm, j, jp), w, v, sat)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _bilinear_kernel(m, rw, sat, lim, aop, dop, valid):  # pragma: no cover - compiled
    """
    Full-resolution bilinear demosaic to (aop, dop, valid).

    ``rw`` (2 row parities, 2 column
    parities, 8): S1 and S2 weights of the (centre, horizontal, vertical, diagonal) channels.
    The interior loop is branch-free (selects only) so that LLVM vectorises it; keep it that way.
    """
    H, W = m.shape
    for i in prange(H):
        im = i - 1 if i > 0 else 1  # BORDER_REFLECT_101 keeps the 2 x 2 phase
        ip = i + 1 if i < H - 1 else H - 2
        r = i & 1
        e0, e1, e2, e3 = rw[r, 0, 0], rw[r, 0, 1], rw[r, 0, 2], rw[r, 0, 3]
        f0, f1, f2, f3 = rw[r, 0, 4], rw[r, 0, 5], rw[r, 0, 6], rw[r, 0, 7]
        o0, o1, o2, o3 = rw[r, 1, 0], rw[r, 1, 1], rw[r, 1, 2], rw[r, 1, 3]
        p0, p1, p2, p3 = rw[r, 1, 4], rw[r, 1, 5], rw[r, 1, 6], rw[r, 1, 7]
        for j in range(1, W - 1):
            odd = (j & 1) == 1
            w = (o0 if odd else e0, o1 if odd else e1, o2 if odd else e2, o3 if odd else e3)
            v = (p0 if odd else f0, p1 if odd else f1, p2 if odd else f2, p3 if odd else f3)
            s0, s1, s2, ok, rd = _bilinear_pixel(m, (im, i, ip), (j - 1, j, j + 1), w, v, sat)
            ok = _consistent(ok, s0, rd, lim)
            aop[i, j], dop[i, j], valid[i, j] = _finish(s0, s1, s2, ok)
        for j in (0, W - 1):
            s0, s1, s2, ok, rd = _bilinear_at(m, i, im, ip, j, W, r, rw, sat)
            ok = _consistent(ok, s0, rd, lim)
            aop[i, j], dop[i, j], valid[i, j] = _finish(s0, s1, s2, ok)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _bilinear_stokes_kernel(m, rw, sat, lim, s0o, s1o, s2o):  # pragma: no cover - compiled
    """Full-resolution bilinear Stokes images; zeros where invalid."""
    H, W = m.shape
    for i in prange(H):
        im = i - 1 if i > 0 else 1
        ip = i + 1 if i < H - 1 else H - 2
        r = i & 1
        for j in range(W):
            s0, s1, s2, ok, rd = _bilinear_at(m, i, im, ip, j, W, r, rw, sat)
            ok = _consistent(ok, s0, rd, lim)
            s0o[i, j], s1o[i, j], s2o[i, j] = _stokes_or_zero(s0, s1, s2, ok)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _stokes_to_aop_kernel(s0, s1, s2, aop, dop, valid):  # pragma: no cover - compiled
    a0 = s0.reshape(-1)
    a1 = s1.reshape(-1)
    a2 = s2.reshape(-1)
    ao = aop.reshape(-1)
    do = dop.reshape(-1)
    vo = valid.reshape(-1)
    inf = np.float32(np.inf)
    for n in prange(a0.size):
        x0, x1, x2 = a0[n], a1[n], a2[n]
        ok = _good(x0, inf) & _good(x1, inf) & _good(x2, inf)
        x0 = x0 if ok else np.float32(0.0)
        x1 = x1 if ok else np.float32(0.0)
        x2 = x2 if ok else np.float32(0.0)
        ao[n], do[n], vo[n] = _finish(x0, x1, x2, ok)


@njit(fastmath=_FM, cache=True, nogil=True)
def _redundancy_samples(m, w, rw, sat, superpixel, rows, cols, s0o, ro, oko):  # pragma: no cover
    """(S0, redundancy, usable) of the method's outputs at ``rows`` x ``cols`` (output indices)."""
    H, W = m.shape
    for a in range(rows.size):
        i = rows[a]
        for b in range(cols.size):
            j = cols[b]
            if superpixel:
                s0, s1, s2, ok, r = _superpixel_pixel(m, 2 * i, 2 * j, w, sat)
            else:
                s0, s1, s2, ok, r = _bilinear_at(m, i, i - 1, i + 1, j, W, i & 1, rw, sat)
            s0o[a, b], ro[a, b], oko[a, b] = s0, r, ok & (s0 > np.float32(0.0))
