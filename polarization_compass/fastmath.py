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
Fast elementary functions for compiled (numba) loops.

This module is the one home of the project's fast float math.

float64, branch-free (:func:`sincos_folded`, :func:`sincos`, :func:`atan2`, :func:`exp_nonpos`; the
fast-math flags :data:`FM` for loops built from them). numba lowers ``math.exp``, ``math.atan2``
and ``math.cos`` to calls into libm, and a call (with no SVML, as on these machines: ``numba -s``
reports ``SVML State: False``) keeps a loop scalar. These are polynomials, square roots, divisions
and selects only, so a loop built from them runs 4 float64 lanes wide on AVX2. They are exact to a
few units in the last place on the stated domains (tested against numpy over wide random samples in
``test/test_vecmath.py``); the pass-2 (uncertainty) kernels of SM-ASM and Symmetry use them, where
a relative error of 1e-12 in a sigma does not matter and a factor 2-3 in time does.

Loops that use them must be compiled with ``error_model="numpy"`` (the default "python" model tests
every float division for zero and raises: an early exit that stops vectorisation) and should write
``x = x if ok else 0.0`` before a reduction, not ``acc += x if ok else 0.0`` (LLVM does not
recognise a select inside the reduction chain).

float32 (:func:`sincos32`, :func:`sincos32_folded`, :func:`axial_atan2_f32`, its array form
:func:`axial_atan2_array`): for the float32 render, sensor and demosaic kernels and the
least-squares pass. They are inlined into the caller's loop, which keeps its own fastmath flags and
vectorises.

