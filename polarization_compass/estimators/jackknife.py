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
Jackknife sigmas of a least-squares sun heading: delete a sector of blocks, or a mosaic phase.

The cluster-robust sigma over small blocks misses errors correlated at larger scales (the IFOV
error of a DoFP sensor at soft cloud edges). :func:`jackknife_sigma_rad` refits the sun with each
of :data:`JACKKNIFE_GROUPS` angular sectors of blocks left out, :func:`phase_jackknife_sigma_rad`
with each of the four mosaic phases left out, both from the block sums of the pixel pass (no pixel
read again); :func:`jackknife_exceeds` tells whether such a sigma is significantly larger than the
cluster-robust one.
"""

from __future__ import annotations

from functools import lru_cache
import math

from numba import njit
import numpy as np

from ._block_layout import block_indices
from ..conventions import wrap_180_deg_float
from ..runtime import kernel_array

__all__ = [
    'JACKKNIFE_GROUPS',
    'JACKKNIFE_Z',
    'jackknife_exceeds',
    'jackknife_groups',
    'jackknife_sigma_rad',
    'phase_jackknife_sigma_rad',
]


#: Angular sectors of the delete-a-group jackknife sigma (:func:`jackknife_sigma_rad`).
JACKKNIFE_GROUPS = 16
#: One-sided normal quantile of the test that replaces the cluster-robust sigma by the jackknife's
#: (:func:`jackknife_exceeds`): 1.645, a 5 % test.
JACKKNIFE_Z = 1.645


def jackknife_exceeds(sigma_jk: float, sigma_cr: float, n_groups: int, z: float = JACKKNIFE_Z):
    """
    Tell whether a jackknife sigma is significantly larger than the cluster-robust sigma.

    With ``G`` groups, ``(G - 1) sigma_jk^2 / sigma^2`` is about chi-square with ``G - 1`` degrees
    of freedom when the groups are independent; the cluster-robust sigma over many small blocks is
    taken as ``sigma``. True when ``sigma_jk^2 / sigma_cr^2`` exceeds the chi-square quantile over
    its degrees of freedom, by the Wilson-Hilferty cube-root approximation ``(1 - 2 / (9 nu) + z
    sqrt(2 / (9 nu)))^3`` (``nu = G - 1``; 1.666 at ``G = 16`` and z = 1.645, the exact 95 %
    quantile 1.666). Then the blocks miss an error correlated at the groups' scale and the
    jackknife is the sigma; otherwise the cluster-robust sigma (the larger of the two always would
    over-state an honest sigma by the jackknife's own scatter: mean err^2 / sigma^2 0.64-0.8
    instead of 1 on independent noise).

    Parameters
    ----------
    sigma_jk, sigma_cr : float
        The jackknife and the cluster-robust sigma (same unit).
    n_groups : int
        Groups of the jackknife (>= 2).
    z : float
        One-sided standard-normal quantile of the test.

    Returns
    -------
    bool
        True when the jackknife sigma is significantly larger.

    References
    ----------
    .. [1] E. B. Wilson and M. M. Hilferty, "The distribution of chi-square", Proc. Natl. Acad.
       Sci. USA 17(12), 684-688 (1931).

    """
    nu = float(n_groups - 1)
    q = (1.0 - 2.0 / (9.0 * nu) + z * math.sqrt(2.0 / (9.0 * nu))) ** 3
    return sigma_jk * sigma_jk > q * sigma_cr * sigma_cr


@lru_cache(maxsize=64)
def _grid_block_centres_px(keys: tuple, block_px: int, n_blocks: int):
    """
    Return the centres (x, y) [sensor px] of regular grids' blocks, numbered as the pass does.

    Blocks are numbered ``row * K + col`` from the first occupied block (``block_indices``); None
    when the pass numbered them otherwise (``n_blocks != R * K``). Cached per camera geometry.
    """
    _, _, K, R = block_indices(keys, block_px)
    if n_blocks != R * K:
        return None
    c0 = min(math.floor((k[0][0] - 0.5) / block_px) for k in keys)
    r0 = min(math.floor((k[1][0] - 0.5) / block_px) for k in keys)
    b = np.arange(n_blocks)
    xc = (c0 + b % K + 0.5) * block_px + 0.5
    yc = (r0 + b // K + 0.5) * block_px + 0.5
    xc.setflags(write=False)
    yc.setflags(write=False)
    return xc, yc


def _block_centres_px(view, block_px: int, n_blocks: int):
    """
    Return the centres (x, y) [sensor px] of the view's cluster-robust blocks, or None.

    The blocks of :func:`._common.view_segments` (``block_px`` sensor pixels square) in the pass's
    numbering: regular grids from their keys (cached), a pixel list from its coordinates (the
    sorted occupied block keys of ``list_segments``).
    """
    keys = (view.grid,) if view.grid is not None else view.subgrids
    if keys is not None:
        return _grid_block_centres_px(tuple(keys), int(block_px), int(n_blocks))
    bx = np.floor((np.asarray(view.x_px, dtype=float) - 0.5) / block_px).astype(np.int64)
    by = np.floor((np.asarray(view.y_px, dtype=float) - 0.5) / block_px).astype(np.int64)
    if bx.size == 0:
        return None
    bx0, by0 = int(bx.min()), int(by.min())
    width = int(bx.max()) - bx0 + 1
    uniq = np.unique((by - by0) * width + (bx - bx0))
    if uniq.size != n_blocks:
        return None
    xc = (bx0 + uniq % width + 0.5) * block_px + 0.5
    return xc, (by0 + uniq // width + 0.5) * block_px + 0.5


def jackknife_groups(xc_px, yc_px, block_w, n_groups: int = JACKKNIFE_GROUPS) -> np.ndarray:
    """
    Assign blocks to the angular sectors of the delete-a-group jackknife.

    ``n_groups`` equal angular sectors around the weight centroid of the used blocks (a sky disc
    or a rectangle about the principal point: roughly equal shares of the weight); -1 for a block
    without weight.

    Parameters
    ----------
    xc_px, yc_px : array_like
        Block centres [sensor px], (G,).
    block_w : array_like
        Block weights (traces of the block sums of ``w e e^T``), (G,).
    n_groups : int
        Number of sectors.

    Returns
    -------
    numpy.ndarray
        Sector of each block, int64 (G,), in ``[0, n_groups)`` or -1.

    """
    w = np.ascontiguousarray(block_w, dtype=np.float64)
    out = np.full(w.size, -1, dtype=np.int64)
    _sectors(
        kernel_array(xc_px, np.float64),
        kernel_array(yc_px, np.float64),
        w,
        int(n_groups),
        out,
    )
    return out


@njit(cache=True, nogil=True)
def _sectors(xc, yc, w, n_groups, out):  # pragma: no cover - compiled
    """Fill ``out`` with the sector of each weighted block (:func:`jackknife_groups`)."""
    sw = sx = sy = 0.0
    for b in range(w.size):
        if w[b] > 0:
            sw += w[b]
            sx += w[b] * xc[b]
            sy += w[b] * yc[b]
    if not sw > 0:
        return
    cx, cy = sx / sw, sy / sw
    for b in range(w.size):
        if w[b] > 0:
            ang = math.atan2(yc[b] - cy, xc[b] - cx)  # [-pi, pi]
            sec = int(math.floor((ang + math.pi) / (2.0 * math.pi) * n_groups))
            out[b] = min(max(sec, 0), n_groups - 1)


@njit(cache=True, nogil=True)
def _leave_group_out_psi(
    M, B, block_m, groups, n_groups, s, R, sigma0_sq
):  # pragma: no cover - compiled
    """
    Return the leave-one-group-out headings [rad] and each group's state (0 empty, 1 ok, 2 failed).

    One sweep over the blocks sums each group, then one eigen-solve per group of ``M`` minus that
    group, debiased by ``sigma0_sq`` times ``B`` scaled by its weight share; the sun's sign along
    ``s``, psi = -atan2 of the first two components of ``R s_(-g)``.
    """
    gsum = np.zeros((n_groups, 3, 3))
    present = np.zeros(n_groups, np.int64)
    for b in range(block_m.shape[0]):
        g = groups[b]
        if g >= 0:
            present[g] = 1
            for i in range(3):
                for j in range(3):
                    gsum[g, i, j] += block_m[b, i, j]
    tr = M[0, 0] + M[1, 1] + M[2, 2]
    psi = np.zeros(n_groups)
    for g in range(n_groups):
        if present[g] == 0:
            continue
        Mg = M - gsum[g]
        share = (Mg[0, 0] + Mg[1, 1] + Mg[2, 2]) / tr if tr > 0 else 0.0
        lam, U = np.linalg.eigh(Mg - (sigma0_sq * share) * B)
        ok = True
        for v in lam:
            if not np.isfinite(v):
                ok = False
        if not ok or not lam[2] > 0.0 or not lam[1] - lam[0] > 1e-12 * lam[2]:
            present[g] = 2
            continue
        sg = U[:, 0].copy()
        if sg @ s < 0.0:
            sg = -sg
        h = R @ sg
        psi[g] = -math.atan2(h[0], h[1])
    return psi, present


def jackknife_sigma_rad(M, B, block_m, groups, s, R, sigma0_sq: float):
    """
    Return the delete-a-group jackknife sigma of psi [rad] and the number of groups, or None.

    Each group's block sums are removed from ``M`` and the sun refitted: ``theta_(-g)`` is the
    heading of that fit in the frame of ``R``, its sign taken along the full fit's sun ``s``;
    ``var = (G - 1) / G * sum_g (theta_(-g) - mean)^2``, angle differences wrapped (Efron & Stein
    1981; Shao & Tu 1995, the delete-d / grouped jackknife). A refit is debiased at the full fit's
    noise scale (:func:`solve_sun`: ``M_(-g) - sigma0^2 B_(-g)``, ``B_(-g)`` = ``B`` times the
    refit's share of the weight, the trace of M): one 3 x 3 eigen-solve per group. No pixel is
    read: the groups are unions of the pass's blocks.

    Parameters
    ----------
    M, B : numpy.ndarray
        The full fit's ``sum w e e^T`` and its noise-bias matrix (:func:`solve_sun`), (3, 3).
    block_m : numpy.ndarray
        Per-block sums of ``w e e^T``, (n_blocks, 3, 3).
    groups : numpy.ndarray
        Group of each block (:func:`jackknife_groups`), -1 for none.
    s : array_like
        The full fit's camera-frame sun, unit (3,).
    R : numpy.ndarray
        Rotation into the frame the heading is read in (levelling or identity), (3, 3).
    sigma0_sq : float
        The full fit's AoP noise scale [rad^2] (:func:`solve_sun`; 0 without bias correction).

    Returns
    -------
    tuple of (float, int) or None
        ``(sigma_psi_rad, G)`` over the ``G`` non-empty groups; None with fewer than 2 groups or
        when a refit does not single out a sun (the cluster-robust sigma alone is then used).

    References
    ----------
    .. [1] B. Efron and C. Stein, "The jackknife estimate of variance", Ann. Statist. 9(3),
       586-596 (1981).
    .. [2] J. Shao and D. Tu, "The Jackknife and Bootstrap", Springer (1995).

    """
    M = np.ascontiguousarray(M, dtype=np.float64)
    if not np.all(np.isfinite(M)):
        return None
    groups = np.ascontiguousarray(groups, dtype=np.int64)
    n_groups = int(groups.max()) + 1 if groups.size else 0
    if n_groups < 2:
        return None
    psi, present = _leave_group_out_psi(
        M,
        np.ascontiguousarray(B, dtype=np.float64),
        np.ascontiguousarray(block_m, dtype=np.float64),
        groups,
        n_groups,
        np.ascontiguousarray(s, dtype=np.float64),
        np.ascontiguousarray(R, dtype=np.float64),
        float(sigma0_sq),
    )
    if np.any(present == 2):  # a refit without a sun direction
        return None
    psi = psi[present == 1]
    G = psi.size
    if G < 2:
        return None
    ref = math.degrees(float(psi[0]))
    d = np.array([wrap_180_deg_float(math.degrees(float(t)) - ref) for t in psi])
    var = (G - 1.0) / G * float(np.sum((d - d.mean()) ** 2))
    return math.radians(math.sqrt(max(var, 0.0))), G


def phase_jackknife_sigma_rad(M, B, phase_m, s, R, sigma0_sq: float):
    """
    Return the delete-a-phase jackknife sigma of psi [rad] and the number of phases, or None.

    :func:`jackknife_sigma_rad` with the four mosaic phases of a DoFP sensor as the groups (every
    pixel of one place ``(row mod 2, column mod 2)`` in the 2 x 2 polarizer mosaic): the refits
    leave out one phase's ``sum w e e^T`` (``phase_m``, summed in the pixel pass). The IFOV error
    at soft cloud edges differs between the phases and cancels only partly in their average,
    which no spatial grouping sees. Phases without weight are not groups (a superpixel grid has
    one phase: None).

    Parameters
    ----------
    M, B : numpy.ndarray
        The full fit's ``sum w e e^T`` and its noise-bias matrix (:func:`solve_sun`), (3, 3).
    phase_m : numpy.ndarray or None
        Per-phase sums of ``w e e^T``, (4, 3, 3) (``full_pass``); None: no phases (a pixel list).
    s : array_like
        The full fit's camera-frame sun, unit (3,).
    R : numpy.ndarray
        Rotation into the frame the heading is read in, (3, 3).
    sigma0_sq : float
        The full fit's AoP noise scale [rad^2].

    Returns
    -------
    tuple of (float, int) or None
        ``(sigma_psi_rad, G)`` over the ``G`` phases with weight, or None (fewer than 2, or a
        refit without a sun).

    References
    ----------
    .. [1] B. Efron and C. Stein, "The jackknife estimate of variance", Ann. Statist. 9(3),
       586-596 (1981).

    """
    if phase_m is None:
        return None
    pm = np.asarray(phase_m, dtype=np.float64)
    tr = pm[:, 0, 0] + pm[:, 1, 1] + pm[:, 2, 2]
    # a share below 1e-6 of the weight is float32 rounding of the pass, not a phase
    groups = np.where(tr > 1e-6 * tr.sum(), np.arange(pm.shape[0]), -1).astype(np.int64)
    return jackknife_sigma_rad(M, B, pm, groups, s, R, sigma0_sq)
