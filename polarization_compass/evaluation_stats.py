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
Heading errors and their running statistics (ROS-free): what the evaluator measures.

Error convention (the paper's): ``error_deg = estimated bearing - true bearing``, which equals
``estimated psi - true psi``; wrapped to (-180, 180] for a method that resolves the 180 deg
ambiguity, folded to (-90, 90] (:func:`~polarization_compass.conventions.fold_axial_deg`) for an
axial one, where a heading and its opposite are the same measurement. Statistics of a stream:

``count``   matched estimates
``mean``    mean signed error (deg)              ``std``  its standard deviation (deg)
``rms``     sqrt(mean(error^2)) (deg)            ``p95``  95th percentile of |error| (deg)
``max``     max |error| (deg)

Every sample is kept up to ``max_samples`` (default 2 million, 16 MB), so ``p95`` is exact for any
run this project simulates; beyond that, percentiles come from a uniform reservoir sample of that
size (deterministic seed) while count, mean, RMS, std and max stay exact.

The stamp matching that feeds them is :mod:`polarization_compass.evaluation`.
"""

from __future__ import annotations

import math

import numpy as np

from .conventions import fold_axial_deg, wrap_180_deg
from .errors import CompassError

__all__ = [
    'EvaluationError',
    'RunningStats',
    'STAT_FIELDS',
    'heading_error_deg',
]

STAT_FIELDS = ('count', 'mean', 'std', 'rms', 'p95', 'max')


class EvaluationError(CompassError):
    """Bad evaluator input (non-finite angle, unknown stream)."""


def heading_error_deg(estimated_bearing_deg, true_bearing_deg, axial: bool):
    """
    Return the estimated minus the true bearing, wrapped or folded.

    Parameters
    ----------
    estimated_bearing_deg : float or array_like
        Estimated bearing of camera +y [deg], clockwise from North.
    true_bearing_deg : float or array_like
        True bearing [deg], same frame; broadcast with the estimate.
    axial : bool
        True for a method that does not resolve the 180 deg ambiguity: the error is folded to
        (-90, 90] (:func:`~polarization_compass.conventions.fold_axial_deg`); else wrapped to
        (-180, 180].

    Returns
    -------
    float or numpy.ndarray
        Signed heading error [deg].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4 and
       Figs 17-19 (orientation error against the heading).

    """
    d = np.asarray(estimated_bearing_deg, dtype=float) - np.asarray(true_bearing_deg, dtype=float)
    return fold_axial_deg(d) if axial else wrap_180_deg(d)


class RunningStats:
    """
    Accumulate mean, std, RMS, p95 and max of signed errors (deg), one sample at a time.

    Sums are accumulated with Welford's update (mean and variance) so that long runs do not lose
    precision; ``max`` and the sample store are updated in O(1) amortised time. Beyond
    ``max_samples`` the percentiles come from a uniform reservoir sample (Vitter's algorithm R).

    Parameters
    ----------
    max_samples : int, default 2_000_000
        Samples kept for the percentiles (8 bytes each); >= 1, else :class:`EvaluationError`.
    seed : int, default 0
        Seed of the reservoir sampling (deterministic summaries).

    """

    def __init__(self, max_samples: int = 2_000_000, seed: int = 0):
        if max_samples < 1:
            raise EvaluationError('max_samples must be >= 1')
        self.max_samples = int(max_samples)
        self.count = 0
        self._mean = 0.0
        self._m2 = 0.0  # sum of squared deviations from the mean (Welford)
        self._sumsq = 0.0
        self._max_abs = 0.0
        self._buf = np.empty(min(1024, self.max_samples), dtype=float)
        self._stored = 0
        self._rng = np.random.default_rng(seed)

    def add(self, error_deg: float) -> None:
        """
        Add one signed error.

        Parameters
        ----------
        error_deg : float
            Signed heading error [deg] (see :func:`heading_error_deg`).

        Raises
        ------
        EvaluationError
            The error is NaN or infinite (nothing is recorded).

        """
        e = float(error_deg)
        if not math.isfinite(e):
            raise EvaluationError(f'non-finite error {error_deg!r}')
        self.count += 1
        delta = e - self._mean
        self._mean += delta / self.count
        self._m2 += delta * (e - self._mean)
        self._sumsq += e * e
        self._max_abs = max(self._max_abs, abs(e))
        if self._stored < self.max_samples:
            if self._stored == self._buf.size:
                grown = np.empty(min(self.max_samples, 2 * self._buf.size), dtype=float)
                grown[: self._stored] = self._buf[: self._stored]
                self._buf = grown
            self._buf[self._stored] = e
            self._stored += 1
        else:  # reservoir sampling (Vitter's algorithm R)
            j = int(self._rng.integers(0, self.count))
            if j < self.max_samples:
                self._buf[j] = e

    def extend(self, errors_deg) -> None:
        """
        Add every error of an array, in order, as :meth:`add` does.

        Parameters
        ----------
        errors_deg : array_like
            Signed heading errors [deg], any shape (read flattened).

        """
        for e in np.asarray(errors_deg, dtype=float).reshape(-1):
            self.add(e)

    @property
    def samples(self) -> np.ndarray:
        """Read-only view of the stored errors [deg]: all of them while count <= max_samples."""
        v = self._buf[: self._stored]
        v.setflags(write=False)
        return v

    @property
    def exact_percentiles(self) -> bool:
        """Whether ``p95`` is exact (every sample kept) rather than from the reservoir."""
        return self.count <= self.max_samples

    def summary(self) -> dict:
        """
        Return the statistics of the errors added so far.

        Returns
        -------
        dict
            ``{"count": int, "mean", "std", "rms", "p95", "max": float [deg]}`` (``std`` is
            the population standard deviation, ``p95`` and ``max`` of |error|); zeros, never
            NaN, for an empty stream.

        """
        if self.count == 0:
            return {k: 0 if k == 'count' else 0.0 for k in STAT_FIELDS}
        p95 = float(np.percentile(np.abs(self._buf[: self._stored]), 95.0))
        return {
            'count': self.count,
            'mean': self._mean,
            'std': math.sqrt(max(self._m2, 0.0) / self.count),
            'rms': math.sqrt(self._sumsq / self.count),
            'p95': p95,
            'max': self._max_abs,
        }
