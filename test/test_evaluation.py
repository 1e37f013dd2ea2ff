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

"""ROS-free running error statistics and stamp matching against independent numpy computations."""

import csv
import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass.evaluation import StampMatcher
from polarization_compass.evaluation_report import (
    plot_report,
    write_samples_csv,
    write_summary_csv,
)
from polarization_compass.evaluation_stats import EvaluationError, heading_error_deg, RunningStats
import pytest


def test_running_stats_match_numpy():
    rng = np.random.default_rng(1)
    x = rng.normal(0.3, 2.0, 5001)
    s = RunningStats()
    for v in x:
        s.add(v)
    d = s.summary()
    assert d['count'] == x.size
    assert d['mean'] == pytest.approx(np.mean(x), abs=1e-12)
    assert d['std'] == pytest.approx(np.std(x), rel=1e-12)
    assert d['rms'] == pytest.approx(math.sqrt(np.mean(x * x)), rel=1e-12)
    assert d['max'] == pytest.approx(np.max(np.abs(x)))
    assert d['p95'] == pytest.approx(np.percentile(np.abs(x), 95))


def test_welford_keeps_precision_with_a_large_offset():
    # naive sum-of-squares loses everything here; Welford keeps the spread
    x = 1e8 + np.array([0.1, 0.2, 0.3, 0.4])
    s = RunningStats()
    s.extend(x)
    assert s.summary()['std'] == pytest.approx(np.std(x - 1e8), rel=1e-6)


def test_empty_stream_has_zeros_not_nan():
    d = RunningStats().summary()
    assert d == {'count': 0, 'mean': 0.0, 'std': 0.0, 'rms': 0.0, 'p95': 0.0, 'max': 0.0}


def test_reservoir_keeps_exact_moments_and_a_close_percentile():
    rng = np.random.default_rng(2)
    x = rng.uniform(-10, 10, 20000)
    s = RunningStats(max_samples=2000)
    s.extend(x)
    d = s.summary()
    assert not s.exact_percentiles
    assert d['count'] == 20000
    assert d['rms'] == pytest.approx(math.sqrt(np.mean(x * x)), rel=1e-12)
    assert d['max'] == pytest.approx(np.max(np.abs(x)))
    # |x| uniform on [0, 10]: p95 = 9.5; a 2000-sample reservoir is within a few tenths
    assert abs(d['p95'] - 9.5) < 0.3


def test_non_finite_error_is_refused():
    with pytest.raises(EvaluationError):
        RunningStats().add(float('nan'))


@given(
    truth=st.floats(0, 360, exclude_max=True),
    err=st.floats(-89.9, 89.9),
    flips=st.integers(-3, 3),
    turns=st.integers(-2, 2),
)
def test_axial_error_ignores_half_turns(truth, err, flips, turns):
    est = truth + err + 180.0 * flips + 360.0 * turns
    assert float(heading_error_deg(est, truth, axial=True)) == pytest.approx(err, abs=1e-9)
    if flips % 2 == 0:
        assert float(heading_error_deg(est, truth, axial=False)) == pytest.approx(err, abs=1e-9)
    else:  # a flipped heading is a 180 deg error for a method that claims to resolve the ambiguity
        assert abs(float(heading_error_deg(est, truth, axial=False))) == pytest.approx(
            180.0 - abs(err), abs=1e-9
        )


def test_error_wraps_across_north():
    assert float(heading_error_deg(1.0, 359.0, axial=False)) == pytest.approx(2.0)
    assert float(heading_error_deg(359.0, 1.0, axial=False)) == pytest.approx(-2.0)


def test_matcher_pairs_by_stamp_in_any_order_and_counts_misses():
    m = StampMatcher(horizon_ns=1_000)
    m.add_stream('a/raw', axial=False)
    m.add_stream('b/raw', axial=True)
    # estimate before truth: waits
    assert m.add_estimate('a/raw', 100, 11.0) is None
    done = m.add_truth(100, 10.0)
    assert [(x.stream, x.error_deg) for x in done] == [('a/raw', pytest.approx(1.0))]
    # truth first, then the estimate (axial stream: a flipped estimate counts as its axial error)
    m.add_truth(200, 20.0)
    got = m.add_estimate('b/raw', 200, 20.0 + 180.0 + 0.5)
    assert got.error_deg == pytest.approx(0.5) and got.axial
    # stamp 100 never answered on b, 200 never on a; both expire once stamps move past the horizon
    m.add_truth(5_000, 0.0)
    s = m.summary()
    assert s['a/raw']['missed'] >= 1 and s['b/raw']['missed'] >= 1
    m.finish()
    s = m.summary()
    # truth frames: 100, 200, 5000; a answered 100 only, b answered 200 only
    assert s['a/raw']['missed'] == 2 and s['b/raw']['missed'] == 2
    assert s['a/raw']['matched'] == 1 and s['b/raw']['matched'] == 1


