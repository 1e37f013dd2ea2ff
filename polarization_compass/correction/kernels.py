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
Compiled kernels of the corrector: per query, the error curve over the yaw nodes and its inversion.

One heading in numpy cost ~8 ms of call overhead (60 bisection steps, 64 stencil terms); the same
algorithm compiled costs microseconds, which matters for a node correcting every frame.
"""

from __future__ import annotations

from numba import njit
import numpy as np

from ..conventions import wrap_180_deg_float


# --------------------------------------------------------------------------------------------
# Compiled kernels: per query, the error curve over the yaw nodes and the 1-D inversion. One
# heading in numpy cost ~8 ms of call overhead (60 bisection steps, 64 stencil terms); the same
# algorithm compiled costs microseconds, which matters for a node correcting every frame.
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _accumulate_curves(E, V, ia, wa, ip, wp, ir, wr, ok):  # pragma: no cover - compiled
    """
    Tensor-product interpolation of the error curves: out[q, y] = sum w_a w_p w_r E[a, y, p, r].

    A node without a valid estimate (any yaw) and a non-zero weight makes query q not ok (in
    place).
    """
    N = ia.shape[0]
    Y = E.shape[1]
    out = np.zeros((N, Y))
    for q in range(N):
        for a in range(ia.shape[1]):
            for b in range(ip.shape[1]):
                for c in range(ir.shape[1]):
                    w = wa[q, a] * wp[q, b] * wr[q, c]
                    A, P, R = ia[q, a], ip[q, b], ir[q, c]
                    good = True
                    for y in range(Y):
                        if not V[A, y, P, R]:
                            good = False
                        v = E[A, y, P, R]
                        if np.isfinite(v):
                            out[q, y] += w * v
                    if not good and w != 0.0:
                        ok[q] = False
    return out


#: :func:`~polarization_compass.conventions.wrap_180_deg_float` compiled for the kernels below.
_wrap180 = njit(inline='always', cache=True)(wrap_180_deg_float)


@njit(inline='always', cache=True)
def _curve_at(curve, q, psi, yaw0, step, n, cubic):  # pragma: no cover - compiled
    """
    Return the error curve of query q at yaw psi (periodic).

    Keys cubic or linear interpolation, as :func:`_yaw_weights`.
    """
    u = np.mod(psi - yaw0, 360.0) / step
    i = int(np.floor(u))
    t = min(max(u - i, 0.0), 1.0)
    i = i % n
    if not cubic:
        return curve[q, i] * (1.0 - t) + curve[q, (i + 1) % n] * t
    t2 = t * t
    t3 = t2 * t
    return (
        curve[q, (i - 1) % n] * (-0.5 * t3 + t2 - 0.5 * t)
        + curve[q, i] * (1.5 * t3 - 2.5 * t2 + 1.0)
        + curve[q, (i + 1) % n] * (-1.5 * t3 + 2.0 * t2 + 0.5 * t)
        + curve[q, (i + 2) % n] * (0.5 * t3 - 0.5 * t2)
    )


@njit(cache=True, nogil=True)
def _invert_kernel(
    curve, ok, meas, yaw0, step, n, cubic, u, max_roots, invert
):  # pragma: no cover - compiled
    """
    Invert the error curve per query: subtract estimate and refined roots.

    Per query: ``sub`` (the subtract estimate), the roots of f(u) = u + e(meas + u) on the sample
    grid ``u`` (sign changes, exact zeros), each refined by 60 bisection steps, as yaws wrapped to
    (-180, 180] (``cand``, NaN-padded, first ``max_roots``), their count, and the root nearest
    ``sub`` (``psi``). With ``invert`` False only ``sub`` is computed.
    """
    N = meas.shape[0]
    S = u.shape[0]
    sub = np.zeros(N)
    psi = np.zeros(N)
    n_roots = np.zeros(N, dtype=np.int64)
    cand = np.full((N, max_roots), np.nan)
    f = np.empty(S)
    for q in range(N):
        sub[q] = _wrap180(meas[q] - _curve_at(curve, q, meas[q], yaw0, step, n, cubic))
        if not (ok[q] and invert):
            continue
        for k in range(S):
            f[k] = u[k] + _curve_at(curve, q, meas[q] + u[k], yaw0, step, n, cubic)
        best = np.inf
        for k in range(S - 1):
            zero = f[k] == 0.0
            if not (zero or np.sign(f[k]) * np.sign(f[k + 1]) < 0):
                continue
            if zero:
                root = u[k]
            else:
                lo, hi, flo = u[k], u[k + 1], f[k]
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    fm = mid + _curve_at(curve, q, meas[q] + mid, yaw0, step, n, cubic)
                    if np.sign(fm) == np.sign(flo):
                        lo, flo = mid, fm
                    else:
                        hi = mid
                root = 0.5 * (lo + hi)
            c = _wrap180(meas[q] + root)
            if n_roots[q] < max_roots:
                cand[q, n_roots[q]] = c
            n_roots[q] += 1
            d = abs(_wrap180(c - sub[q]))
            if d < best:
                best = d
                psi[q] = c
    return sub, psi, n_roots, cand
