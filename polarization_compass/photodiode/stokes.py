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
Per-unit linear Stokes vector, angle and degree of polarization from 2-4 polarizer channels.

An ideal linear polarizer at angle theta in front of a photodiode of relative gain g reads ``I = g
* (S0 + S1 cos 2 theta + S2 sin 2 theta) / 2`` (Malus's law in Stokes form, e.g. Hecht, *Optics*,
8.12; Tyo et al. 2006, Appl. Opt. 45(22) eq 5). With 3-4 channels at distinct angles (mod 180 deg)
the least-squares (S0, S1, S2) follow from the gain-corrected readings; the angle of polarization
is ``0.5 * atan2(S2, S1)`` in the unit's polarizer angle convention and the DoP ``hypot(S1, S2) /
S0``. Two channels determine S0 and one linear polarization component only: no angle, and the unit
is reported unusable for a heading (``valid`` False, ``reason`` says why).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

__all__ = ['UnitStokes', 'fit_stokes', 'design_matrix']


def design_matrix(channels_deg) -> np.ndarray:
    """
    Return the matrix A with ``I / g = A @ (S0, S1, S2)`` for ideal polarizers (Malus's law).

    Parameters
    ----------
    channels_deg : array_like
        (C,) polarizer angles [deg] in the unit's convention.

    Returns
    -------
    numpy.ndarray
        (C, 3) rows ``0.5 * (1, cos 2 theta, sin 2 theta)``.

    References
    ----------
    Tyo, Goldstein, Chenault and Shaw 2006, Appl. Opt. 45(22), eq 5.

    """
    t = np.radians(np.asarray(channels_deg, dtype=float))
    return 0.5 * np.stack([np.ones_like(t), np.cos(2 * t), np.sin(2 * t)], axis=-1)


@dataclass
class UnitStokes:
    """
    Stokes fit of every unit in every sample: arrays (S, U).

    ``aop_rad`` in the units' polarizer angle convention, folded to [-pi/2, pi/2); ``dop`` in [0,
    inf) (noise can push it over 1); ``misfit`` the rms residual of the channels relative to S0 (0
    with three channels); ``valid`` False where a unit has no angle (two channels, S0 <= 0,
    non-finite or negative readings, disabled); ``reason`` (U,) says why a whole unit is unusable
    ('' when usable).
    """

    s0: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    aop_rad: np.ndarray
    dop: np.ndarray
    misfit: np.ndarray
    valid: np.ndarray
    reason: list


def fit_stokes(intensities, geometry) -> UnitStokes:
    """
    Fit (S0, S1, S2), the angle and the degree of polarization of every unit in every sample.

    Parameters
    ----------
    intensities : array_like
        (S, U, C) readings (counts, any linear unit).
    geometry : ArrayGeometry
        Channel angles [deg], gains and enabled units.

    Returns
    -------
    UnitStokes
        Arrays (S, U): least-squares Stokes vector of the gain-corrected readings, ``aop_rad`` =
        ``0.5 atan2(S2, S1)`` folded to [-pi/2, pi/2), ``dop`` = ``hypot(S1, S2) / S0``, misfit and
        validity.

    References
    ----------
    Tyo, Goldstein, Chenault and Shaw 2006, Appl. Opt. 45(22), eqs 5-8.

    """
    x = np.asarray(intensities, dtype=np.float64)
    S, U, _ = x.shape
    out = {k: np.zeros((S, U)) for k in ('s0', 's1', 's2', 'aop_rad', 'dop', 'misfit')}
    valid = np.zeros((S, U), dtype=bool)
    reasons = []
    for u, unit in enumerate(geometry.units):
        n = unit.n_channels
        if not unit.enabled:
            reasons.append('disabled in the geometry')
            continue
        if n < 3:
            reasons.append(f'{n} channels give no angle of polarization (3 or more needed)')
            continue
        reasons.append('')
        y = x[:, u, :n] / np.asarray(unit.gains, dtype=float)
        A = design_matrix(unit.channels_deg)
        ok = np.all(np.isfinite(y), axis=1) & np.all(y >= 0.0, axis=1)
        yy = np.where(ok[:, None], y, 0.0)
        stokes = yy @ np.linalg.pinv(A).T  # (S, 3)
        s0, s1, s2 = stokes[:, 0], stokes[:, 1], stokes[:, 2]
        ok &= s0 > 0.0
        resid = yy - stokes @ A.T
        safe_s0 = np.where(ok, s0, 1.0)
        out['s0'][:, u], out['s1'][:, u], out['s2'][:, u] = s0, s1, s2
        out['aop_rad'][:, u] = np.where(ok, 0.5 * np.arctan2(s2, s1), 0.0)
        out['dop'][:, u] = np.where(ok, np.hypot(s1, s2) / safe_s0, 0.0)
        out['misfit'][:, u] = (
            np.where(ok, np.sqrt(np.mean(resid**2, axis=1)) / safe_s0, 0.0) if n > 3 else 0.0
        )
        valid[:, u] = ok
    # 0.5 * atan2 lies in [-pi/2, pi/2]; fold +pi/2 to -pi/2 (the fold_aop_rad contract) without
    # another pass
    a = out['aop_rad']
    a[a >= math.pi / 2] = -math.pi / 2
    return UnitStokes(
        out['s0'], out['s1'], out['s2'], a, out['dop'], out['misfit'], valid, reasons
    )
