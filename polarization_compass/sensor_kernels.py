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
The numba kernels of the sensor's forward model: one per stage and per fused pair of effects.

Malus's law behind ideal, leaky or miscalibrated polarizers, crosstalk, shot and read noise,
saturation and quantisation (the physics is in :mod:`.sensor`'s docstring). :data:`_IMPLEMENTS`
names the effects each kernel computes and :func:`_count` counts them in :mod:`.instrumentation`
just before the kernel runs; :func:`.sensor.simulate_mosaic` chooses the kernels of the declared
effects.
"""

from __future__ import annotations

import math

from numba import njit, prange
import numpy as np

from . import instrumentation as instr
from .fastmath import sincos32
from .rng import (
    _DRAWS_PER_ELEMENT,
    _normal,
    _poisson_small,
    _splitmix,
    _ZW,
    _ZX,
)

_FM = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}


# ------------------------------------------------------------------------------------------------
# Forward model: one kernel per stage (and per combination of fused effects)
# ------------------------------------------------------------------------------------------------
# Every effect's arithmetic lives only in the kernels that implement it; the kernels of the other
# stages do not contain it (no "multiply by 1", no "add 0 * noise", no "min with +inf").
# ``_IMPLEMENTS`` names the effects each kernel computes and ``_count`` counts exactly those (plus
# the kernel itself) just before that kernel runs, so a counter reports the code that ran, not the
# configuration that asked for it.
_IMPLEMENTS = {
    '_mean_electrons_kernel': ('mosaic',),  # ideal polarizers (Malus)
    '_mean_electrons_er_kernel': (
        'mosaic',
        'extinction_ratio',
    ),  # leaky polarizers: DoP scaled by d
    '_mean_electrons_cal_kernel': (
        'mosaic',
        'calibration',
    ),  # per-pixel angle, efficiency d and gain
    '_crosstalk_kernel': ('calibration',),  # electrons shared with the 4 neighbours
    '_shot_noise_kernel': ('shot_noise',),
    '_read_noise_kernel': ('read_noise',),
    '_shot_read_noise_kernel': (
        'shot_noise',
        'read_noise',
    ),  # one draw of variance lambda + sigma^2
    '_saturate_kernel': ('exposure',),  # full-well clip, float32 electrons
    '_quantize_kernel': ('quantization',),  # DN; the ADC range clips at 2^bits - 1
    '_saturate_quantize_kernel': (
        'exposure',
        'quantization',
    ),  # full-well clip fused into the DN pass
}


def _count(name: str) -> None:
    """
    Count the sensor stages of kernel ``name`` just before it runs.

    ``sensor.<effect>`` for each effect the kernel implements, and ``sensor.kernel.<name>``: one
    dict increment per stage per frame.
    """
    for effect in _IMPLEMENTS[name]:
        instr.count('sensor.' + effect)
    instr.count('sensor.kernel.' + name)


@njit(inline='always', fastmath=_FM, cache=True)
def _malus_unit(a, dp, p, q, n0):  # pragma: no cover - compiled
    """
    Return the mean electrons at S0 = 1 behind an ideal polarizer (float32).

    ``N0 (1 - DoP (p cos 2a - q sin 2a))``.
    """
    sa, ca = sincos32(a)
    one = np.float32(1.0)
    dp = min(max(dp, np.float32(0.0)), one)
    return n0 * (one - dp * (p * (ca * ca - sa * sa) - q * (np.float32(2.0) * sa * ca)))


@njit(inline='always', fastmath=_FM, cache=True)
def _malus_unit_er(a, dp, p, q, n0, d):  # pragma: no cover - compiled
    """
    Return the mean electrons at S0 = 1 behind a polarizer of finite extinction ratio (float32).

    The polarizer's efficiency is d = (ER - 1) / (ER + 1): DoP is seen as d DoP.
    """
    sa, ca = sincos32(a)
    one = np.float32(1.0)
    dp = min(max(dp, np.float32(0.0)), one)
    return n0 * (one - d * dp * (p * (ca * ca - sa * sa) - q * (np.float32(2.0) * sa * ca)))


@njit(parallel=True, fastmath=_FM, cache=True)
def _mean_electrons_kernel(aop, dop, s0, has_s0, pq, n0, out):  # pragma: no cover - compiled
    """
    Compute the mean electrons per pixel behind ideal polarizers.

    lambda = N0 S0 (1 - DoP (p cos 2a - q sin 2a)) per pixel (ideal polarizers), (p, q) = (cos,
    sin) 2phi of the pixel's polarizer (row/column parity). float32 and branch-free inner loops so
    that they vectorise (8 lanes; keep them that way: a select on a loaded S0 inside one loop made
    it 5x slower). The float32 sine/cosine polynomials are good to ~1e-7. Non-finite or negative S0
    count as 0.
    """
    H, W = aop.shape
    n0f = np.float32(n0)
    zero = np.float32(0.0)
    for i in prange(H):
        r = i & 1
        pe, qe = np.float32(pq[r, 0, 0]), np.float32(pq[r, 0, 1])
        po, qo = np.float32(pq[r, 1, 0]), np.float32(pq[r, 1, 1])
        if has_s0:
            for j in range(W):
                odd = (j & 1) == 1
                lam = _malus_unit(aop[i, j], dop[i, j], po if odd else pe, qo if odd else qe, n0f)
                sv = s0[i, j]
                ok = (sv >= zero) & (sv < np.float32(1e30))  # NaN and inf fail both
                out[i, j] = lam * sv if ok else zero
        else:
            for j in range(W):
                odd = (j & 1) == 1
                out[i, j] = _malus_unit(
                    aop[i, j], dop[i, j], po if odd else pe, qo if odd else qe, n0f
                )


@njit(parallel=True, fastmath=_FM, cache=True)
def _mean_electrons_er_kernel(aop, dop, s0, has_s0, pq, n0, d, out):  # pragma: no cover - compiled
    """:func:`_mean_electrons_kernel` with a finite extinction ratio: DoP becomes d DoP."""
    H, W = aop.shape
    n0f = np.float32(n0)
    df = np.float32(d)
    zero = np.float32(0.0)
    for i in prange(H):
        r = i & 1
        pe, qe = np.float32(pq[r, 0, 0]), np.float32(pq[r, 0, 1])
        po, qo = np.float32(pq[r, 1, 0]), np.float32(pq[r, 1, 1])
        if has_s0:
            for j in range(W):
                odd = (j & 1) == 1
                lam = _malus_unit_er(
                    aop[i, j], dop[i, j], po if odd else pe, qo if odd else qe, n0f, df
                )
                sv = s0[i, j]
                ok = (sv >= zero) & (sv < np.float32(1e30))
                out[i, j] = lam * sv if ok else zero
        else:
            for j in range(W):
                odd = (j & 1) == 1
                out[i, j] = _malus_unit_er(
                    aop[i, j], dop[i, j], po if odd else pe, qo if odd else qe, n0f, df
                )


@njit(parallel=True, fastmath=_FM, cache=True)
def _mean_electrons_cal_kernel(
    aop, dop, s0, has_s0, pmap, qmap, dmap, gain, n0, out
):  # pragma: no cover
    """
    Compute the mean electrons per pixel with calibration errors.

    lambda = g N0 S0 (1 - d DoP (p cos 2a - q sin 2a)) with (p, q) = (cos, sin) 2phi of the pixel's
    own polarizer angle phi (camera frame, nominal + error), efficiency d and gain g (maps of the
    block).
    """
    H, W = aop.shape
    n0f = np.float32(n0)
    zero = np.float32(0.0)
    for i in prange(H):
        for j in range(W):
            lam = gain[i, j] * _malus_unit_er(
                aop[i, j], dop[i, j], pmap[i, j], qmap[i, j], n0f, dmap[i, j]
            )
            if has_s0:
                sv = s0[i, j]
                ok = (sv >= zero) & (sv < np.float32(1e30))
                lam = lam * sv if ok else zero
            out[i, j] = lam


@njit(parallel=True, fastmath=_FM, cache=True)
def _crosstalk_kernel(e, c, out):  # pragma: no cover - compiled
    """
    Add crosstalk: each pixel takes a share c of each of its 4 neighbours.

    out = (1 - 4c) e + c (sum of the 4 neighbours); a neighbour outside the block is the pixel
    itself.
    """
    H, W = e.shape
    cf = np.float32(c)
    keep = np.float32(1.0) - np.float32(4.0) * cf
    for i in prange(H):
        up = max(i - 1, 0)
        dn = min(i + 1, H - 1)
        for j in range(W):
            lf = max(j - 1, 0)
            rt = min(j + 1, W - 1)
            out[i, j] = keep * e[i, j] + cf * (e[up, j] + e[dn, j] + e[i, lf] + e[i, rt])


@njit(inline='always', fastmath=_FM, cache=True)
def _row_normals(key, b0, W):  # pragma: no cover - compiled
    """
    Draw standard normals (float32) for a row of pixels.

    Standard normals (float32) of pixels b0 ... b0 + W - 1: pixel n's normal starts at counter n *
    1024. (1) the ziggurat's fast path for every pixel, branch-free so that it vectorises, flagging
    the ~1.5 % that need the slow path; (2) those, scalar. Equal to :func:`standard_normal_f32`
    element by element.
    """
    stride = np.uint64(_DRAWS_PER_ELEMENT)
    z_row = np.empty(W, np.float32)
    slow = np.empty(W, np.bool_)
    for j in range(W):  # (1) ziggurat fast path
        z = _splitmix(key, (b0 + np.uint64(j)) * stride)
        k = np.int64(z & np.uint64(0xFF))
        neg = ((z >> np.uint64(8)) & np.uint64(1)) == np.uint64(1)
        x = np.float64(np.int64(z >> np.uint64(11))) * (1.0 / 9007199254740992.0) * _ZW[k]
        slow[j] = x >= _ZX[k]
        z_row[j] = np.float32(-x if neg else x)
    for j in range(W):  # (2) its slow path
        if slow[j]:
            z_row[j] = np.float32(_normal(key, (b0 + np.uint64(j)) * stride))
    return z_row


# Noise kernels. Pixel (i, j) of a W-wide image owns the counters ``(i W + j) * 1024 + [0, 1024)``:
# its normal starts at 0, the read noise of a Poisson pixel at 512. Results do not depend on the
# thread count.
@njit(parallel=True, fastmath=_FM, cache=True)
def _shot_noise_kernel(e, key, gauss_above):  # pragma: no cover - compiled
    """
    Add photon shot noise to the mean electrons ``e`` in place.

    Gaussian of variance lambda where lambda >= gauss_above, exact Poisson below.
    """
    H, W = e.shape
    stride = np.uint64(_DRAWS_PER_ELEMENT)
    for i in prange(H):
        row = e[i]
        b0 = np.uint64(i * W)
        z_row = _row_normals(key, b0, W)
        for j in range(W):
            lam = np.float64(row[j])
            v = lam + math.sqrt(lam) * np.float64(z_row[j])
            row[j] = row[j] if lam < gauss_above else np.float32(v)
        if gauss_above > 0.0:
            for j in range(W):
                lam = np.float64(row[j])
                if lam < gauss_above:
                    row[j] = np.float32(_poisson_small(key, (b0 + np.uint64(j)) * stride, lam))


@njit(parallel=True, fastmath=_FM, cache=True)
def _read_noise_kernel(e, key, read_sigma):  # pragma: no cover - compiled
    """Gaussian read noise of ``read_sigma`` electrons on ``e`` (in place)."""
    H, W = e.shape
    for i in prange(H):
        row = e[i]
        z_row = _row_normals(key, np.uint64(i * W), W)
        for j in range(W):
            row[j] = np.float32(np.float64(row[j]) + read_sigma * np.float64(z_row[j]))


@njit(parallel=True, fastmath=_FM, cache=True)
def _shot_read_noise_kernel(e, key, gauss_above, read_sigma):  # pragma: no cover - compiled
    """
    Add shot and read noise to ``e`` in place.

    One Gaussian draw of variance lambda + sigma^2 where lambda >= gauss_above (independent
    Gaussians add), else exact Poisson plus a Gaussian read draw.
    """
    H, W = e.shape
    stride = np.uint64(_DRAWS_PER_ELEMENT)
    var_read = read_sigma * read_sigma
    for i in prange(H):
        row = e[i]
        b0 = np.uint64(i * W)
        z_row = _row_normals(key, b0, W)
        for j in range(W):
            lam = np.float64(row[j])
            v = lam + math.sqrt(lam + var_read) * np.float64(z_row[j])
            row[j] = row[j] if lam < gauss_above else np.float32(v)
        if gauss_above > 0.0:
            for j in range(W):
                lam = np.float64(row[j])
                if lam < gauss_above:
                    base = (b0 + np.uint64(j)) * stride
                    v = np.float64(_poisson_small(key, base, lam)) + read_sigma * _normal(
                        key, base + np.uint64(512)
                    )
                    row[j] = np.float32(v)


@njit(parallel=True, fastmath=_FM, cache=True)
def _saturate_kernel(e, full_well):  # pragma: no cover - compiled
    """Clip to the full well: e = min(e, full_well) in place (float32)."""
    ef = e.reshape(-1)
    fw = np.float32(full_well)
    for n in prange(ef.size):
        ef[n] = min(ef[n], fw)


@njit(parallel=True, fastmath=_FM, cache=True)
def _quantize_kernel(e, gain, max_dn, out):  # pragma: no cover - compiled
    """DN = round(e * gain) clipped to the ADC range [0, max_dn] (round half up)."""
    ef = e.reshape(-1)
    of = out.reshape(-1)
    top = np.float32(max_dn)
    for n in prange(ef.size):
        x = np.float32(ef[n]) * gain + np.float32(0.5)
        x = min(max(x, np.float32(0.0)), top)
        of[n] = np.uint16(x)  # <= max_dn, so exact for a uint8 output too


@njit(parallel=True, fastmath=_FM, cache=True)
def _saturate_quantize_kernel(e, full_well, gain, max_dn, out):  # pragma: no cover - compiled
    """
    Saturate and quantise in one pass.

    :func:`_saturate_kernel` then :func:`_quantize_kernel` in one pass (``e`` is left unclipped).
    """
    ef = e.reshape(-1)
    of = out.reshape(-1)
    top = np.float32(max_dn)
    fw = np.float32(full_well)
    for n in prange(ef.size):
        x = min(np.float32(ef[n]), fw) * gain + np.float32(0.5)
        x = min(max(x, np.float32(0.0)), top)
        of[n] = np.uint16(x)
