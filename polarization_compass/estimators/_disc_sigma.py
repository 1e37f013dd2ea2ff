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
The disc methods' cluster-robust sigma: block sums of the influence and the CR1-corrected sigma.

:func:`_blocks` sums a pass's per-pixel influence terms over the view's blocks, :func:`cr1_sigma`
turns block sums into the sigma (small-sample factor :func:`._common.cr1_factor`); the constants
say when coarser blocks are tried too (``DiscEstimator._cluster_sigma_rad`` in
:mod:`._disc_estimator`).
"""

from __future__ import annotations

import math

import numpy as np

from ._common import cr1_factor
from ._disc import _block_sums

__all__ = ['cr1_sigma', 'COARSE_CLUSTER_FACTOR', 'MIN_COARSE_CLUSTERS', 'COARSE_MIN_COVERAGE']


#: The cluster-robust sigma is also taken over blocks this many times ``block_px`` a side (if the
#: view has at least ``MIN_COARSE_CLUSTERS`` of them), and the larger of the two is used: under
#: broken clouds seen by an IMX250MZR-like sensor (superpixel demosaic) the AoP errors are
#: correlated across cloud edges, beyond the default 32 px blocks (2 x 2 pixels at stride 16): mean
#: err^2/sigma^2 3.6 / 3.1 (sm_asm / symmetry, clouds 30 %, 12 scenes) with the fine blocks alone,
#: 2.5 / 2.3 with 2x, 1.9 with 4x, 1.3 / 1.9 with 8x coarser blocks; but coarse blocks also sum
#: smooth residual structure whose effects cancel (uniform overcast, sm_asm: 0.46 fine, 0.22 at 2x,
#: 0.04 at 8x), so 2x.
COARSE_CLUSTER_FACTOR = 2
MIN_COARSE_CLUSTERS = 12
#: ... and only where this share of the disc is paired (clouds with an IMX250-like sensor:
#: 0.83-0.85; half the disc occluded: at most 0.5): on a wedge of pairs the influence has large
#: lobes of both signs, and coarse blocks would count the residual of the fitted axis itself many
#: times over (3.7x sigma under independent noise).
COARSE_MIN_COVERAGE = 0.6


def cr1_sigma(block_sum, n: int) -> float:
    """
    Return the cluster-robust sigma (rad) from the block sums of the influence.

    ``block_sum``: the influence (rad) summed over each block, ``n`` pixels in all; the blocks
    with a non-zero sum are the clusters; small-sample factor :func:`._common.cr1_factor`
    with two parameters (as the other methods).
    """
    b = np.asarray(block_sum, dtype=float)
    b = b[b != 0.0]
    G = b.size
    if G == 0:
        return 0.0
    return math.sqrt(float(np.dot(b, b)) * cr1_factor(G, n, 2))


def _blocks(t0, t1, segs) -> np.ndarray:
    """Return the block sums (2, n_blocks) of the per-pixel terms t0, t1 over the segments."""
    block_sum = np.zeros((2, segs[3]))
    _block_sums(t0, t1, segs[0], segs[1], segs[2], block_sum)
    return block_sum
