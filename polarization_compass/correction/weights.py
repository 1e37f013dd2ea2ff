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
Interpolation weights along one axis of the error map.

Keys' cubic convolution (a = -1/2) with its cubic boundary rule, multilinear on non-uniform or
short axes, and the periodic yaw axis.
"""

from __future__ import annotations

import numpy as np


def _is_uniform(axis: np.ndarray) -> bool:
    if axis.size < 3:
        return True
    d = np.diff(axis)
    return bool(np.all(np.abs(d - d[0]) <= 1e-9 * max(1.0, abs(d[0]))))


def _keys(t):
    """
    Return Keys (a = -1/2) cubic convolution weights of four nodes at fraction t.

    The nodes are i-1, i, i+1, i+2; t is in [0, 1].
    """
    t2 = t * t
    t3 = t2 * t
    return np.stack(
        [
            -0.5 * t3 + t2 - 0.5 * t,
            1.5 * t3 - 2.5 * t2 + 1.0,
            -1.5 * t3 + 2.0 * t2 + 0.5 * t,
            0.5 * t3 - 0.5 * t2,
        ],
        -1,
    )


def _keys_dt(t):
    """Return the derivatives d/dt of the Keys (a = -1/2) weights of :func:`_keys` at t."""
    t2 = t * t
    return np.stack(
        [
            -1.5 * t2 + 2.0 * t - 0.5,
            4.5 * t2 - 5.0 * t,
            -4.5 * t2 + 4.0 * t + 0.5,
            1.5 * t2 - t,
        ],
        -1,
    )


#: How the four Keys weights of stencil nodes i-1..i+2 land on the 4-node window
#: ``start..start+3``: inside the axis the window is the stencil (identity); at the low end (window
#: shifted up by one) the ghost node f(-1) = 3 f(0) - 3 f(1) + f(2) (Keys' cubic boundary rule);
#: mirrored at the high end.
_KEYS_BOUNDARY = np.array(
    [
        [
            [3.0, -3.0, 1.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],  # off = -1
        np.eye(4),  # off = 0
        [
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, -3.0, 3.0],
        ],  # off = +1
    ]
)


def _axis_weights(axis: np.ndarray, x: np.ndarray, order: int, deriv: bool = False):
    """
    Return node indices and weights of points on a non-periodic axis.

    Node indices (N, k) and weights (N, k) of points x on a non-periodic axis, and inside (N,)
    bool. With ``deriv`` the weights are their derivatives d/dx [1/axis unit], so that the sum of
    weights times node values is the interpolant's derivative (0 on a one-node axis).

    Outside the axis the indices are clipped and ``inside`` is False (the caller rejects the
    point).
    """
    x = np.asarray(x, dtype=float)
    n = axis.size
    tol = 1e-9 * max(1.0, float(np.max(np.abs(axis))))
    inside = (x >= axis[0] - tol) & (x <= axis[-1] + tol)
    if n == 1:
        w1 = np.zeros(x.shape + (1,)) if deriv else np.ones(x.shape + (1,))
        return np.zeros(x.shape + (1,), dtype=np.intp), w1, inside
    xc = np.clip(x, axis[0], axis[-1])
    i = np.clip(np.searchsorted(axis, xc, side='right') - 1, 0, n - 2)
    h = axis[i + 1] - axis[i]
    t = np.clip((xc - axis[i]) / h, 0.0, 1.0)
    if order == 1 or n < 4 or not _is_uniform(axis):
        if deriv:
            return np.stack([i, i + 1], -1), np.stack([-1.0 / h, 1.0 / h], -1), inside
        return np.stack([i, i + 1], -1), np.stack([1.0 - t, t], -1), inside
    w = _keys_dt(t) / h[..., None] if deriv else _keys(t)
    start = np.clip(i - 1, 0, n - 4)
    off = (i - 1) - start  # -1 at the low end, +1 at the high end, else 0
    W = np.einsum('...k,...kj->...j', w, _KEYS_BOUNDARY[off + 1])
    return start[..., None] + np.arange(4), W, inside


def _yaw_weights(y0: float, step: float, n: int, psi: np.ndarray, order: int, deriv: bool = False):
    """
    Return indices and weights on the periodic yaw axis ``y0 + step * k`` (n * step = 360).

    With ``deriv`` the weights are their derivatives d/dpsi [1/deg].
    """
    u = np.mod(np.asarray(psi, dtype=float) - y0, 360.0) / step
    i = np.floor(u).astype(np.intp)
    t = np.clip(u - i, 0.0, 1.0)
    i = np.mod(i, n)
    if order == 1 or n < 4:
        if deriv:
            d = np.full(t.shape, 1.0 / step)
            return np.stack([i, (i + 1) % n], -1), np.stack([-d, d], -1)
        return np.stack([i, (i + 1) % n], -1), np.stack([1.0 - t, t], -1)
    w = _keys_dt(t) / step if deriv else _keys(t)
    return np.mod(np.stack([i - 1, i, i + 1, i + 2], -1), n), w
