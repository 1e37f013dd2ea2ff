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
The gather both disc methods run before their fits on mirror pairs.

With mirror pairs (:mod:`._mirror`) each trial axis is a short fit over the disc's pixels whose
invariant terms were compacted once. :func:`gather_chunk` selects the pixels of one chunk of the
view (valid, finite, in the disc ring, S(p) > 0), writes what both methods' fits read (the offset
from the principal point and taper S(p)) and leaves each kept pixel's values in a small table
(rows ``KEPT_*``), from which the method writes its own terms
(:func:`._sm_asm_kernels.band_gather`, :func:`._symmetry_kernels.ring_gather`)::

    scratch = gather_scratch()
    n = 0
    for o in range(0, view[0].size, GATHER_CHUNK):
        kept = gather_chunk(view, ring, mirror, own_dop2, o, scratch, g_uv, g_ts, n)
        for k in range(kept):
            usable, tp, q, rx, ry, rho, c2a, s2a = kept_pixel(scratch, k)
            ...  # the method's terms of gathered pixel n
            n += 1
"""

from __future__ import annotations

from numba import njit
import numpy as np

from ._disc import _gather_lanes, GATHER_CHUNK
from ._mirror import _bilinear0_pair, _grid_pos, _offset_mm

__all__ = ['gather_scratch', 'gather_chunk', 'kept_pixel', 'GATHER_CHUNK']

#: Rows of the kept pixels' table: usable (1.0: DoP >= min_dop, else 0.0), taper, the pair
#: weight's own factor q (Q(p), or DoP(p)^2 S(p) with ``own_dop2``), the ray's r_x, r_y and
#: hypot(r_x, r_y), cos 2a and sin 2a of the AoP.
KEPT_USABLE, KEPT_TAPER, KEPT_Q = 0, 1, 2
KEPT_RX, KEPT_RY, KEPT_RHO, KEPT_C2A, KEPT_S2A = 3, 4, 5, 6, 7
N_KEPT = 8


@njit(inline='always', cache=True)
def gather_scratch():  # pragma: no cover - compiled
    """Return the scratch arrays of :func:`gather_chunk` (one chunk's lanes and kept pixels)."""
    CH = GATHER_CHUNK
    return np.empty(CH, np.int8), np.empty(CH), np.empty((6, CH)), np.empty((N_KEPT, CH))


@njit(cache=True, nogil=True)
def gather_chunk(
    view, ring, mirror, own_dop2, o, scratch, g_uv, g_ts, n
):  # pragma: no cover - compiled
    """
    Gather the kept pixels of the chunk from view index ``o`` for the fits on mirror pairs.

    Parameters
    ----------
    view : tuple
        (aop, dop, valid, rays, xs, ys) of the view's pixels (``xs``, ``ys``: sensor px).
    ring : DiscRing
        The pixels the pass reads and the taper (:class:`._disc.DiscRing`).
    mirror : tuple
        (mg, mq, mp): the S and Q grids and the reflection parameters (:meth:`MirrorMap.at`).
    own_dop2 : bool
        The pair weight's own factor is DoP(p)^2 S(p) (the occlusion-only pair weights, fitted with
        Q = S) instead of Q(p).
    o : int
        The chunk's first view index (``GATHER_CHUNK`` pixels from it, fewer at the end).
    scratch : tuple
        :func:`gather_scratch`; out: the kept pixels' values (:func:`kept_pixel`).
    g_uv, g_ts : ndarray
        Out, from gathered pixel ``n`` on: the offset (u, v) mm from the principal point (2, N)
        and taper S(p) (N,).
    n : int
        Pixels gathered before this chunk.

    Returns
    -------
    int
        The chunk's kept pixels (valid, finite, in the ring and S(p) > 0), in view order.

    """
    aop, dop, valid, rays, xs, ys = view
    mg, mq, mp = mirror
    fl, tps, px, kept = scratch
    m = min(GATHER_CHUNK, aop.size - o)
    _gather_lanes(
        aop,
        dop,
        valid,
        rays,
        o,
        m,
        ring.min_dop,
        ring.rho_lo,
        ring.rho_max,
        ring.taper_frac,
        fl,
        tps,
        px,
    )
    k = 0
    for u in range(m):
        if not fl[u] & 1:  # not valid, finite and in the ring
            continue
        i = o + u
        r, c = _grid_pos(mp, xs[i], ys[i])
        s, q_own = _bilinear0_pair(mg, mq, r, c)  # S(p) and Q(p) from one position
        if not s > 0.0:
            continue
        tp = tps[u]
        p = px[0, u]
        g_uv[0, n + k], g_uv[1, n + k] = _offset_mm(mp, xs[i], ys[i])
        g_ts[n + k] = tp * s
        kept[KEPT_USABLE, k] = 1.0 if fl[u] & 2 else 0.0
        kept[KEPT_TAPER, k] = tp
        kept[KEPT_Q, k] = q_own if not own_dop2 else p * p * s
        kept[KEPT_RX, k] = px[1, u]
        kept[KEPT_RY, k] = px[2, u]
        kept[KEPT_RHO, k] = px[3, u]
        kept[KEPT_C2A, k] = px[4, u]
        kept[KEPT_S2A, k] = px[5, u]
        k += 1
    return k


@njit(inline='always', cache=True)
def kept_pixel(scratch, k):  # pragma: no cover - compiled
    """Return kept pixel k of the last chunk: (usable, taper, q, r_x, r_y, rho, cos 2a, sin 2a)."""
    kept = scratch[3]
    return (
        kept[KEPT_USABLE, k] != 0.0,
        kept[KEPT_TAPER, k],
        kept[KEPT_Q, k],
        kept[KEPT_RX, k],
        kept[KEPT_RY, k],
        kept[KEPT_RHO, k],
        kept[KEPT_C2A, k],
        kept[KEPT_S2A, k],
    )