def test_matcher_counts_estimates_whose_truth_never_came():
    m = StampMatcher(horizon_ns=10)
    m.add_stream('x', axial=False)
    m.add_estimate('x', 1, 0.0)
    m.add_estimate('x', 100, 0.0)  # pushes stamp 1 past the horizon
    m.finish()
    assert m.summary()['x']['unmatched'] == 2
    with pytest.raises(EvaluationError):
        m.add_estimate('nope', 1, 0.0)


def test_reports_are_written_and_read_back(tmp_path):
    m = StampMatcher()
    m.add_stream('least_squares/raw', False)
    m.add_stream('least_squares/corrected', False)
    for k in range(20):
        t = k * 100_000_000
        m.add_truth(t, k * 18.0)
        m.add_estimate(
            'least_squares/raw', t, k * 18.0 + 3.0 * math.sin(k), extra={'latency_ms': 5.0}
        )
        m.add_estimate('least_squares/corrected', t, k * 18.0 + 0.01, extra={'latency_ms': 6.0})
    with open(write_samples_csv(tmp_path / 's.csv', m.matches, ('latency_ms',))) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 40
    raw = np.array([float(r['error_deg']) for r in rows if r['stream'] == 'least_squares/raw'])
    assert raw == pytest.approx([3.0 * math.sin(k) for k in range(20)], abs=1e-5)
    with open(write_summary_csv(tmp_path / 't.csv', m.summary())) as f:
        summ = list(csv.DictReader(f))
    by = {r['stream']: r for r in summ}
    assert float(by['least_squares/raw']['rms']) == pytest.approx(
        math.sqrt(np.mean(raw**2)), abs=1e-5
    )
    assert float(by['least_squares/corrected']['max']) == pytest.approx(0.01, abs=1e-5)
    png = plot_report(tmp_path / 'r.png', m.matches, 'test')
    assert png.is_file() and png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert plot_report(tmp_path / 'none.png', []) is None


def test_yaw_track_interpolates_a_filter_output_at_the_truth_stamps():
    from polarization_compass.evaluation import YawTrack

    tr = YawTrack(max_gap_ns=500_000_000)
    tr.add_truth(50)  # before the first output: nothing to interpolate from, dropped
    assert tr.add_output(100, math.radians(179.0), 1e-4) == []
    tr.add_truth(150)  # halfway to the next output, across the +-180 deg yaw wrap
    tr.add_truth(200)  # exactly at it
    tr.add_truth(250)  # after it: waits
    got = tr.add_output(200, math.radians(-179.0), 3e-4)
    assert [g[0] for g in got] == [150, 200]
    # yaw 180 deg = bearing 270 deg; yaw -179 deg = bearing 269 deg (bearing = 90 - yaw)
    assert got[0][1] == pytest.approx(270.0) and got[1][1] == pytest.approx(269.0)
    assert got[0][2] == pytest.approx(math.degrees(math.sqrt(2e-4)))
    assert got[1][2] == pytest.approx(math.degrees(math.sqrt(3e-4)))
    # the next output is further than max_gap_ns: the stamp between is dropped, not interpolated
    assert tr.add_output(900_000_000, 0.0, 1e-4) == []


def test_not_received_is_missed_minus_the_frames_a_node_declined():
    from polarization_compass.evaluation import not_received

    streams = {
        'a/raw': {'missed': 5, 'not_published': {'ambiguous': 1, 'prior_disagrees': 1}},
        'a/corrected': {'missed': 7, 'not_published': {'no_solution': 2}},
        'b/raw': {'missed': 1, 'not_published': {'bad_input': 3}},
        'c/corrected': {'missed': 4},  # no raw stream evaluated: nothing else to subtract
    }
    assert not_received(streams, 'a/raw') == 3
    assert not_received(streams, 'a/corrected') == 3  # the estimator's 2 never reached it
    assert not_received(streams, 'b/raw') == 0  # never negative
    assert not_received(streams, 'c/corrected') == 4
