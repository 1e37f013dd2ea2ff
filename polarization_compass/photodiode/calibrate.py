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
Relative channel gains of each unit from the data alone (no rig).

With gains g_k, the gain-corrected readings ``h_k I_k`` (``h_k = 1 / g_k``) of a unit with C >= 4
channels must lie in the 3-D space of ideal polarizer responses spanned by the columns of the
design matrix A (:func:`~.stokes.design_matrix`): ``Q^T diag(I_t) h = 0`` for every sample t, with
Q a basis of A's left null space (for 0/45/90/135 deg: ``I_0 h_0 + I_90 h_90 = I_45 h_45 + I_135
h_135``, both being S0). Stacked over samples this is a homogeneous linear system; h is its
smallest right singular vector. It is identifiable when the sky's polarization seen by the unit
varies (a full turn sweeps the angle of polarization through the unit's frame); a sky seen at one
constant polarization leaves a family of solutions, reported as ``poorly conditioned``. Gains are
normalised to mean 1 per unit.

Uncertainty: delete-one-group jackknife over groups of samples (the turns when several recordings
are given, else 8 contiguous blocks of one recording). Units with fewer than four channels have no
redundancy: their gains are not identifiable this way and are left unchanged (reported).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .stokes import design_matrix
from ..errors import CompassError

__all__ = ['GainCalibration', 'calibrate_gains', 'CalibrationError']


class CalibrationError(CompassError):
    """Gains that cannot be estimated from these data."""


@dataclass
class GainCalibration:
    """
    Relative channel gains of each unit, with their uncertainty.

    Per unit: ``gains`` (C,), ``gains_sigma`` (C,) (None: not estimated), ``condition`` (ratio of
    the two smallest singular values, > ~3 is well identified), ``note`` (why not estimated /
    warnings).
    """

    gains: list
    gains_sigma: list
    condition: list
    note: list


def _unit_gains(samples: np.ndarray, channels_deg) -> tuple[np.ndarray, float]:
    """Gains (C,) mean 1 and the singular-value ratio, from readings (S, C) of one unit."""
    A = design_matrix(channels_deg)
    Uq, sv, _ = np.linalg.svd(A, full_matrices=True)
    Q = Uq[:, 3:]  # (C, C-3) left null space of A
    # rows: for each sample and null vector q: sum_k q_k I_k h_k
    D = (samples[:, None, :] * Q.T[None, :, :]).reshape(-1, samples.shape[1])
    scale = np.sqrt(np.mean(D * D, axis=0))
    scale = np.where(scale > 0, scale, 1.0)
    _, s, Vt = np.linalg.svd(D / scale, full_matrices=False)
    h = Vt[-1] / scale
    if np.sum(h) < 0:
        h = -h
    if not s[-2] > 1e-9 * s[0]:
        cond = 0.0  # a null space of two or more dimensions: not identifiable at all
    else:
        cond = float(s[-2] / max(s[-1], 1e-12 * s[0]))
    if not np.all(h > 0):
        return np.full(samples.shape[1], np.nan), cond
    g = 1.0 / h
    return g / g.mean(), cond


def calibrate_gains(recordings, geometry, min_condition: float = 3.0) -> GainCalibration:
    """
    Estimate every unit's relative channel gains from recordings of full turns.

    Parameters
    ----------
    recordings : sequence of array_like
        Readings (S, U, C) of one or more recordings (one turn each is best; several give the
        jackknife groups).
    geometry : ArrayGeometry
        Channel angles and the current gains (kept for units that cannot be calibrated).
    min_condition : float, optional
        Singular-value ratio a unit needs to be calibrated (default 3).

    Returns
    -------
    GainCalibration
        Gains (mean 1 per unit), jackknife sigmas, conditions and notes.

    Raises
    ------
    CalibrationError
        No recording, or no unit could be calibrated.

    """
    recs = [np.asarray(r, dtype=float) for r in recordings]
    if not recs:
        raise CalibrationError('no recordings to calibrate from')
    if len(recs) >= 2:
        groups = recs
    else:
        groups = [b for b in np.array_split(recs[0], 8) if b.shape[0] > 0]
    gains, sigmas, conds, notes = [], [], [], []
    for u, unit in enumerate(geometry.units):
        n = unit.n_channels
        if n < 4:
            gains.append(list(unit.gains))
            sigmas.append(None)
            conds.append(0.0)
            notes.append(
                f'{n} channels: no redundancy, gains not identifiable from the data (kept)'
            )
            continue
        parts = []
        for grp in groups:
            x = grp[:, u, :n]
            ok = np.all(np.isfinite(x), axis=1) & np.all(x >= 0, axis=1)
            parts.append(x[ok])
        allx = np.concatenate(parts) if parts else np.zeros((0, n))
        if allx.shape[0] < 3 * n:
            gains.append(list(unit.gains))
            sigmas.append(None)
            conds.append(0.0)
            notes.append(f'only {allx.shape[0]} usable sample(s) (kept the old gains)')
            continue
        g, cond = _unit_gains(allx, unit.channels_deg)
        if not np.all(np.isfinite(g)):
            gains.append(list(unit.gains))
            sigmas.append(None)
            conds.append(cond)
            notes.append(
                'the fitted gains are not all positive: the unit does not follow the '
                'ideal-polarizer model '
                '(faulty channel?) (kept)'
            )
            continue
        if cond < min_condition:
            gains.append(list(unit.gains))
            sigmas.append(None)
            conds.append(cond)
            notes.append(
                f'poorly conditioned (singular-value ratio {cond:.2f} < {min_condition:g}): the '
                "sky's "
                'polarization did not vary enough across the samples, or the unit is faulty (kept)'
            )
            continue
        jk = []
        for i in range(len(parts)):
            rest = np.concatenate([p for j, p in enumerate(parts) if j != i])
            if rest.shape[0] >= 3 * n:
                gj, _ = _unit_gains(rest, unit.channels_deg)
                if np.all(np.isfinite(gj)):
                    jk.append(gj)
        if len(jk) >= 2:
            jk = np.array(jk)
            m = len(jk)
            sig = np.sqrt((m - 1) / m * np.sum((jk - jk.mean(axis=0)) ** 2, axis=0))
        else:
            sig = None
        gains.append([float(v) for v in g])
        sigmas.append(None if sig is None else [float(v) for v in sig])
        conds.append(cond)
        notes.append('')
    if all(s is None for s in sigmas) and all(n for n in notes):
        raise CalibrationError(
            'no unit could be calibrated: '
            + '; '.join(f'unit {i}: {t}' for i, t in enumerate(notes))
        )
    return GainCalibration(gains, sigmas, conds, notes)
