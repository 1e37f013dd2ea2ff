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
Counter-based random numbers for the sensor noise: SplitMix64 feeding a 256-layer ziggurat.

Pixel (i, j) of a W-wide block owns counters ``(i W + j) * 1024 ...`` of a stream keyed by one
64-bit draw, so the same key gives the same numbers whatever the thread count (module docstring of
:mod:`polarization_compass.sensor`).
"""

from __future__ import annotations

import math

from numba import njit, prange
import numpy as np

__all__ = ['standard_normal_f32']

# ------------------------------------------------------------------------------------------------
# Random numbers: counter-based SplitMix64 + ziggurat (Marsaglia & Tsang 2000), 256 layers
# ------------------------------------------------------------------------------------------------
_ZIG_N = 256


def _ziggurat_tables(n: int = _ZIG_N):
    """
    Compute the ziggurat layer edges for the standard normal density.

    Layer edges for f(x) = exp(-x^2 / 2): ``x[0] = r`` (base layer, tail beyond it), x decreasing
    to ``x[n-1] = 0`` at the top, every layer of area ``v``. ``r`` solved by bisection so the top
    closes.

    Returns (width (n,), inner (n,), f_edge (n + 1,), r, v): a layer k draws ``x = u * width[k]``
    and accepts at once when ``x < inner[k]``; ``f_edge[k]`` / ``f_edge[k + 1]`` are f at its
    bottom / top.
    """
    f = lambda x: math.exp(-0.5 * x * x)  # noqa: E731
    tail = lambda r: math.sqrt(math.pi / 2) * math.erfc(r / math.sqrt(2))  # noqa: E731

    def close(r):
        v = r * f(r) + tail(r)
        x = r
        xs = [r]
        for _ in range(n - 2):
            fx = f(x) + v / x
            if fx >= 1.0:
                return 1.0, v, xs
            x = math.sqrt(-2.0 * math.log(fx))
            xs.append(x)
        return f(x) + v / x - 1.0, v, xs

    lo, hi = 2.0, 6.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if close(mid)[0] > 0.0:
            lo = mid
        else:
            hi = mid
    _, v, xs = close(hi)
    r = hi
    xs.append(0.0)  # x[n-1] = 0: the top layer has no inner box
    x = np.array(xs)
    width = np.empty(n)
    width[0] = v / f(r)  # base strip: box [0, r] x [0, f(r)] plus the tail
    width[1:] = x[:-1]
    inner = x.copy()
    f_edge = np.empty(n + 1)
    f_edge[0] = 0.0
    f_edge[1:] = np.exp(-0.5 * x * x)
    return width, inner, f_edge, r, v


_ZW, _ZX, _ZF, _ZR, _ZV = _ziggurat_tables()
_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_DRAWS_PER_ELEMENT = (
    1024  # counter space reserved per element (a normal needs ~1.01 draws on average)
)


@njit(inline='always', cache=True)
def _splitmix(key, counter):  # pragma: no cover - compiled
    """
    Return the ``counter``-th output of SplitMix64 started at ``key``.

    The state is key + counter * gamma.
    """
    z = key + counter * _GAMMA
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@njit(inline='always', cache=True)
def _uniform(key, counter):  # pragma: no cover - compiled
    """Uniform in (0, 1) from the top 53 bits (never exactly 0, so log() is safe)."""
    return (np.float64(np.int64(_splitmix(key, counter) >> np.uint64(11))) + 0.5) * (
        1.0 / 9007199254740992.0
    )


@njit(cache=True)
def _normal_slow(key, base, j, k, x, neg):  # pragma: no cover - compiled
    """
    Draw on the ziggurat's rare paths (~1.5 % of draws): tail, wedge, and restarts.

    ``j`` counters used.
    """
    zw, zx, zf, r = _ZW, _ZX, _ZF, _ZR  # global arrays: compile-time constants, no call overhead
    while True:
        if k == 0:  # tail beyond r (Marsaglia 1964)
            while True:
                a = -math.log(_uniform(key, base + j)) / r
                b = -math.log(_uniform(key, base + j + np.uint64(1)))
                j += np.uint64(2)
                if 2.0 * b > a * a:
                    return -(r + a) if neg else r + a
        y = zf[k] + _uniform(key, base + j) * (zf[k + 1] - zf[k])
        j += np.uint64(1)
        if y < math.exp(-0.5 * x * x):
            return -x if neg else x
        z = _splitmix(key, base + j)  # rejected: a fresh draw
        j += np.uint64(1)
        k = np.int64(z & np.uint64(0xFF))
        neg = ((z >> np.uint64(8)) & np.uint64(1)) == np.uint64(1)
        x = np.float64(np.int64(z >> np.uint64(11))) * (1.0 / 9007199254740992.0) * zw[k]
        if x < zx[k]:
            return -x if neg else x


@njit(inline='always', cache=True)
def _normal(key, base):  # pragma: no cover - compiled
    """
    Draw a standard normal from the counter stream starting at ``base``.

    One draw on the fast path (98.5 %), ~1.02 on average. Bits: 0-7 layer, 8 sign, 11-63 the
    uniform.
    """
    z = _splitmix(key, base)
    k = np.int64(z & np.uint64(0xFF))
    neg = ((z >> np.uint64(8)) & np.uint64(1)) == np.uint64(1)
    x = np.float64(np.int64(z >> np.uint64(11))) * (1.0 / 9007199254740992.0) * _ZW[k]
    if x < _ZX[k]:
        return -x if neg else x
    return _normal_slow(key, base, np.uint64(1), k, x, neg)


@njit(cache=True)
def _poisson_small(key, base, lam):  # pragma: no cover - compiled
    """
    Draw an exact Poisson(lam) by Knuth's product of uniforms; lam <= 200.

    The bound keeps exp(-lam) a normal double.
    """
    limit = math.exp(-lam)
    p = 1.0
    k = -1
    j = np.uint64(0)
    while True:
        k += 1
        p *= _uniform(key, base + j)
        j += np.uint64(1)
        if p <= limit:
            return k


@njit(parallel=True, cache=True)
def _normal_kernel(key, out):  # pragma: no cover - compiled
    o = out.reshape(-1)
    stride = np.uint64(_DRAWS_PER_ELEMENT)
    for n in prange(o.size):
        o[n] = np.float32(_normal(key, np.uint64(n) * stride))


def standard_normal_f32(key: int, shape) -> np.ndarray:
    """
    Return standard normals (float32) of the counter-based stream ``key``.

    Element n uses counters ``n * 1024 ...``. Exposed for tests of the generator's distribution.

    Parameters
    ----------
    key : int
        64-bit key of the SplitMix64 stream.
    shape : int or tuple of int
        Shape of the output.

    Returns
    -------
    numpy.ndarray
        float32 draws from N(0, 1) of that shape; the same key gives the same values.

    References
    ----------
    .. [1] G. Marsaglia and W. W. Tsang, "The ziggurat method for generating random variables",
       Journal of Statistical Software 5(8), 2000.

    """
    out = np.empty(shape, np.float32)
    _normal_kernel(np.uint64(key), out.reshape(-1))  # flat: one argument type for any shape
    return out
