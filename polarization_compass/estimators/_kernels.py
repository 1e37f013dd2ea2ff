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
Compiled single pass of the least-squares estimators.

The pass (numba, cached) reads the observation as it is (float32 AoP/DoP/rays, bool validity),
skips unusable pixels without copying, lifts each AoP to its unit E-vector (the lift of
:func:`polarization_compass.conventions.evector_cam_from_aop`, written out inline; tests check both
agree) and accumulates, per block of pixels, ``M_b = sum w e e^T``, plus frame totals of the
noise-bias matrices ``B``, ``C`` and the sufficient statistics of the brightness regression.
Because every per-pixel first-order influence on the solution is a quadratic form ``-w (s.e)(c.e) =
-s^T (w e e^T) c``, the block sums of the influence are ``-s^T M_b c``: the uncertainty needs no
second full pass.

Speed: the full pass is float32 inside a run of pixels (float64 across runs), branch-free, with
``error_model="numpy"`` (no Python zero-division guard) so LLVM vectorises it; sine and cosine are
Taylor polynomials on the folded AoP (no SVML here; libm calls would dominate). The second-order
terms and the brightness statistics come from a sparse, evenly spread subsample.
"""

from __future__ import annotations

from functools import lru_cache
import math

from numba import njit
import numpy as np

from ..fastmath import sincos32_folded as _sincos32
from ..runtime import kernel_array

__all__ = [
    'sub_pass',
    'full_pass',
    'N_STATS',
    'sym3',
    'acc_sym',
    'acc_brightness',
]

_FM = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}  # no nnan/ninf: NaN tests must stay
# brightness sufficient statistics: n, sum I, sum I^2, sum r (3), sum I r (3), sum r r^T (6)
N_STATS = 15


@njit(inline='always', cache=True)
def acc_sym(tot, off, w, x, y, z):  # pragma: no cover - compiled
    """tot[off:off + 6] += w * (x, y, z)(x, y, z)^T, upper triangle (00 01 02 11 12 22)."""
    tot[off] += w * x * x
    tot[off + 1] += w * x * y
    tot[off + 2] += w * x * z
    tot[off + 3] += w * y * y
    tot[off + 4] += w * y * z
    tot[off + 5] += w * z * z


@njit(inline='always', cache=True)
def acc_brightness(tot, off, ival, rx, ry, rz):  # pragma: no cover - compiled
    """
    Accumulate the brightness sufficient statistics of one pixel.

    They go into tot[off:off + N_STATS]: n, sum I, sum I^2, sum r (3), sum I r (3), sum r r^T (6).
    """
    tot[off] += 1.0
    tot[off + 1] += ival
    tot[off + 2] += ival * ival
    tot[off + 3] += rx
    tot[off + 4] += ry
    tot[off + 5] += rz
    tot[off + 6] += ival * rx
    tot[off + 7] += ival * ry
    tot[off + 8] += ival * rz
    acc_sym(tot, off + 9, 1.0, rx, ry, rz)


@njit(fastmath=_FM, cache=True, nogil=True, error_model='numpy')
def _count_pass(aop, dop, valid, rays, min_dop, counts):  # pragma: no cover - compiled
    """
    Count usable, valid and valid non-finite pixels.

    counts: [0] usable pixels (the same test as :func:`_m_pass`), [1] valid pixels, [2] valid
    pixels with a non-finite value.
    """
    big = np.float32(1e6)
    md = np.float32(min_dop)
    n_ok = 0
    n_valid = 0
    n_bad = 0
    for i in range(aop.size):  # branch-free int32 counts: vectorises
        a = np.float32(aop[i])
        p = np.float32(dop[i])
        fin = (
            (abs(a) < big)
            & (abs(p) < big)
            & (abs(np.float32(rays[0, i])) < big)
            & (abs(np.float32(rays[1, i])) < big)
            & (abs(np.float32(rays[2, i])) < big)
        )
        v = valid[i]
        n_valid += np.int32(v)
        n_bad += np.int32(v & (fin ^ True))
        n_ok += np.int32(v & fin & (p >= md))
    counts[0] = n_ok
    counts[1] = n_valid
    counts[2] = n_bad


@njit(inline='always', fastmath=_FM, cache=True, error_model='numpy')
def _lift_pixel(a, p, rx, ry, rz, v_in, md, dop_weight):  # pragma: no cover - compiled
    """
    Lift one pixel of the full pass, branch-free.

    Returns (w, ex, ey, ez, usable, finite) with ``w e e^T`` its
    share of M (``e`` unnormalised, ``w`` = DoP^2 or 1 over |e|^2; 0 for an unusable pixel). A
    non-finite value zeroes the pixel's numbers (0 * inf would poison the block sum with NaN).
    """
    f0 = np.float32(0.0)
    f1 = np.float32(1.0)
    big = np.float32(1e6)
    fin = (abs(a) < big) & (abs(p) < big) & (abs(rx) < big) & (abs(ry) < big) & (abs(rz) < big)
    a = a if fin else f0
    p = p if fin else f0
    rx = rx if fin else f0
    ry = ry if fin else f0
    rz = rz if fin else f0
    sa, ca = _sincos32(a)
    q = rx * sa + ry * ca
    nn = rz * rz + q * q
    use = v_in & fin & (p >= md)
    ok = use & (nn > np.float32(1e-20))
    inv = f1 / (nn if ok else f1)
    w = ((p * p if dop_weight else f1) * inv) if ok else f0
    return w, rz * sa, rz * ca, -q, use, fin


@njit(fastmath=_FM, cache=True, nogil=True, error_model='numpy')
def _m_pass(
    aop, dop, valid, rays, seg_start, seg_end, seg_block, min_dop, dop_weight, block_m
):  # pragma: no cover - compiled
    """
    Accumulate per block ``M_b = sum w e e^T`` (float32 within a segment, float64 across).

    Branch-free inner loop without counters (selects; error_model numpy so division is not
    guarded): it vectorises.
    """
    f0 = np.float32(0.0)
    md = np.float32(min_dop)
    for k in range(seg_start.size):
        m0 = m1 = m2 = m3 = m4 = m5 = f0
        for i in range(seg_start[k], seg_end[k]):
            w, ex, ey, ez, _, _ = _lift_pixel(
                np.float32(aop[i]),
                np.float32(dop[i]),
                np.float32(rays[0, i]),
                np.float32(rays[1, i]),
                np.float32(rays[2, i]),
                valid[i],
                md,
                dop_weight,
            )
            m0 += w * ex * ex
            m1 += w * ex * ey
            m2 += w * ex * ez
            m3 += w * ey * ey
            m4 += w * ey * ez
            m5 += w * ez * ez
        bk = seg_block[k]
        block_m[bk, 0] += m0
        block_m[bk, 1] += m1
        block_m[bk, 2] += m2
        block_m[bk, 3] += m3
        block_m[bk, 4] += m4
        block_m[bk, 5] += m5


@njit(inline='always', fastmath=_FM, cache=True, error_model='numpy')
def _column_sums(acc, cpf, nx, out):  # pragma: no cover - compiled
    """
    Sum each of the first six rows of ``acc`` over parity-0 and parity-1 columns.

    ``out[c] = (sum over parity-0 columns, over parity-1 columns)`` in float64, exact enough that a
    row's share (the difference of two) keeps what the float32 column sums gained.
    """
    for c in range(6):
        ac = acc[c]
        t = 0.0
        t1 = 0.0
        for j in range(nx):
            v = np.float64(ac[j])
            t += v
            t1 += v * np.float64(cpf[j])
        out[c, 0] = t - t1
        out[c, 1] = t1


@njit(inline='always', fastmath=_FM, cache=True, error_model='numpy')
def _phase_rows(acc, cpf, nx, odd, cur, prev, odd_m):  # pragma: no cover - compiled
    """
    Take the share of the rows since the last reduction of :func:`_m_pass_grid`'s column sums.

    ``cur`` = the column sums so far (:func:`_column_sums`); when those rows were of parity 1
    (``odd``) their share ``cur - prev`` goes into ``odd_m``; ``prev`` becomes ``cur``.
    """
    _column_sums(acc, cpf, nx, cur)
    if odd:
        for c in range(6):
            for q in range(2):
                odd_m[c, q] += cur[c, q] - prev[c, q]
    for c in range(6):
        for q in range(2):
            prev[c, q] = cur[c, q]


@njit(inline='always', fastmath=_FM, cache=True, error_model='numpy')
def _block_row_sums(acc, nx, col_block, b0, block_m, n_ok, n_fin):  # pragma: no cover - compiled
    """
    Add one block row's per-column sums into ``block_m`` (from block ``b0``) and the counts.

    The same reduction order into ``block_m`` as without the phases; returns (n_ok, n_fin) plus
    the block row's usable and finite counts.
    """
    for j in range(nx):
        bk = b0 + col_block[j]
        for c in range(6):
            block_m[bk, c] += acc[c, j]
        n_ok += acc[6, j]
        n_fin += acc[7, j]
    return n_ok, n_fin


@njit(fastmath=_FM, cache=True, nogil=True, error_model='numpy')
def _m_pass_grid(
    aop,
    dop,
    valid,
    rays,
    off,
    nx,
    ny,
    col_block,
    row_block,
    n_block_cols,
    min_dop,
    dop_weight,
    block_m,
    counts,
    col_par,
    row_par,
    phase_m,
):  # pragma: no cover - compiled
    """
    Run :func:`_m_pass` and :func:`_count_pass` in one sweep over a row-major grid.

    The grid is ``ny`` x ``nx``, stored from flat index ``off``: column j is in block column
    ``col_block[j]``, row r in block row ``row_block[r]`` (non-decreasing). Each pixel's ``w e
    e^T`` goes into a per-column float32 accumulator over the rows of one block row, reduced into
    ``block_m`` (float64) once per block row: the inner loop runs along a whole row with no
    per-block reduction, so it vectorises (per-block runs of a few pixels did not).

    Counts: ``counts[0]`` += usable pixels, ``counts[1]`` += valid pixels whose values are all
    finite (the caller gets the non-finite ones from the valid count). They are per-column float32
    rows too (exact below 2^24 rows per block row): an integer counter, or a select on the bare
    validity flag, in this loop stops LLVM vectorising it (measured: 2x slower).

    Mosaic phases: ``phase_m[2 * row_par[r] + col_par[j]]`` += the pixel's ``w e e^T`` (the
    sensor row and column parities, 0 or 1, of the 2 x 2 polarizer mosaic). The pixel loop is
    untouched (psi does not change: ``block_m`` gets the same bits); the per-column float32 sums
    are reduced (float64, by column parity) before and after each row of parity 1, whose share is
    the difference, and at the end of the block row (the parity-0 rows' share is the rest; a block
    row of one parity, e.g. a superpixel grid's, is reduced only there): the phase sums add up to
    the block sums to float64 rounding.
    """
    f0 = np.float32(0.0)
    f1 = np.float32(1.0)
    md = np.float32(min_dop)
    acc = np.zeros((8, nx), np.float32)
    cpf = np.zeros(nx, np.float32)  # column parity as a 0/1 factor
    for j in range(nx):
        cpf[j] = f1 if col_par[j] == 1 else f0
    prev = np.zeros((6, 2))  # column sums so far in the block row, by column parity
    cur = np.zeros((6, 2))
    odd_m = np.zeros((6, 2))  # the block row's parity-1 rows, by column parity
    n_ok = 0.0
    n_fin = 0.0
    r = 0
    while r < ny:
        br = row_block[r]
        acc[:] = f0
        prev[:] = 0.0
        odd_m[:] = 0.0
        n_odd = 0  # parity-1 rows of the block row: none or all need no per-row sums
        r_end = r
        while r_end < ny and row_block[r_end] == br:
            n_odd += row_par[r_end]
            r_end += 1
        mixed = 0 < n_odd < r_end - r
        while r < ny and row_block[r] == br:
            odd = row_par[r] == 1
            base = off + r * nx
            a0 = acc[0]
            a1 = acc[1]
            a2 = acc[2]
            a3 = acc[3]
            a4 = acc[4]
            a5 = acc[5]
            a6 = acc[6]
            a7 = acc[7]
            # row slices, indexed by the loop counter: with a computed index (base + j) numba's
            # negative-index wrap-around made LLVM load every lane separately
            ar = aop[base : base + nx]
            pr = dop[base : base + nx]
            vr = valid[base : base + nx]
            xr = rays[0, base : base + nx]
            yr = rays[1, base : base + nx]
            zr = rays[2, base : base + nx]
            for j in range(nx):
                v_in = vr[j]
                w, ex, ey, ez, use, fin = _lift_pixel(
                    np.float32(ar[j]),
                    np.float32(pr[j]),
                    np.float32(xr[j]),
                    np.float32(yr[j]),
                    np.float32(zr[j]),
                    v_in,
                    md,
                    dop_weight,
                )
                a0[j] += w * ex * ex
                a1[j] += w * ex * ey
                a2[j] += w * ex * ez
                a3[j] += w * ey * ey
                a4[j] += w * ey * ez
                a5[j] += w * ez * ez
                a6[j] += f1 if use else f0
                a7[j] += f1 if (v_in & fin) else f0
            r += 1
            last = r >= ny or row_block[r] != br
            if last or (mixed and (odd or row_par[r] == 1)):  # before or after a parity-1 row
                _phase_rows(acc, cpf, nx, odd, cur, prev, odd_m)
        for c in range(6):  # prev: the block row's totals
            for q in range(2):
                phase_m[2 + q, c] += odd_m[c, q]
                phase_m[q, c] += prev[c, q] - odd_m[c, q]
        n_ok, n_fin = _block_row_sums(acc, nx, col_block, br * n_block_cols, block_m, n_ok, n_fin)
    counts[0] += np.int64(n_ok)
    counts[1] += np.int64(n_fin)


@njit(fastmath=_FM, cache=True, nogil=True, error_model='numpy')
def _bc_pass(
    aop, dop, valid, rays, inten, has_inten, starts, run, min_dop, dop_weight, var_mode, tot
):  # pragma: no cover
    """
    Accumulate B, C, M and brightness statistics over runs of pixels.

    Runs of ``run`` pixels from each of ``starts``: ``tot`` [0:6] B, [6:12] C, [12:18] M (of the
    same pixels, to scale), [18:33] brightness statistics (n, sum I, sum I^2, sum r, sum I r, sum r
    r^T).
    """
    n = aop.size
    for i0 in starts:
        for i in range(i0, min(i0 + run, n)):  # contiguous runs keep the cache warm
            a = np.float64(aop[i])
            p = np.float64(dop[i])
            rx = np.float64(rays[0, i])
            ry = np.float64(rays[1, i])
            rz = np.float64(rays[2, i])
            fin = (
                (abs(a) < 1e6)
                & (abs(p) < 1e6)
                & (abs(rx) < 1e6)
                & (abs(ry) < 1e6)
                & (abs(rz) < 1e6)
            )
            if not (valid[i] and fin and p >= min_dop):
                continue
            sa, ca = _sincos32(np.float32(a))
            sa = np.float64(sa)
            ca = np.float64(ca)
            q = rx * sa + ry * ca
            nn = rz * rz + q * q
            if not nn > 1e-20:
                continue
            inv = 1.0 / math.sqrt(nn)
            ex = rz * sa * inv
            ey = rz * ca * inv
            ez = -q * inv
            tx = ry * ez - rz * ey  # t = r x e: where e turns when the AoP changes
            ty = rz * ex - rx * ez
            tz = rx * ey - ry * ex
            g = -rz / nn  # d theta / d AoP
            gp = 2.0 * rz * q * (rx * ca - ry * sa) / (nn * nn)
            pp = max(p * p, 1e-6)
            w = pp if dop_weight else 1.0
            if var_mode == 0:
                v = 1.0
            elif var_mode == 1 or not has_inten:
                v = 1.0 / pp
            else:
                v = 1.0 / (pp * max(np.float64(inten[i]), 1e-9))
            wv = w * v
            k2 = wv * g * g
            h = 0.5 * wv * gp
            tot[0] += k2 * (tx * tx - ex * ex) + 2.0 * h * ex * tx
            tot[1] += k2 * (tx * ty - ex * ey) + h * (ex * ty + tx * ey)
            tot[2] += k2 * (tx * tz - ex * ez) + h * (ex * tz + tx * ez)
            tot[3] += k2 * (ty * ty - ey * ey) + 2.0 * h * ey * ty
            tot[4] += k2 * (ty * tz - ey * ez) + h * (ey * tz + ty * ez)
            tot[5] += k2 * (tz * tz - ez * ez) + 2.0 * h * ez * tz
            acc_sym(tot, 6, k2, tx, ty, tz)
            acc_sym(tot, 12, w, ex, ey, ez)
            if has_inten:
                ii = np.float64(inten[i])
                if abs(ii) < 1e30:
                    acc_brightness(tot, 18, ii, rx, ry, rz)


_SYM = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])


def sym3(u) -> np.ndarray:
    """3x3 symmetric matrix from its upper triangle (00 01 02 11 12 22), any leading axes."""
    u = np.asarray(u)
    return u[..., _SYM].reshape(u.shape[:-1] + (3, 3))


_RUN = 64


def _reads_every_pixel(n: int, sub_pixels: int) -> bool:
    """
    Tell whether a subsample of about ``sub_pixels`` from ``n`` pixels is all of them.

    The subsample of :func:`_run_starts`.
    """
    return n <= 2 * sub_pixels


@lru_cache(maxsize=64)
def _run_starts(n: int, sub_pixels: int) -> np.ndarray:
    """
    Return the starts of the subsample's runs.

    The runs cover every pixel when n is small, else there are about sub_pixels / 64 runs at
    golden-ratio (low-discrepancy) positions, sorted. Evenly spaced runs would lock onto the image
    rows (a period that is a multiple of the row length samples one vertical strip).
    """
    if _reads_every_pixel(n, sub_pixels):
        out = np.arange(0, n, _RUN, dtype=np.int64)
    else:
        k = max(1, sub_pixels // _RUN)
        frac = np.mod(0.5 + np.arange(k) * 0.6180339887498949, 1.0)
        out = np.unique(np.floor(frac * (n - _RUN)).astype(np.int64))
    out.setflags(write=False)  # cached, and one argument type of _bc_pass either way
    return out


def sub_pass(
    aop,
    dop,
    valid,
    rays,
    intensity,
    min_dop: float,
    weight_mode: int,
    var_mode: int,
    sub_pixels: int = 16384,
):
    """
    Second-order and brightness sums over about ``sub_pixels`` spread-out pixels (runs of 64).

    ``weight_mode`` 0 uniform, 1 DoP^2; ``var_mode`` (relative AoP noise variance v of a pixel) 0
    uniform, 1 1/DoP^2, 2 1/(DoP^2 I). Returns dict of 3x3 ``M`` (= sum w e e^T), ``B`` (noise bias
    of M per unit variance), ``C`` (expected residual sum per unit variance: s^T C s), ``stats``
    (brightness, or None) and ``every_pixel`` (the view was small enough to read whole: a larger
    ``sub_pixels`` reads the same).
    """
    has_i = intensity is not None
    inten = intensity if has_i else np.zeros(1, np.float32)
    tot = np.zeros(33)
    n = int(aop.size)
    _bc_pass(
        aop,
        dop,
        valid,
        kernel_array(rays),
        inten,
        has_i,
        _run_starts(n, int(sub_pixels)),
        _RUN,
        float(min_dop),
        bool(weight_mode),
        int(var_mode),
        tot,
    )
    return {
        'M': sym3(tot[12:18]),
        'B': sym3(tot[0:6]),
        'C': sym3(tot[6:12]),
        'stats': tot[18:33].copy() if has_i else None,
        'every_pixel': _reads_every_pixel(n, int(sub_pixels)),
    }


def full_pass(
    aop, dop, valid, rays, segments, min_dop: float, weight_mode: int, grids=None, parities=None
):
    """
    Per-block ``M_b = sum w e e^T`` over every usable pixel, and the pixel counts.

    ``segments`` = (start, end, block, n_blocks): runs of pixels [start, end) of block ``block``.
    ``grids``: the same pixels as regular grids (:func:`grid_layout`), or None; when given, the
    row-wise kernel runs instead of the per-segment one (the same block sums, numbered differently;
    faster). Returns dict: ``block_m`` (G, 3, 3), ``block_w`` (G,) block weights (traces), ``n``
    usable pixels, ``nonfinite`` (valid pixels with a NaN/inf value), ``considered`` (valid
    pixels), ``phase_m`` (4, 3, 3): ``sum w e e^T`` per mosaic phase ``2 * (row parity) + (column
    parity)`` when ``grids`` and ``parities`` (:func:`grid_parities` of the grids) are given, else
    None.
    """
    start, end, block, n_blocks = segments
    rays = kernel_array(rays)  # the kernels' one form of it (a free view when C-contiguous)
    if grids is not None:
        grids, n_blocks = grids
    block_m = np.zeros((n_blocks, 6))
    phase_m = np.zeros((4, 6))
    counts = np.zeros(3, np.int64)
    if grids is not None:
        for gi, (off, col_block, row_block, n_block_cols) in enumerate(grids):
            if parities is not None:
                col_par, row_par = parities[gi]
            else:
                # read-only like grid_parities': one argument type of the kernel
                col_par = kernel_array(np.zeros(col_block.size, np.int64))
                row_par = kernel_array(np.zeros(row_block.size, np.int64))
            _m_pass_grid(
                aop,
                dop,
                valid,
                rays,
                off,
                col_block.size,
                row_block.size,
                col_block,
                row_block,
                n_block_cols,
                float(min_dop),
                bool(weight_mode),
                block_m,
                counts,
                col_par,
                row_par,
                phase_m,
            )
        n_valid = int(np.count_nonzero(valid))
        counts[2] = n_valid - counts[1]  # valid pixels with a non-finite value
        counts[1] = n_valid
    else:
        _count_pass(aop, dop, valid, rays, float(min_dop), counts)
        _m_pass(
            aop,
            dop,
            valid,
            rays,
            kernel_array(start, np.int64),
            kernel_array(end, np.int64),
            kernel_array(block, np.int64),
            float(min_dop),
            bool(weight_mode),
            block_m,
        )
    return {
        'block_m': sym3(block_m),
        'block_w': block_m[:, 0] + block_m[:, 3] + block_m[:, 5],
        'n': int(counts[0]),
        'nonfinite': int(counts[2]),
        'considered': int(counts[1]),
        'phase_m': sym3(phase_m) if (grids is not None and parities is not None) else None,
    }
