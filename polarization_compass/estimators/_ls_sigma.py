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
The least-squares sun's analytic sigmas: cluster-robust over the pass's blocks, the known tilt's.

:func:`_block_sigmas` propagates first-order sensitivities of the sun (psi, its elevation) over
the block sums of the pixel pass (the cluster-robust sandwich with the CR1 factor);
:func:`_attitude_sigma_deg` is the heading's sigma due to the uncertainty of the pitch and roll it
was levelled with. The jackknife sigmas that may replace the cluster-robust one are in
:mod:`.jackknife`.
"""

from __future__ import annotations

import math

from numba import njit
import numpy as np

from ._common import cr1_factor
from .base import Observation
from .sun_from_evectors import tilt_sensitivity

#: :func:`._common.cr1_factor` compiled for :func:`_block_sigmas`.
_cr1_factor = njit(inline='always', cache=True)(cr1_factor)


@njit(cache=True, nogil=True)
def _block_sigmas(block_m, block_w, n, s, cs):  # pragma: no cover - compiled
    """
    Return the cluster-robust sigma for each row c of ``cs`` (CR1 factor).

    The sigma of ``sum_i -s^T (w_i e_i e_i^T) c`` over the blocks: block sums centred by weight
    share (the debiased solution leaves a small O(sigma^2) mean), CR1 small-sample factor
    (:func:`._common.cr1_factor`).
    """
    K = cs.shape[0]
    G = block_m.shape[0]
    out = np.zeros(K)
    W = 0.0
    used = 0
    for g in range(G):
        if block_w[g] > 0:
            W += block_w[g]
            used += 1
    if used == 0 or not W > 0:
        return out
    corr = _cr1_factor(used, n, 2)
    sums = np.zeros(G)
    for k in range(K):
        total = 0.0
        for g in range(G):
            if block_w[g] > 0:
                v = 0.0
                for a in range(3):
                    for b in range(3):
                        v -= s[a] * block_m[g, a, b] * cs[k, b]
                sums[g] = v
                total += v
        ss = 0.0
        for g in range(G):
            if block_w[g] > 0:
                d = sums[g] - total * block_w[g] / W
                ss += d * d
        out[k] = math.sqrt(max(ss * corr, 0.0))
    return out


def _attitude_sigma_deg(obs: Observation, s_cam):
    """
    Return the heading's 1-sigma due to the known tilt's uncertainty [deg], or None.

    ``sqrt(J diag(sigma_pitch^2, sigma_roll^2) J^T)`` with ``J`` of :func:`tilt_sensitivity`;
    None when the observation states no attitude uncertainty.
    """
    a = obs.attitude_sigma_deg
    if a is None:
        return None
    sp, sr = float(a[0]), float(a[1])
    if not (math.isfinite(sp) and math.isfinite(sr) and sp >= 0.0 and sr >= 0.0):
        return None  # not a usable uncertainty: the tilt is taken as exact
    if sp == 0.0 and sr == 0.0:
        return None
    jp, jr = tilt_sensitivity(s_cam, float(obs.pitch_deg), float(obs.roll_deg))
    return math.hypot(jp * sp, jr * sr)
