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
Pixel blocks of the least-squares pass: the segments and grid layouts that number its blocks.

A view's pixels are grouped in square blocks of ``block_px`` sensor pixels (the cluster-robust
sigma's clusters, :mod:`._kernels`): :func:`grid_segments` and :func:`list_segments` cut regular
grids and pixel lists into runs of one block, :func:`grid_layout` and :func:`block_indices` number
the blocks of grids stored one after the other, :func:`grid_parities` gives the mosaic phase of
their columns and rows. Plain numpy, cached per camera.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ['grid_segments', 'grid_layout', 'grid_parities', 'block_indices', 'list_segments']


@lru_cache(maxsize=64)
def grid_parities(keys: tuple) -> tuple:
    """
    Return the mosaic parities of regular grids' columns and rows.

    For each grid key ``((x0, dx, nx), (y0, dy, ny))`` (sensor pixels), the parity, 0 or 1, of the
    sensor column ``floor(x)`` of every column and of the sensor row ``floor(y)`` of every row: the
    place of a pixel in the 2 x 2 polarizer mosaic (relabelled alike for any origin). A superpixel
    grid (2 px apart) has one parity per axis. Cached.
    """
    out = []
    for (x0, dx, nx), (y0, dy, ny) in keys:
        cp = np.floor(x0 + dx * np.arange(nx)).astype(np.int64) % 2
        rp = np.floor(y0 + dy * np.arange(ny)).astype(np.int64) % 2
        cp.setflags(write=False)
        rp.setflags(write=False)
        out.append((cp, rp))
    return tuple(out)


@lru_cache(maxsize=64)
def grid_segments(x_key: tuple, y_key: tuple, block_px: int):
    """
    Return the segments of a row-major 2-D grid, one run per (row, block column).

    The grid's column coordinates are ``x0 + dx * arange(nx)`` and its row coordinates ``y0 + dy *
    arange(ny)`` (keys ``(x0, dx, nx)``, sensor pixels). Cached (a camera that does not change
    costs nothing).
    """
    x0, dx, nx = x_key
    y0, dy, ny = y_key
    xs = x0 + dx * np.arange(nx)
    ys = y0 + dy * np.arange(ny)
    bc = np.floor((xs - 0.5) / block_px).astype(np.int64)
    br = np.floor((ys - 0.5) / block_px).astype(np.int64)
    bc -= bc.min()
    br -= br.min()
    change = np.nonzero(np.diff(bc))[0] + 1
    cs = np.concatenate([[0], change])
    ce = np.concatenate([change, [nx]])
    K = cs.size
    start = (np.arange(ny)[:, None] * nx + cs[None, :]).reshape(-1)
    end = (np.arange(ny)[:, None] * nx + ce[None, :]).reshape(-1)
    blk = (br[:, None] * K + np.arange(K)[None, :]).reshape(-1)
    n_blocks = int((br.max() + 1) * K)
    out = (start.astype(np.int64), end.astype(np.int64), blk.astype(np.int64), n_blocks)
    for a in out[:3]:
        a.setflags(write=False)
    return out


def block_indices(keys: tuple, block_px: int):
    """
    Return the block column of every column and the block row of every row of grids.

    The grids are regular, with keys ``((x0, dx, nx), (y0, dy, ny))`` (sensor pixels; blocks of
    ``block_px`` sensor pixels); the blocks are numbered from 0 alike in every grid. Returns
    (column indices per grid, row indices per grid, block columns K, block rows R).
    """
    axes = [
        (k[0][0] + k[0][1] * np.arange(k[0][2]), k[1][0] + k[1][1] * np.arange(k[1][2]))
        for k in keys
    ]
    bcs = [np.floor((xg - 0.5) / block_px).astype(np.int64) for xg, _ in axes]
    brs = [np.floor((yg - 0.5) / block_px).astype(np.int64) for _, yg in axes]
    c0 = min(int(b.min()) for b in bcs)
    r0 = min(int(b.min()) for b in brs)
    K = max(int(b.max()) for b in bcs) - c0 + 1
    R = max(int(b.max()) for b in brs) - r0 + 1
    return [b - c0 for b in bcs], [b - r0 for b in brs], K, R


@lru_cache(maxsize=64)
def grid_layout(keys: tuple, block_px: int) -> tuple:
    """
    Lay out regular grids stored one after the other for :func:`._kernels._m_pass_grid`.

    The grids are row-major, with keys ``((x0, dx, nx), (y0, dy, ny))`` in sensor pixels. Returns
    ``(pieces, n_blocks)`` with ``(offset, col_block, row_block, n_block_cols)`` per grid, blocks
    of ``block_px`` sensor pixels numbered ``row * n_block_cols + col`` alike in every grid (the
    same partition as :func:`grid_segments` and ``subgrid_segments``; numbers may skip blocks no
    pixel falls in). None when a grid's rows are not in block-row order. Cached.
    """
    bcs, brs, K, R = block_indices(keys, block_px)
    out, off = [], 0
    for bc, br in zip(bcs, brs):
        if np.any(np.diff(br) < 0):
            return None  # rows not in block-row order: the per-segment kernel handles it
        bc.setflags(write=False)
        br.setflags(write=False)
        out.append((off, bc, br, K))
        off += bc.size * br.size
    return tuple(out), int(R * K)


def list_segments(x_px, y_px, block_px: int):
    """
    Return the pixel order and segments for a pixel list, sorted by block.

    Returns ``(order, segments)``: ``order`` sorts the pixels by block, the segments are runs of
    one block in that order, as :func:`grid_segments` gives them.
    """
    bx = np.floor((np.asarray(x_px, dtype=float) - 0.5) / block_px).astype(np.int64)
    by = np.floor((np.asarray(y_px, dtype=float) - 0.5) / block_px).astype(np.int64)
    bx -= bx.min() if bx.size else 0
    by -= by.min() if by.size else 0
    key = by * (int(bx.max()) + 1 if bx.size else 1) + bx
    order = np.argsort(key, kind='stable')
    ks = key[order]
    if ks.size == 0:
        return order, (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), 0)
    change = np.nonzero(np.diff(ks))[0] + 1
    start = np.concatenate([[0], change]).astype(np.int64)
    end = np.concatenate([change, [ks.size]]).astype(np.int64)
    uniq, blk = np.unique(ks[start], return_inverse=True)
    blk = blk.astype(np.int64)
    for a in (start, end, blk):
        a.setflags(write=False)  # read-only like grid_segments': one argument type of the kernels
    return order, (start, end, blk, int(uniq.size))
