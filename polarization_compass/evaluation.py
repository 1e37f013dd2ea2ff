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
Running heading-error statistics and the stamp matching behind ``error_evaluator`` (ROS-free).

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

:class:`StampMatcher` pairs estimates with the ground truth by identical stamp (the estimator
stamps its output with the image's stamp, and the simulator stamps the truth with the same stamp):
an estimate that arrives before its truth waits (bounded), a truth frame without an estimate on a
stream after ``horizon_ns`` counts as *missed* for that stream.
"""

from __future__ import annotations

from collections import OrderedDict
import csv
from dataclasses import dataclass, field
import math
from pathlib import Path

import numpy as np

from .conventions import fold_axial_deg, wrap_180_deg
from .errors import CompassError

__all__ = [
    'RunningStats',
    'heading_error_deg',
    'StampMatcher',
    'Match',
    'EvaluationError',
    'write_samples_csv',
    'write_summary_csv',
    'plot_report',
    'STAT_FIELDS',
    'YawTrack',
    'not_received',
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


@dataclass
class Match:
    """One estimate paired with its truth."""

    stream: str
    stamp_ns: int
    true_bearing_deg: float
    estimated_bearing_deg: float
    error_deg: float
    axial: bool
    extra: dict = field(default_factory=dict)


@dataclass
class _Stream:
    name: str
    axial: bool
    stats: RunningStats
    received: int = 0
    matched: int = 0
    unmatched: int = 0  # estimates whose truth never arrived (dropped from the wait buffer)
    missed: int = 0  # truth frames that got no estimate on this stream within the horizon
    pending: OrderedDict = field(default_factory=OrderedDict)  # stamp_ns -> (bearing, extra)
    seen: set = field(default_factory=set)  # stamps matched, for miss accounting


class StampMatcher:
    """
    Pair estimates with truth by identical stamp and keep one :class:`RunningStats` per stream.

    Parameters
    ----------
    horizon_ns : int, default 5_000_000_000
        How long [ns of stamp time] a truth frame waits for each stream before it is counted as
        missed there, and how long an early estimate waits for its truth; > 0.
    max_pending : int, default 1000
        Early estimates kept per stream (bounds memory); > 0. The oldest beyond it is dropped and
        counted as unmatched.
    max_samples : int, default 2_000_000
        ``max_samples`` of each stream's :class:`RunningStats`.

    """

    def __init__(
        self,
        horizon_ns: int = 5_000_000_000,
        max_pending: int = 1000,
        max_samples: int = 2_000_000,
    ):
        if horizon_ns <= 0 or max_pending <= 0:
            raise EvaluationError('horizon_ns and max_pending must be positive')
        self.horizon_ns = int(horizon_ns)
        self.max_pending = int(max_pending)
        self.max_samples = int(max_samples)
        self.truth: OrderedDict = OrderedDict()  # stamp_ns -> true bearing
        self.truth_count = 0
        self.streams: dict[str, _Stream] = {}
        self.matches: list[Match] = []
        self._latest_ns = None

    def add_stream(self, name: str, axial: bool) -> None:
        """
        Declare a stream (an estimator output); declaring one twice keeps the first.

        Parameters
        ----------
        name : str
            Stream name, e.g. ``"zenith/raw"``.
        axial : bool
            Whether its errors are folded to (-90, 90] (a method with a 180 deg ambiguity).

        """
        if name not in self.streams:
            self.streams[name] = _Stream(name, bool(axial), RunningStats(self.max_samples))

    def add_truth(self, stamp_ns: int, true_bearing_deg: float) -> list[Match]:
        """
        Record a truth sample and return the matches it completes.

        Parameters
        ----------
        stamp_ns : int
            Stamp [ns] of the image the truth belongs to.
        true_bearing_deg : float
            True bearing of camera +y [deg], clockwise from North.

        Returns
        -------
        list of Match
            Estimates with this stamp that arrived first; empty when the stamp is known already.

        Raises
        ------
        EvaluationError
            The true bearing is NaN or infinite.

        """
        b = float(true_bearing_deg)
        if not math.isfinite(b):
            raise EvaluationError('non-finite true bearing')
        stamp_ns = int(stamp_ns)
        if stamp_ns in self.truth:
            return []
        self.truth[stamp_ns] = b
        self.truth_count += 1
        out = []
        for s in self.streams.values():
            if stamp_ns in s.pending:
                est, extra, ax = s.pending.pop(stamp_ns)
                out.append(self._match(s, stamp_ns, est, extra, ax))
        self._advance(stamp_ns)
        return out

    def add_estimate(
        self,
        stream: str,
        stamp_ns: int,
        bearing_deg: float,
        axial: bool = False,
        extra: dict | None = None,
    ) -> Match | None:
        """
        Record an estimate and return its :class:`Match` when the truth is known already.

        The error is folded (axial) when the stream was declared axial or this estimate says so.

        Parameters
        ----------
        stream : str
            A stream declared with :meth:`add_stream`.
        stamp_ns : int
            Stamp [ns] of the image the estimate was computed from.
        bearing_deg : float
            Estimated bearing of camera +y [deg], clockwise from North.
        axial : bool, default False
            Fold this estimate's error to (-90, 90].
        extra : dict, optional
            Extra columns carried into the :class:`Match` (e.g. status, sigma).

        Returns
        -------
        Match or None
            The match, or None while the estimate waits for its truth.

        Raises
        ------
        EvaluationError
            Unknown stream, or a NaN or infinite bearing.

        """
        if stream not in self.streams:
            raise EvaluationError(f'unknown stream {stream!r}')
        b = float(bearing_deg)
        if not math.isfinite(b):
            raise EvaluationError('non-finite estimated bearing')
        s = self.streams[stream]
        s.received += 1
        stamp_ns = int(stamp_ns)
        ax = bool(axial)
        if stamp_ns in self.truth:
            return self._match(s, stamp_ns, b, extra or {}, ax)
        s.pending[stamp_ns] = (b, extra or {}, ax)
        while len(s.pending) > self.max_pending:
            s.pending.popitem(last=False)
            s.unmatched += 1
        self._advance(stamp_ns)
        return None

    def _match(self, s: _Stream, stamp_ns: int, est: float, extra: dict, axial: bool) -> Match:
        truth = self.truth[stamp_ns]
        ax = s.axial or axial
        err = float(heading_error_deg(est, truth, ax))
        s.stats.add(err)
        s.matched += 1
        s.seen.add(stamp_ns)
        m = Match(s.name, stamp_ns, truth, est, err, ax, dict(extra))
        self.matches.append(m)
        return m

    def _advance(self, stamp_ns: int) -> None:
        """Expire truth frames and early estimates older than the horizon (in stamp time)."""
        if self._latest_ns is None or stamp_ns > self._latest_ns:
            self._latest_ns = stamp_ns
        cutoff = self._latest_ns - self.horizon_ns
        while self.truth:
            t0 = next(iter(self.truth))
            if t0 >= cutoff:
                break
            self.truth.popitem(last=False)
            for s in self.streams.values():
                if t0 in s.seen:
                    s.seen.discard(t0)
                else:
                    s.missed += 1
        for s in self.streams.values():
            while s.pending:
                t0 = next(iter(s.pending))
                if t0 >= cutoff:
                    break
                s.pending.popitem(last=False)
                s.unmatched += 1

    def finish(self) -> None:
        """End of run: every truth frame still waiting counts as missed where nothing came."""
        for t0 in list(self.truth):
            for s in self.streams.values():
                if t0 in s.seen:
                    s.seen.discard(t0)
                else:
                    s.missed += 1
        self.truth.clear()
        for s in self.streams.values():
            s.unmatched += len(s.pending)
            s.pending.clear()

    def missed_so_far(self, stream: str) -> int:
        """
        Return the truth frames received so far without an estimate on ``stream``.

        Parameters
        ----------
        stream : str
            A declared stream.

        Returns
        -------
        int
            Missed frames, those still waiting within the horizon included.

        """
        s = self.streams[stream]
        waiting = sum(1 for t in self.truth if t not in s.seen)
        return s.missed + waiting

    def summary(self) -> dict:
        """
        Return the statistics and counts of every stream.

        Returns
        -------
        dict
            ``{stream: {count, mean, std, rms, p95, max [deg], received, matched, missed,
            unmatched, axial}}`` (see :meth:`RunningStats.summary`).

        """
        out = {}
        for name, s in self.streams.items():
            d = s.stats.summary()
            d.update(
                received=s.received,
                matched=s.matched,
                missed=self.missed_so_far(name),
                unmatched=s.unmatched,
                axial=s.axial,
            )
            out[name] = d
        return out


def not_received(streams: dict, name: str) -> int:
    """
    Return the missed frames of a stream that no node declined: lost on the way.

    A truth frame is missed on a stream when no estimate came for it; a node that declines a
    frame says so on its status topic (the evaluator's ``not_published`` reasons). The rest never
    reached a node, or its output never reached the evaluator (transport loss, e.g. best-effort
    images dropped behind a slow estimator). For ``<m>/corrected`` the estimator's reasons count
    too: a heading the estimator declined never reaches the corrector.

    Parameters
    ----------
    streams : dict
        The evaluator's summary ``streams``: ``{stream: {missed, not_published, ...}}``.
    name : str
        The stream.

    Returns
    -------
    int
        Missed minus the declined frames, at least 0 (a declined frame without a truth frame is
        not among the missed).

    """
    d = streams[name]
    declined = sum(d.get('not_published', {}).values())
    method, _, kind = name.partition('/')
    if kind == 'corrected':
        declined += sum(streams.get(f'{method}/raw', {}).get('not_published', {}).values())
    return max(0, int(d['missed']) - declined)


# ------------------------------------------------------------------------------------------------
# Report files
# ------------------------------------------------------------------------------------------------
class YawTrack:
    """
    Sample a filter's yaw output at the truth stamps, by linear interpolation.

    A state estimator (robot_localization's ``/odometry/filtered``) publishes at its own rate and
    stamps, not at the camera frames': each truth stamp is scored with the filter's yaw
    interpolated between the two outputs around it (the shorter way round the circle).

    Parameters
    ----------
    max_gap_ns : int, default 1_000_000_000
        Outputs further apart than this [ns] are not interpolated across: the truth stamps
        between them get no estimate (missed).

    """

    def __init__(self, max_gap_ns: int = 1_000_000_000):
        self.max_gap_ns = int(max_gap_ns)
        self._prev = None  # (stamp ns, yaw ENU rad, yaw variance rad^2)
        self._waiting: list[int] = []

    def add_truth(self, stamp_ns: int) -> None:
        """
        Queue a truth stamp to be sampled once the filter's output has passed it.

        Parameters
        ----------
        stamp_ns : int
            Stamp [ns] of a truth frame.

        """
        self._waiting.append(int(stamp_ns))

    def add_output(self, stamp_ns: int, yaw_enu_rad: float, yaw_variance_rad2: float) -> list:
        """
        Record one filter output and return the truth stamps it completes.

        Parameters
        ----------
        stamp_ns : int
            Stamp [ns] of the output.
        yaw_enu_rad : float
            Its REP-103 yaw [rad] (ENU, counter-clockwise from East).
        yaw_variance_rad2 : float
            Its yaw variance [rad^2].

        Returns
        -------
        list of tuple
            ``(truth stamp ns, bearing_deg, sigma_deg)`` per truth stamp at or before this output
            and after the previous one (the bearing of body +x clockwise from North, in [0, 360));
            truth stamps before the previous output, or across a gap longer than ``max_gap_ns``,
            are dropped.

        """
        t1, y1, v1 = int(stamp_ns), float(yaw_enu_rad), float(yaw_variance_rad2)
        out, keep = [], []
        for ts in self._waiting:
            if ts > t1:
                keep.append(ts)
                continue
            prev = self._prev
            if ts == t1:
                y, v = y1, v1
            elif prev is None or ts < prev[0] or t1 - prev[0] > self.max_gap_ns:
                continue
            else:
                f = (ts - prev[0]) / (t1 - prev[0])
                dy = math.remainder(y1 - prev[1], 2.0 * math.pi)
                y, v = prev[1] + f * dy, prev[2] + f * (v1 - prev[2])
            bearing = (90.0 - math.degrees(y)) % 360.0
            out.append((ts, bearing, math.sqrt(max(v, 0.0)) * 180.0 / math.pi))
        self._waiting = keep
        self._prev = (t1, y1, v1)
        return out


def write_samples_csv(path, matches: list[Match], extra_fields: tuple = ()) -> Path:
    """
    Write one CSV row per matched estimate.

    Columns: ``stamp_s`` [s], ``stream``, ``true_bearing_deg``, ``estimated_bearing_deg``,
    ``error_deg`` [deg], ``axial`` (0/1), then ``extra_fields``.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory is created.
    matches : list of Match
        The matches, in the order to write.
    extra_fields : tuple of str, default ()
        Keys of :attr:`Match.extra` to add as columns (empty where a match lacks one).

    Returns
    -------
    pathlib.Path
        The file written.

    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with p.open('w', newline='') as f:
        w = csv.writer(f)
        w.writerow(
            [
                'stamp_s',
                'stream',
                'true_bearing_deg',
                'estimated_bearing_deg',
                'error_deg',
                'axial',
                *extra_fields,
            ]
        )
        for m in matches:
            w.writerow(
                [
                    f'{m.stamp_ns / 1e9:.9f}',
                    m.stream,
                    f'{m.true_bearing_deg:.6f}',
                    f'{m.estimated_bearing_deg:.6f}',
                    f'{m.error_deg:.6f}',
                    int(m.axial),
                    *[m.extra.get(k, '') for k in extra_fields],
                ]
            )
    return p


def write_summary_csv(path, summary: dict, extra: dict | None = None) -> Path:
    """
    Write one CSV row per stream with its :meth:`StampMatcher.summary` fields.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory is created.
    summary : dict
        ``{stream: fields}`` as :meth:`StampMatcher.summary` returns.
    extra : dict, optional
        ``{stream: {column: value}}``: more columns (sorted by name), empty where missing.

    Returns
    -------
    pathlib.Path
        The file written.

    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    extra = extra or {}
    extra_cols = sorted({k for v in extra.values() for k in v})
    cols = [
        'stream',
        *STAT_FIELDS,
        'received',
        'matched',
        'missed',
        'unmatched',
        'axial',
        *extra_cols,
    ]
    with p.open('w', newline='') as f:
        w = csv.writer(f)
        w.writerow(cols)
        for name, d in summary.items():
            row = [name]
            for c in cols[1:]:
                v = d.get(c, extra.get(name, {}).get(c, ''))
                row.append(
                    f'{v:.6f}' if isinstance(v, float) else (int(v) if isinstance(v, bool) else v)
                )
            w.writerow(row)
    return p


def plot_report(path, matches: list[Match], title: str = '') -> Path | None:
    """
    Plot the error against the true bearing per stream, one panel per method.

    Like the paper's Fig 17. Streams named ``<method>/raw`` and ``<method>/corrected`` share a
    panel; each legend entry gives the stream's RMS error [deg].

    Parameters
    ----------
    path : str or os.PathLike
        Output image (format from the suffix, e.g. ``.png``); its directory is created.
    matches : list of Match
        The matched estimates.
    title : str, default ""
        Figure title, none when empty.

    Returns
    -------
    pathlib.Path or None
        The file written, or None when there is nothing to plot.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4 and
       Figs 17-19 (orientation error against the heading).

    """
    if not matches:
        return None
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    by_stream: dict[str, list[Match]] = {}
    for m in matches:
        by_stream.setdefault(m.stream, []).append(m)
    methods = sorted({s.split('/')[0] for s in by_stream})
    n = len(methods)
    fig, axes = plt.subplots(
        n, 1, figsize=(8.0, 2.4 * n + 0.6), dpi=100, sharex=True, squeeze=False
    )
    for ax, method in zip(axes[:, 0], methods):
        for name in sorted(s for s in by_stream if s.split('/')[0] == method):
            ms = sorted(by_stream[name], key=lambda m: m.stamp_ns)
            x = np.array([m.true_bearing_deg for m in ms])
            y = np.array([m.error_deg for m in ms])
            label = name.split('/', 1)[1] if '/' in name else name
            ax.plot(x, y, '.', ms=3, label=f'{label} (rms {math.sqrt(float(np.mean(y * y))):.2f})')
        ax.axhline(0.0, color='0.5', lw=0.6)
        ax.set_ylabel(f'{method}\nerror, deg')
        ax.legend(loc='upper right', fontsize=7)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel('true bearing of camera +y, deg clockwise from North')
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p)
    plt.close(fig)
    return p
