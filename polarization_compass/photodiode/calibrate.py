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

Uncertainty: delete-one-group jackknife over groups of samples (the distinct recordings when
several are given -- a recording given twice counts once --, else 8 contiguous blocks of one
recording). Units with fewer than four channels have no redundancy: their gains are not
identifiable this way and are left unchanged (reported); disabled units are left alone; readings
that are not measurements (:func:`~.readings.reading_flags`) are left out.

When not to use the gains: they remove the part of each unit's channel misfit that a gain error
explains, and change the unit's angle by ``angle_change_deg``. That helps only when gain errors
dominate the angle errors. On a sensor whose units' angle residuals against the sky are far larger
than that change (the real POL-OP sensor: changes of 2-4 deg against residuals of 12-30 deg), the
new gains mostly fit other defects and made the heading worse (docs/photodiode-arrays.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .readings import reading_flags
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
    warnings), ``angle_change_deg`` (DoP^2-weighted rms change of the unit's angle of polarization
    the new gains make over the samples, None when not calibrated). ``notes`` holds notes on the
    recordings (repeated recordings counted once).
    """

    gains: list
    gains_sigma: list
    condition: list
    note: list
    angle_change_deg: list = field(default_factory=list)
    notes: list = field(default_factory=list)


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


def _groups(recordings) -> tuple[list, list]:
    """
    Return the jackknife groups and notes: the distinct recordings, or 8 blocks of a single one.

    A recording given twice is the same data: counted once (else the jackknife sees no spread and
    reports sigma 0).
    """
    recs, notes = [], []
    for i, r in enumerate(recordings):
        a = np.asarray(r, dtype=float)
        same = next((j for j, (_, b) in enumerate(recs) if _same(a, b)), None)
        if same is None:
            recs.append((i, a))
        else:
            notes.append(f'recording {i} repeats recording {recs[same][0]}: counted once')
    if len(recs) >= 2:
        return [a for _, a in recs], notes
    return [b for b in np.array_split(recs[0][1], 8) if b.shape[0] > 0], notes


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


def _angle_change_deg(x: np.ndarray, channels_deg, g_old, g_new) -> float:
    """
    Return how much new gains turn a unit's angle [deg] (readings (S, C)).

    The rms over the samples weighted by DoP^2 (the weight a unit's angle has in the heading), so
    that nearly unpolarized samples, whose angle any change turns, do not dominate.
    """
    P = np.linalg.pinv(design_matrix(channels_deg))
    st = [(x / np.asarray(g, dtype=float)) @ P.T for g in (g_old, g_new)]
    a = [0.5 * np.arctan2(v[:, 2], v[:, 1]) for v in st]
    s0 = st[0][:, 0]
    w = np.where(s0 > 0, np.hypot(st[0][:, 1], st[0][:, 2]) / np.where(s0 > 0, s0, 1.0), 0.0) ** 2
    d = (a[1] - a[0] + np.pi / 2) % np.pi - np.pi / 2
    if not np.sum(w) > 0:
        return 0.0
    return float(np.degrees(np.sqrt(np.sum(w * d**2) / np.sum(w))))


def _calibrate_unit(parts, unit, min_condition: float):
    """
    Calibrate one enabled unit from its usable readings per group.

    Returns ``(gains, sigma or None, condition, note, angle change or None)``.
    """
    n = unit.n_channels
    keep = list(unit.gains)
    if n < 4:
        return keep, None, 0.0, f'{n} channels: no redundancy, gains not identifiable (kept)', None
    allx = np.concatenate(parts) if parts else np.zeros((0, n))
    if allx.shape[0] < 3 * n:
        return keep, None, 0.0, f'only {allx.shape[0]} usable sample(s) (kept the old gains)', None
    g, cond = _unit_gains(allx, unit.channels_deg)
    if not np.all(np.isfinite(g)):
        why = (
            'the fitted gains are not all positive: the unit does not follow the '
            'ideal-polarizer model (faulty channel?) (kept)'
        )
        return keep, None, cond, why, None
    if cond < min_condition:
        why = (
            f'poorly conditioned (singular-value ratio {cond:.2f} < {min_condition:g}): the '
            "sky's polarization did not vary enough across the samples, or the unit is faulty "
            '(kept)'
        )
        return keep, None, cond, why, None
    jk = []
    for i in range(len(parts)):
        rest = np.concatenate([p for j, p in enumerate(parts) if j != i])
        if rest.shape[0] >= 3 * n:
            gj, _ = _unit_gains(rest, unit.channels_deg)
            if np.all(np.isfinite(gj)):
                jk.append(gj)
    sig = None
    if len(jk) >= 2:
        jk = np.array(jk)
        m = len(jk)
        var = (m - 1) / m * np.sum((jk - jk.mean(axis=0)) ** 2, axis=0)
        sig = [float(v) for v in np.sqrt(var)]
    change = _angle_change_deg(allx, unit.channels_deg, unit.gains, g)
    return [float(v) for v in g], sig, cond, '', change


def calibrate_gains(recordings, geometry, min_condition: float = 3.0) -> GainCalibration:
    """
    Estimate every enabled unit's relative channel gains from recordings of full turns.

    Parameters
    ----------
    recordings : sequence of array_like
        Readings (S, U, C) of one or more recordings (one turn each is best; several give the
        jackknife groups; a recording given twice counts once).
    geometry : ArrayGeometry
        Channel angles, the current gains (kept for units that cannot be calibrated), enabled
        units (disabled ones are left alone) and the saturation limits.
    min_condition : float, optional
        Singular-value ratio a unit needs to be calibrated (default 3).

    Returns
    -------
    GainCalibration
        Gains (mean 1 per unit), jackknife sigmas, conditions, notes and the angle change the
        gains make.

    Raises
    ------
    CalibrationError
        No recording, or no enabled unit could be calibrated.

    Notes
    -----
    Samples whose readings are not measurements (:func:`~.readings.reading_flags`) are left out.

    """
    recs = list(recordings)
    if not recs:
        raise CalibrationError('no recordings to calibrate from')
    groups, rec_notes = _groups(recs)
    flags = [reading_flags(grp, geometry) for grp in groups]
    gains, sigmas, conds, notes, changes = [], [], [], [], []
    for u, unit in enumerate(geometry.units):
        if not unit.enabled:
            gains.append(list(unit.gains))
            sigmas.append(None)
            conds.append(0.0)
            notes.append('disabled (kept)')
            changes.append(None)
            continue
        n = unit.n_channels
        parts = [
            grp[:, u, :n][~np.any([f[k][:, u] for k in f], axis=0)]
            for grp, f in zip(groups, flags)
        ]
        res = _calibrate_unit(parts, unit, min_condition)
        for lst, v in zip((gains, sigmas, conds, notes, changes), res):
            lst.append(v)
    enabled = [i for i, un in enumerate(geometry.units) if un.enabled]
    if all(sigmas[i] is None and notes[i] for i in enabled):
        raise CalibrationError(
            'no unit could be calibrated: ' + '; '.join(f'unit {i}: {notes[i]}' for i in enabled)
        )
    return GainCalibration(gains, sigmas, conds, notes, changes, rec_notes)
