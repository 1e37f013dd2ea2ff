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
Mount calibration from several recordings, and the within-turn scatter that judges it (issue 28).

:func:`fit_mount_recordings` fits the mount of :mod:`.mount_fit` from several recordings at once,
leaving out those whose sky misfits the single-scattering model (:data:`MAX_SKY_MISFIT_DEG`), and
widens its sigmas by how much the kept recordings' own mounts disagree (a sky that is not clear
biases one recording); :func:`heading_scatter_deg` is the before/after measure of a calibration:
how much ``bearing + imu_yaw`` moves within a turn in place.
"""

from __future__ import annotations

import math

import numpy as np

from .mount import Mount
from .mount_fit import concat, fit_mount, MountFit, MountFitError

__all__ = [
    'MAX_DISAGREEMENT_DEG',
    'MAX_SKY_MISFIT_DEG',
    'fit_mount_recordings',
    'heading_scatter_deg',
]

#: recordings whose own mounts lie within this of each other (per axis, deg) are fitted together
#: with Birge-widened sigmas and a warning; further apart they are refused (a sky that is not
#: clear moved one recording's fit by 4.6 deg of pitch on the real sessions, docs)
MAX_DISAGREEMENT_DEG = 5.0

#: a recording whose sky misfit (``MountFit.sky_misfit_deg``: the median rms angle residual, at its
#: own best mount, of the units viewing the sky 60-120 deg from the sun, where a clear sky's angle
#: of polarization is the single-scattering one) exceeds this [deg] is left out of the mount: its
#: sky is not the model's (trees, clouds). A tilt of the mount moves the units' angles by about its
#: own size (3 deg of pitch: 2.1-3.5 deg rms with the sun at 26-64 deg, the 8-unit array), and the
#: tilts looked for are a few degrees (recordings further apart than 5 deg are refused,
#: MAX_DISAGREEMENT_DEG): a sky that misfits by more hides the tilt the fit is for. Below
#: it lie the units' angle noise (0.3-1 deg on the real sessions, from successive differences of
#: the residuals) and both clear real skies (2.1 deg at sun 64 deg, 3.8 at sun 26, uncalibrated
#: polarizer offsets included); the session under trees misfits by 7.7 (docs/photodiode-arrays.md)
MAX_SKY_MISFIT_DEG = 5.0


def heading_scatter_deg(bearing_deg, imu_yaw_rad, turn, ok) -> tuple:
    """
    Return the within-turn scatter of ``bearing + degrees(imu_yaw)`` (constant in a perfect turn).

    Parameters
    ----------
    bearing_deg, imu_yaw_rad, turn, ok : array_like
        (S,) estimated bearings [deg], IMU yaw [rad], turn labels, and which estimates count.

    Returns
    -------
    tuple
        ``(rms_deg, n)``: the rms over counted samples of their deviation from their turn's
        circular mean (turns with fewer than 3 counted samples left out), and how many counted.

    """
    b = np.asarray(bearing_deg, dtype=float)
    ok = np.asarray(ok, dtype=bool) & np.isfinite(b)
    c = np.radians(b + np.degrees(np.asarray(imu_yaw_rad, dtype=float)))
    turn = np.asarray(turn)
    dev = []
    for t in np.unique(turn[ok]):
        sel = ok & (turn == t)
        if sel.sum() < 3:
            continue
        mean = math.atan2(float(np.mean(np.sin(c[sel]))), float(np.mean(np.cos(c[sel]))))
        dev.append(np.degrees(np.angle(np.exp(1j * (c[sel] - mean)))))
    if not dev:
        return math.nan, 0
    d = np.concatenate(dev)
    return float(np.sqrt(np.mean(d**2))), int(d.size)


def _sky_gate(singles: list, n: int, max_sky_misfit_deg: float) -> tuple:
    """
    Return the recordings whose sky misfits, and one line for each.

    Parameters
    ----------
    singles : list of (int, MountFit)
        Each recording's own fit, by its index (those that determine a mount alone).
    n : int
        How many recordings there are.
    max_sky_misfit_deg : float
        The bound [deg] on ``MountFit.sky_misfit_deg``.

    Returns
    -------
    tuple
        ``(out, notes)``: the set of indices left out and their lines.

    Raises
    ------
    MountFitError
        Every recording left out.

    """
    out = {i for i, s in singles if s.sky_misfit_deg > max_sky_misfit_deg}
    notes = [
        f'recording {i + 1}: the sky misfit {s.sky_misfit_deg:.1f} deg (median) > '
        f'{max_sky_misfit_deg:g}: under trees or clouds; left out of the mount'
        for i, s in singles
        if i in out
    ]
    if len(out) == n:
        raise MountFitError(
            'cannot calibrate the mount: the sky of every recording misfits the single-scattering '
            f'model (median > {max_sky_misfit_deg:g} deg: trees or clouds); calibrate from turns '
            'under a clear, open sky'
        )
    return out, notes


def fit_mount_recordings(
    geometry,
    parts: list,
    max_disagreement_deg: float = MAX_DISAGREEMENT_DEG,
    max_sky_misfit_deg: float = MAX_SKY_MISFIT_DEG,
    **limits,
) -> MountFit:
    """
    Fit the mount from several recordings, widening its sigmas by how much they disagree.

    Each recording is first fitted alone: one whose sky misfits the single-scattering model by
    more than ``max_sky_misfit_deg`` (median, ``MountFit.sky_misfit_deg``) is left out, with one
    line in ``warning`` naming it and its misfit; if all are, the fit is refused. The others are
    fitted together (:func:`fit_mount`) and, from two on, compared; a
    sigma is the larger of the joint fit's and the Birge-scaled sigma of the single fits' weighted
    mean, ``sqrt(chi2 / (n - 1)) / sqrt(sum 1 / sigma_i^2)`` with chi2 of the single fits about
    the joint one (a sky that is not clear biases a recording's mount beyond its own sigma). When
    the single mounts differ by more than 3 of their combined sigmas on an axis but by at most
    ``max_disagreement_deg``, the joint fit is kept with the widened sigmas and ``warning`` names
    each recording's mount; further apart, the recordings are refused.

    Parameters
    ----------
    geometry : ArrayGeometry or CameraRays
        The sensor description.
    parts : list of TurnSamples
        One per recording, turn labels distinct across them.
    max_disagreement_deg : float, optional
        Largest difference [deg] of two recordings' own pitch (or roll) fitted together.
    max_sky_misfit_deg : float, optional
        Largest sky misfit [deg] of a recording fitted (:data:`MAX_SKY_MISFIT_DEG`).
    **limits
        The limits of :func:`fit_mount`.

    Returns
    -------
    MountFit
        The joint fit of the recordings kept, sigmas widened; ``spread`` the Birge ratios (pitch,
        roll); ``used`` and ``left_out`` the recordings (1-based) fitted and left out.

    Raises
    ------
    MountFitError
        The joint fit refused, every recording's sky misfits, or the recordings kept disagree by
        more than ``max_disagreement_deg``.

    """
    singles = []
    for i, p in enumerate(parts):
        try:
            singles.append((i, fit_mount(geometry, p, **{**limits, 'max_sigma_deg': 90.0})))
        except MountFitError:
            continue  # a recording that cannot determine the mount alone still counts jointly
    out, notes = _sky_gate(singles, len(parts), max_sky_misfit_deg)
    kept = [i for i in range(len(parts)) if i not in out]
    singles = [(i, s) for i, s in singles if i not in out]
    fit = fit_mount(geometry, concat([parts[i] for i in kept]), **limits)
    fit.used = tuple(i + 1 for i in kept)
    fit.left_out = tuple(sorted(i + 1 for i in out))
    fit.warning = '\n'.join(notes)
    if len(singles) < 2:
        return fit
    m = fit.mount
    ratios, gaps, combined, tense = [], [], [], False
    for key in ('pitch', 'roll'):
        x = np.array([getattr(s.mount, f'{key}_deg') for _, s in singles])
        sx = np.array([getattr(s.mount, f'{key}_sigma_deg') for _, s in singles])
        chi2 = float(np.sum(((x - getattr(m, f'{key}_deg')) / sx) ** 2)) / (len(singles) - 1)
        ratios.append(max(1.0, math.sqrt(chi2)))
        gaps.append(float(np.ptp(x)))
        combined.append(sx)
        i, j = int(np.argmin(x)), int(np.argmax(x))
        tense |= x[j] - x[i] > 3.0 * math.hypot(sx[i], sx[j])
    each = '; '.join(
        f'recording {i + 1}: pitch {s.mount.pitch_deg:.1f} +- {s.mount.pitch_sigma_deg:.1f}, '
        f'roll {s.mount.roll_deg:.1f} +- {s.mount.roll_sigma_deg:.1f}'
        for i, s in singles
    )
    if max(gaps) > max_disagreement_deg:
        raise MountFitError(
            f'cannot calibrate the mount: the recordings disagree by {max(gaps):.1f} deg > '
            f'{max_disagreement_deg:g} ({each} deg); calibrate from turns under a clear, open sky '
            '(trees and clouds bias the fit)'
        )
    sig = [
        max(getattr(m, f'{key}_sigma_deg'), r / math.sqrt(float(np.sum(1.0 / sx**2))))
        for key, r, sx in zip(('pitch', 'roll'), ratios, combined)
    ]
    fit.mount = Mount(m.pitch_deg, m.roll_deg, sig[0], sig[1])
    fit.spread = (ratios[0], ratios[1])
    if tense:
        notes.append(
            f'warning: the recordings disagree ({each} deg): the sigmas are widened by '
            f'{ratios[0]:.1f} (pitch) and {ratios[1]:.1f} (roll); a mount from turns under a '
            'clear, open sky alone is better'
        )
    fit.warning = '\n'.join(notes)
    return fit
