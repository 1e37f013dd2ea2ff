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

from dataclasses import dataclass, field
import math

import numpy as np

from .readings import reading_flags, READING_REASONS

__all__ = ['UnitStokes', 'fit_stokes', 'design_matrix', 'FIT_REASONS']

#: Why a unit's fit is not a measurement in a sample (besides :data:`~.readings.READING_REASONS`).
FIT_REASONS = ('dop_above_1', 'channel_misfit')


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
    readings that are not measurements, disabled); ``reason`` (U,) says why a whole unit is
    unusable ('' when usable); ``unusable`` maps each reason a usable unit lost a sample for
    (:data:`~.readings.READING_REASONS` and :data:`FIT_REASONS`) to a bool array (S, U).
    """

    s0: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    aop_rad: np.ndarray
    dop: np.ndarray
    misfit: np.ndarray
    valid: np.ndarray
    reason: list
    unusable: dict = field(default_factory=dict)

    def unusable_counts(self, i: int) -> dict:
        """
        Count the units that were not measurements in sample ``i``, per reason.

        Parameters
        ----------
        i : int
            The sample.

        Returns
        -------
        dict of str to int
            Reason -> number of units (reasons with none are left out).

        """
        out = {}
        for k, v in self.unusable.items():
            n = int(np.count_nonzero(v[i]))
            if n:
                out[k] = n
        return out


#: DoP noise of one sample's fit assumed at least (readings' noise), for the ``dop_above_1`` test.
DOP_NOISE_FLOOR = 0.05
#: A unit's DoP above 1 by more than this many of its noise sigmas is not a measurement.
DOP_EXCESS_SIGMAS = 3.0
#: Four channels whose rms residual from one Stokes vector exceeds this share of S0 do not follow
#: Malus's law (a wrong gain, a broken polarizer): the unit's angle is not a measurement. The real
#: POL-OP units that work stay below 0.12 (99th percentile); the one with a bad channel is at 0.2.
MAX_CHANNEL_MISFIT = 0.15


def fit_stokes(intensities, geometry) -> UnitStokes:
    """
    Fit (S0, S1, S2), the angle and the degree of polarization of every unit in every sample.

    Readings that are not measurements (:func:`~.readings.reading_flags`: NaN or negative,
    saturated, a lone zero channel, duplicated channels), a DoP above 1 by more than
    ``DOP_EXCESS_SIGMAS`` of its noise, and four channels that do not fit one Stokes vector
    (misfit above ``MAX_CHANNEL_MISFIT``) make the unit unusable in that sample, recorded per
    reason in ``unusable``. The noise of the DoP is ``sqrt(2) sigma / S0`` for channel noise
    sigma; with four channels ``sigma / S0 = 2 misfit`` (the one redundant combination), floored
    at ``DOP_NOISE_FLOOR``.

    Parameters
    ----------
    intensities : array_like
        (S, U, C) readings (counts, any linear unit).
    geometry : ArrayGeometry
        Channel angles [deg], dark offsets, gains, saturation limits and enabled units.

    Returns
    -------
    UnitStokes
        Arrays (S, U): least-squares Stokes vector of the dark-subtracted, gain-corrected readings,
        ``aop_rad`` = ``0.5 atan2(S2, S1)`` folded to [-pi/2, pi/2), ``dop`` = ``hypot(S1, S2) /
        S0``, misfit, validity and the reasons.

    References
    ----------
    Tyo, Goldstein, Chenault and Shaw 2006, Appl. Opt. 45(22), eqs 5-8.

    """
    x = np.asarray(intensities, dtype=np.float64)
    S, U, _ = x.shape
    out = {k: np.zeros((S, U)) for k in ('s0', 's1', 's2', 'aop_rad', 'dop', 'misfit')}
    valid = np.zeros((S, U), dtype=bool)
    flags = reading_flags(x, geometry)
    unusable = {k: np.zeros((S, U), dtype=bool) for k in (*READING_REASONS, *FIT_REASONS)}
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
        ok = np.ones(S, dtype=bool)
        for k in READING_REASONS:
            unusable[k][:, u] = flags[k][:, u]
            ok &= ~flags[k][:, u]
        _fit_unit(x[:, u, :n], unit, ok, out, u)
        mis = out['misfit'][:, u]
        over = ok & (out['dop'][:, u] > 1.0 + DOP_EXCESS_SIGMAS * _dop_sigma(mis))
        unusable['dop_above_1'][:, u] = over
        unusable['channel_misfit'][:, u] = ok & ~over & (mis > MAX_CHANNEL_MISFIT)
        valid[:, u] = ok & (out['s0'][:, u] > 0.0) & ~over & (mis <= MAX_CHANNEL_MISFIT)
    # 0.5 * atan2 lies in [-pi/2, pi/2]; fold +pi/2 to -pi/2 (the fold_aop_rad contract) without
    # another pass
    a = out['aop_rad']
    a[a >= math.pi / 2] = -math.pi / 2
    return UnitStokes(
        out['s0'], out['s1'], out['s2'], a, out['dop'], out['misfit'], valid, reasons, unusable
    )


def _dop_sigma(misfit: np.ndarray) -> np.ndarray:
    """Return the 1-sigma of a unit's DoP from its channel misfit (:func:`fit_stokes`)."""
    return np.maximum(DOP_NOISE_FLOOR, 2.0 * math.sqrt(2.0) * misfit)


def _fit_unit(x: np.ndarray, unit, ok: np.ndarray, out: dict, u: int) -> None:
    """
    Fit one unit's readings (S, n) where ``ok``; write column ``u`` of ``out``.

    Samples not ``ok`` or with S0 <= 0 get angle, DoP and misfit 0.
    """
    n = unit.n_channels
    dark = 0.0 if unit.dark_offset is None else np.asarray(unit.dark_offset, dtype=float)
    y = (x - dark) / np.asarray(unit.gains, dtype=float)
    A = design_matrix(unit.channels_deg)
    yy = np.where(ok[:, None], y, 0.0)
    stokes = yy @ np.linalg.pinv(A).T  # (S, 3)
    s0, s1, s2 = stokes[:, 0], stokes[:, 1], stokes[:, 2]
    good = ok & (s0 > 0.0)
    resid = yy - stokes @ A.T
    safe_s0 = np.where(good, s0, 1.0)
    out['s0'][:, u], out['s1'][:, u], out['s2'][:, u] = s0, s1, s2
    out['aop_rad'][:, u] = np.where(good, 0.5 * np.arctan2(s2, s1), 0.0)
    out['dop'][:, u] = np.where(good, np.hypot(s1, s2) / safe_s0, 0.0)
    out['misfit'][:, u] = (
        np.where(good, np.sqrt(np.mean(resid**2, axis=1)) / safe_s0, 0.0) if n > 3 else 0.0
    )