ROS-free, no state.
"""

from __future__ import annotations

import math

from numba import njit, prange
import numpy as np

__all__ = [
    'sincos_folded',
    'sincos',
    'atan2',
    'exp_nonpos',
    'FM',
    'sincos32',
    'sincos32_folded',
    'axial_atan2_f32',
    'axial_atan2_array',
]

#: LLVM fast-math flags for vectorised loops: reassociation (vector reductions), contraction (FMA),
#: reciprocal. No nnan/ninf: finiteness tests in the loops must stay.
FM = {'nsz', 'arcp', 'contract', 'reassoc'}

_LN2_HI = 0.693147180369123816490  # ln 2 split so that k * _LN2_HI is exact for |k| < 2^11
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.0 / math.log(2.0)


@njit(inline='always', cache=True)
def sincos_folded(a):  # pragma: no cover - compiled
    """
    Return (sin, cos) of ``a`` folded to [-pi/2, pi/2] by a multiple n of pi (float64).

    That is ``(-1)^n (sin a, cos a)``: the sign flip is harmless for axial angles (products such
    as ``cos 2a = c^2 - s^2``). Taylor polynomials to a^19 and a^20 in Horner form; the first
    omitted terms are < 3e-16 at |a| = pi/2. Branch-free, so loops built from it vectorise.

    Parameters
    ----------
    a : float
        Angle [rad], finite.

    Returns
    -------
    s, c : float
        ``(-1)^n sin a`` and ``(-1)^n cos a``, n = round(a / pi).

    """
    a = a - math.pi * np.rint(a * (1.0 / math.pi))
    z = a * a
    s = 1.0 / 121645100408832000.0
    s = s * -z + 1.0 / 355687428096000.0
    s = s * -z + 1.0 / 1307674368000.0
    s = s * -z + 1.0 / 6227020800.0
    s = s * -z + 1.0 / 39916800.0
    s = s * -z + 1.0 / 362880.0
    s = s * -z + 1.0 / 5040.0
    s = s * -z + 1.0 / 120.0
    s = s * -z + 1.0 / 6.0
    s = a * (1.0 - z * s)
    c = 1.0 / 2432902008176640000.0
    c = c * -z + 1.0 / 6402373705728000.0
    c = c * -z + 1.0 / 20922789888000.0
    c = c * -z + 1.0 / 87178291200.0
    c = c * -z + 1.0 / 479001600.0
    c = c * -z + 1.0 / 3628800.0
    c = c * -z + 1.0 / 40320.0
    c = c * -z + 1.0 / 720.0
    c = c * -z + 1.0 / 24.0
    c = c * -z + 0.5
    c = 1.0 - z * c
    return s, c


@njit(inline='always', cache=True, error_model='numpy')
def sincos(a):  # pragma: no cover - compiled
    """
    Return (sin a, cos a) for finite ``a`` (float64, branch-free).

    :func:`sincos_folded` with the sign ``(-1)^n`` restored.

    Parameters
    ----------
    a : float
        Angle [rad], finite with |a| < 1e9.

    Returns
    -------
    s, c : float
        sin a and cos a, to a few units in the last place.

    """
    n = np.rint(a * (1.0 / math.pi))
    s, c = sincos_folded(a)
    sign = 1.0 - 2.0 * abs(n - 2.0 * np.rint(0.5 * n))
    return sign * s, sign * c


@njit(inline='always', cache=True, error_model='numpy')
def atan2(y, x):  # pragma: no cover - compiled
    """
    Return the angle of (x, y) in [-pi, pi] for finite x, y: the two-argument arctangent.

    float64, branch-free; atan2(0, 0) = 0. ``t = min / max`` of |x|, |y| in [0, 1] is halved
    twice in angle (``atan t = 2 atan(t / (1 + sqrt(1 + t^2)))``) to |v| <= tan(pi / 16) < 0.2,
    where 11 terms of the odd series leave < 1e-17; then the octant is restored. Error < 1e-15
    rad.

    Parameters
    ----------
    y, x : float
        Ordinate and abscissa, finite, any common unit.

    Returns
    -------
    float
        The angle [rad] of (x, y) from +x towards +y, in [-pi, pi].

    """
    ax = abs(x)
    ay = abs(y)
    hi = max(ax, ay)
    t = min(ax, ay) / max(hi, 1e-300)
    v = t / (1.0 + math.sqrt(1.0 + t * t))
    v = v / (1.0 + math.sqrt(1.0 + v * v))
    z = v * v
    p = 1.0 / 21.0
    p = p * -z + 1.0 / 19.0
    p = p * -z + 1.0 / 17.0
    p = p * -z + 1.0 / 15.0
    p = p * -z + 1.0 / 13.0
    p = p * -z + 1.0 / 11.0
    p = p * -z + 1.0 / 9.0
    p = p * -z + 1.0 / 7.0
    p = p * -z + 1.0 / 5.0
    p = p * -z + 1.0 / 3.0
    p = p * -z + 1.0
    r = 4.0 * v * p
    r = 0.5 * math.pi - r if ay > ax else r
    r = math.pi - r if x < 0.0 else r
    return -r if y < 0.0 else r


@njit(inline='always', cache=True, error_model='numpy')
def exp_nonpos(x):  # pragma: no cover - compiled
    """
    Return exp(x) for x <= 0 (float64, branch-free).

    ``exp(x) = 2^-n exp(r)`` with ``n = round(x / ln 2)``, |r| <= ln 2 / 2 (Taylor to r^13,
    < 1e-17); ``2^-n`` is the exact product of the powers of two of n's bits. Relative error
    < 1e-15.

    Parameters
    ----------
    x : float
        Exponent, clipped to [-700, 0] (below -700 the true value is < 1e-304 and this returns
        exp(-700)).

    Returns
    -------
    float
        exp(x) in (0, 1].

    """
    x = min(max(x, -700.0), 0.0)
    k = np.rint(x * _INV_LN2)
    r = (x - k * _LN2_HI) - k * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r + 1.0
    p = p * r + 1.0
    n = np.int64(-k)
    s = (0.5 if n & 1 else 1.0) * (0.25 if n & 2 else 1.0) * (0.0625 if n & 4 else 1.0)
    s *= (
        (2.0**-8 if n & 8 else 1.0) * (2.0**-16 if n & 16 else 1.0) * (2.0**-32 if n & 32 else 1.0)
    )
    s *= (
        (2.0**-64 if n & 64 else 1.0)
        * (2.0**-128 if n & 128 else 1.0)
        * (2.0**-256 if n & 256 else 1.0)
    )
    s *= 2.0**-512 if n & 512 else 1.0
    return p * s


# --------------------------------------------------------------------------------------------
# float32
# --------------------------------------------------------------------------------------------
@njit(inline='always', cache=True)
def sincos32(a):  # pragma: no cover - compiled
    """
    Return float32 (sin a, cos a) for |a| <= pi/2.

    Taylor polynomials to a^11 and a^12 in Horner form (truncation < 6e-8 at pi/2, below float32
    rounding). Callers with wider angles fold them first (:func:`sincos32_folded`).

    Parameters
    ----------
    a : numpy.float32
        Angle [rad] with |a| <= pi/2.

    Returns
    -------
    s, c : numpy.float32
        sin a and cos a.

    """
    z = a * a
    s = np.float32(1.0 / 39916800.0)
    s = s * -z + np.float32(1.0 / 362880.0)
    s = s * -z + np.float32(1.0 / 5040.0)
    s = s * -z + np.float32(1.0 / 120.0)
    s = s * -z + np.float32(1.0 / 6.0)
    s = a * (np.float32(1.0) - z * s)
    c = np.float32(1.0 / 479001600.0)
    c = c * -z + np.float32(1.0 / 3628800.0)
    c = c * -z + np.float32(1.0 / 40320.0)
    c = c * -z + np.float32(1.0 / 720.0)
    c = c * -z + np.float32(1.0 / 24.0)
    c = c * -z + np.float32(0.5)
    c = np.float32(1.0) - z * c
    return s, c


@njit(inline='always', cache=True, error_model='numpy')
def sincos32_folded(a):  # pragma: no cover - compiled
    """
    Return float32 (sin, cos) of ``a`` folded to [-pi/2, pi/2] by a multiple n of pi.

    That is ``(-1)^n (sin a, cos a)`` (a sign flip is harmless for axial angles), by
    :func:`sincos32`: error < 4e-6 at pi/2 in the polynomial, float32 rounding 1e-7.

    Parameters
    ----------
    a : numpy.float32
        Angle [rad], finite.

    Returns
    -------
    s, c : numpy.float32
        ``(-1)^n sin a`` and ``(-1)^n cos a``, n = round(a / pi).

    """
    return sincos32(a - np.float32(math.pi) * np.rint(a * np.float32(1.0 / math.pi)))


# Odd minimax polynomial for atan(t), |t| <= tan(pi/8): atan(t) ~ t + t^3 (C3 + C5 t^2 + C7 t^4 +
# C9 t^6). Fitted for this project (Lawson-weighted least squares); max error 5e-9 rad in float64,
# 2.3e-8 rad evaluated in float32 (tests compare against numpy.arctan2). Unlike libm's scalar
# atan2f it vectorises.
_ATAN_C3 = -0.3333275666758043
_ATAN_C5 = 0.19971879261954273
_ATAN_C7 = -0.1382445336732415
_ATAN_C9 = 0.07902597096846205


@njit(inline='always', fastmath=True, cache=True)
def axial_atan2_f32(x, y):  # pragma: no cover - compiled
    """
    Return atan2(x, y) folded to [-pi/2, pi/2): the axial angle of (x, y) from +y towards +x.

    Folding mod pi makes this atan(x / y) without the division hazards: 0/0 (a ray at the sun)
    gives 0. An odd minimax polynomial on |t| <= tan(pi/8) plus octant steps; error 2.3e-8 rad in
    float32. This is the form of the paper's AoP (eq 28, atan of E(1) / E(2)).

    Parameters
    ----------
    x, y : numpy.float32
        Components along the angle's +90 deg axis (x) and its zero axis (y), any common unit.

    Returns
    -------
    numpy.float32
        The axial angle [rad] in [-pi/2, pi/2).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28.

    """
    ax = abs(x)
    ay = abs(y)
    mx = max(ax, ay)
    mn = min(ax, ay)
    q = mn / (mx if mx > np.float32(0.0) else np.float32(1.0))  # [0, 1]
    big = q > np.float32(0.41421356237309503)  # tan(pi/8)
    t = (q - np.float32(1.0)) / (q + np.float32(1.0)) if big else q
    z = t * t
    p = np.float32(_ATAN_C9)
    p = p * z + np.float32(_ATAN_C7)
    p = p * z + np.float32(_ATAN_C5)
    p = p * z + np.float32(_ATAN_C3)
    a = t + t * z * p
    if big:
        a += np.float32(math.pi / 4)
    if ax > ay:
        a = np.float32(math.pi / 2) - a
    if (x < np.float32(0.0)) != (y < np.float32(0.0)):
        a = -a
    if a >= np.float32(math.pi / 2):
        a = np.float32(-math.pi / 2)
    return a


@njit(parallel=True, cache=True, fastmath=True)
def axial_atan2_array(x, y, out):  # pragma: no cover - compiled
    """
    Apply :func:`axial_atan2_f32` elementwise over float32 arrays, in parallel.

    Parameters
    ----------
    x, y : numpy.ndarray
        float32 arrays of one shape (any, read flattened; contiguous), as for
        :func:`axial_atan2_f32`.
    out : numpy.ndarray
        float32 array of the same size, written in place with the axial angles [rad] in
        [-pi/2, pi/2).

    """
    xf = x.reshape(-1)
    yf = y.reshape(-1)
    of = out.reshape(-1)
    for i in prange(xf.size):
        of[i] = axial_atan2_f32(xf[i], yf[i])
