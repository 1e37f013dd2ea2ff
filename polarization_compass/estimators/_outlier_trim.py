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
The consensus step of the least-squares robust refit: a sky-fit sun, and the pixels that disagree.

:func:`_consensus_sun` fits the whole view robustly (:func:`polarization_compass.skyfit.fit_sky`,
which clouds or flare cannot pull); :func:`_trim_outliers` drops the pixels whose AoP is further
than ``outlier_deg`` from the Rayleigh AoP of a sun, in one compiled pass (:func:`_outlier_pass`).
The refit loop itself is ``_LSBase._robust_refit`` (:mod:`.least_squares`).
"""

from __future__ import annotations

import math

from numba import njit
import numpy as np

from ._kernels import _FM
from ..fastmath import sincos32_folded as _sincos32


def _consensus_sun(view, obs):
    """
    Return the camera-frame sun of the robust whole-view fit, or None with too few pixels.

    The fit is :func:`polarization_compass.skyfit.fit_sky` at the ephemeris altitude and the known
    tilt (level when unknown).

    The fit reads at most 2000 pixels spread evenly over the view; the view is thinned to about
    20000 first (a regular step through its pixels) so that picking them does not scan a
    multi-megapixel frame.
    """
    from ..skyfit import _sun_cam, fit_sky, sample_sky

    n = int(np.size(view.aop))
    step = max(1, n // 20000)
    sample = sample_sky(
        np.ravel(view.aop)[::step],
        np.ravel(view.dop)[::step],
        np.ravel(view.valid)[::step],
        np.asarray(view.rays).reshape(3, -1)[:, ::step],
        max_pixels=2000,
    )
    if sample is None:
        return None
    p = float(obs.pitch_deg) if obs.pitch_deg is not None else 0.0
    r = float(obs.roll_deg) if obs.roll_deg is not None else 0.0
    f = fit_sky(sample, float(obs.sun_altitude_deg), p, r)
    return _sun_cam([f.psi_deg], [f.sun_altitude_deg], p, r)[0]


@njit(fastmath=_FM, cache=True, nogil=True, error_model='numpy')
def _outlier_pass(aop, valid, rays, s0, s1, s2, cos_lim, keep):  # pragma: no cover - compiled
    """
    Mark the valid pixels whose AoP is within the limit of the Rayleigh AoP of the sun.

    One pass: ``keep[i] = valid[i]`` unless pixel i's AoP is further than the limit from the
    Rayleigh AoP of the sun ``(s0, s1, s2)``: ``cos 2(a - m) < cos_lim`` with ``m`` the eq 28 angle
    of ``E = S x P`` (eq 18), from doubled angles (no angle subtraction). float32, branch-free with
    the vectorising ``sincos32_folded`` (a non-finite AoP compares false and is kept, as the fit's
    own pass decides about it). Returns how many valid pixels were dropped.
    """
    f2 = np.float32(2.0)
    t0, t1, t2 = np.float32(s0), np.float32(s1), np.float32(s2)
    lim = np.float32(cos_lim)
    tiny = np.float32(1e-24)
    dropped = 0.0
    for i in range(aop.size):
        px, py, pz = rays[0, i], rays[1, i], rays[2, i]
        ex = t1 * pz - t2 * py
        ey = t2 * px - t0 * pz
        n2 = ex * ex + ey * ey
        sa, ca = _sincos32(np.float32(aop[i]))
        num = (ca * ca - sa * sa) * (
            ey * ey - ex * ex
        ) + f2 * sa * ca * f2 * ex * ey  # cos 2(a - m) * n2
        drop = valid[i] and n2 > tiny and num < lim * n2
        keep[i] = valid[i] and not drop
        x = 1.0 if drop else 0.0
        dropped += x
    return int(dropped)


def _trim_outliers(view, sun_cam, outlier_deg: float):
    """
    Drop the view's pixels whose AoP is more than ``outlier_deg`` from the Rayleigh AoP of a sun.

    The sun is ``sun_cam`` (camera frame); the model AoP of a pixel is eq 28 of ``E = S x P`` (eq
    18); the residual is the axial difference, computed from doubled angles. Returns the view with
    those pixels invalid and how many were dropped (of the valid ones). This is the consensus step
    of the robust refit (``outlier_deg`` knob): a fit that clouds, flare ghosts or an obstacle
    pulled is refitted on the pixels that agree with it. One compiled pass over the pixels the
    estimator already reads, no temporaries (:func:`_outlier_pass`).
    """
    from dataclasses import replace

    valid = np.asarray(view.valid, dtype=bool)
    keep = np.empty(valid.shape, dtype=bool)
    s = np.asarray(sun_cam, dtype=np.float64)
    rays = np.asarray(view.rays)
    dropped = _outlier_pass(
        np.ravel(view.aop),
        np.ravel(valid),
        rays.reshape(3, -1),
        float(s[0]),
        float(s[1]),
        float(s[2]),
        math.cos(math.radians(2.0 * outlier_deg)),
        keep.reshape(-1),
    )
    return replace(view, valid=keep), int(dropped)
