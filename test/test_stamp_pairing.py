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
stamp_pairing.StampPairer: arrays paired with their companion headers (ROS-free).

The node keys both messages by their arrival time. The oracle is the documented rule, computed here
from the simulated driver and transport and not from the pairer's queues: a driver at 10 Hz
publishes each sample's header and array together; on-time messages arrive within a few ms; one of
the two topics may stall (messages lost, or late: arriving between two samples, and holding back
what follows on that topic, FIFO). Then sample k is paired -- with its own stamp and frame --
exactly when both its messages arrive within the tolerance of each other; every array that arrives
is either paired or counted once as a drop, every header likewise; nothing stays queued.
"""

import math

from hypothesis import given, settings
from hypothesis import strategies as st
from polarization_compass.stamp_pairing import StampPairer
import pytest

TOL_S, TIMEOUT_S = 0.02, 0.5
PERIOD_S = 0.1  # 10 Hz driver: more than 2 x the tolerance
JITTER_S = 0.005  # on-time transport delay


@st.composite
def runs(draw):
    n = draw(st.integers(1, 25))
    stalling = draw(st.sampled_from(['header', 'array']))  # the topic that may be late
    samples = []
    for k in range(n):
        pub = 1000.0 + k * PERIOD_S
        lost_a, lost_h = (
            draw(st.booleans()) and draw(st.booleans()),
            draw(st.booleans()) and draw(st.booleans()),
        )
        on_time = st.floats(0.0, JITTER_S)
        # late: m sample intervals and a half later (between two samples, never within the
        # tolerance of one)
        late = st.builds(
            lambda m, e: m * PERIOD_S + PERIOD_S / 2 + e,
            st.integers(0, 8),
            st.floats(-JITTER_S, JITTER_S),
        )
        d_late = draw(st.one_of(on_time, on_time, late))
        d_a, d_h = (draw(on_time), d_late) if stalling == 'header' else (d_late, draw(on_time))
        zero = draw(st.integers(0, 19)) == 0  # a driver that forgot the stamp
        samples.append(
            {
                'k': k,
                'pub': pub,
                'lost_a': lost_a,
                'lost_h': lost_h,
                'd_a': d_a,
                'd_h': d_h,
                'stamp': 0 if zero else 5_000_000_000 + 7 * k,
            }
        )
    return samples


def _arrivals(samples, delay_key, lost_key):
    """
    Return the arrival times of one topic (FIFO per topic).

    One writer per topic, so a stall delays what follows it too.
    """
    out, last = {}, -math.inf
    for s in samples:
        if s[lost_key]:
            continue
        last = max(last, s['pub'] + s[delay_key])
        out[s['k']] = last
    return out


@settings(max_examples=300, deadline=None)
@given(runs())
def test_pairs_exactly_the_samples_whose_header_arrived_with_them(samples):
    arr_a = _arrivals(samples, 'd_a', 'lost_a')
    arr_h = _arrivals(samples, 'd_h', 'lost_h')
    by_k = {s['k']: s for s in samples}
    # all arrivals of both topics, in arrival order (ties: either order is possible; take headers
    # first)
    events = sorted([(t, 1, k) for k, t in arr_a.items()] + [(t, 0, k) for k, t in arr_h.items()])
    p = StampPairer(TOL_S, TIMEOUT_S)
    got = []
    for t, is_array, k in events:
        p.expire(t)  # the node's timer runs between callbacks
        key = int(round(t * 1e9))
        if is_array:
            got += p.add_array(key, t, k)
        else:
            got += p.add_header(key, t, by_k[k]['stamp'], f'frame{k}')
    p.expire(math.inf)
    # never a wrong stamp or frame: a paired sample carries its own header's
    for g in got:
        assert g.stamp_ns == by_k[g.payload]['stamp'] and g.frame_id == f'frame{g.payload}'
    expected = sorted(
        k
        for k in set(arr_a) & set(arr_h)
        if abs(arr_a[k] - arr_h[k]) <= TOL_S and by_k[k]['stamp'] != 0
    )
    assert [g.payload for g in got] == expected  # all of them, in order
    # every array is accounted for once: paired, dropped without header / timed out, or its header
    # had no stamp
    zero_paired = p.drops['header_zero_stamp']
    assert len(got) + p.drops['no_header'] + p.drops['header_timeout'] + zero_paired == len(arr_a)
    assert len(got) + p.drops['header_without_array'] + zero_paired == len(arr_h)
    assert p.pending_arrays == 0


def test_late_header_is_not_given_to_the_next_sample():
    """
    A late header is not given to the next sample.

    Header 0 arrives after array 0 timed out and after array 1 arrived: array 0 is dropped
    (header_timeout), header 0 discarded, array 1 waits for and gets header 1.
    """
    p = StampPairer(0.02, 0.5)
    assert p.add_array(1_000_000_000, 10.0, 'a0') == []
    p.expire(10.6)
    assert p.drops['header_timeout'] == 1
    assert p.add_array(1_100_000_000, 10.7, 'a1') == []
    assert p.add_header(1_000_000_000, 10.8, 111, 'f') == []  # header 0, late
    assert p.drops['header_without_array'] == 1
    (s,) = p.add_header(1_100_000_000, 10.81, 222, 'f')
    assert (s.payload, s.stamp_ns) == ('a1', 222)


def test_a_lost_header_drops_only_its_array():
    p = StampPairer(0.02, 0.5)
    p.add_array(1_000_000_000, 1.0, 'a0')  # header 0 lost
    p.add_array(1_100_000_000, 1.1, 'a1')
    (s,) = p.add_header(1_105_000_000, 1.1, 222, 'f')  # header 1, 5 ms after its array
    assert (s.payload, s.stamp_ns) == ('a1', 222) and p.drops == {'no_header': 1}


def test_queue_is_bounded_and_counts_overflow():
    p = StampPairer(0.02, 100.0, max_pending=3)
    for k in range(5):
        p.add_array(k * 100_000_000, 0.0, k)
    assert p.pending_arrays == 3 and p.drops['queue_full'] == 2


@pytest.mark.parametrize(
    'args', [(-0.1, 0.5, 10), (0.02, -1.0, 10), (0.02, 0.5, 0), (math.nan, 0.5, 10)]
)
def test_bad_settings_are_refused(args):
    with pytest.raises(ValueError):
        StampPairer(*args)
