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
The stamp matching behind ``error_evaluator``: estimates paired with the truth (ROS-free).

:class:`StampMatcher` pairs estimates with the ground truth by identical stamp (the estimator
stamps its output with the image's stamp, and the simulator stamps the truth with the same stamp):
an estimate that arrives before its truth waits (bounded), a truth frame without an estimate on a
stream after ``horizon_ns`` counts as *missed* for that stream.

Each stream's errors accumulate in a :class:`~polarization_compass.evaluation_stats.RunningStats`
(:mod:`polarization_compass.evaluation_stats`, which also holds the error convention); the report
files are :mod:`polarization_compass.evaluation_report`'s.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field
import math

from .evaluation_stats import EvaluationError, heading_error_deg, RunningStats

__all__ = [
    'StampMatcher',
    'Match',
    'YawTrack',
    'not_received',
]


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
