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
player_flow's backlog count (ROS-free), and its pause and resume decisions at the water marks.

The count: frames the player published that an estimator has not answered yet, from stamps alone.
The node itself runs against the real ``ros2 bag play`` in test_rosbag2.py.
"""

from hypothesis import given, settings
from hypothesis import strategies as st
from polarization_compass.nodes.player_flow import Backlog
import pytest

S = 100_000_000  # 10 Hz frame spacing [ns]


def test_behind_counts_the_frames_after_each_estimators_newest_answer():
    b = Backlog(['a', 'b'], high_water=6, low_water=2)
    for k in range(1, 11):
        b.published(k * S)
    b.answered('a', 3 * S)
    b.answered('b', 8 * S)
    assert b.behind() == {'a': 7, 'b': 2}
    assert b.should_pause() and not b.may_resume()
    b.answered('a', 9 * S)
    assert b.behind() == {'a': 1, 'b': 2}
    assert not b.should_pause() and b.may_resume()


def test_an_estimator_that_never_answered_is_behind_by_everything_published():
    b = Backlog(['a', 'b'], high_water=3, low_water=1)
    for k in range(1, 4):
        b.published(k * S)
    b.answered('a', 3 * S)
    assert b.behind() == {'a': 0, 'b': 3}
    assert b.should_pause()


def test_a_frame_lost_on_the_way_does_not_hold_the_player():
    b = Backlog(['a'], high_water=2, low_water=0)
    for k in range(1, 6):
        b.published(k * S)
    b.answered('a', 2 * S)
    b.answered('a', 4 * S)  # frame 3 never reached the estimator: no status for it
    assert b.behind() == {'a': 1}
    b.answered('a', 5 * S)
    assert b.behind() == {'a': 0} and b.may_resume()


def test_late_duplicate_and_unknown_stamps_change_nothing():
    b = Backlog(['a'], high_water=2, low_water=0)
    for k in (1, 2, 2, 1, 3):  # a repeated or older camera_info is not a new frame
        b.published(k * S)
    assert b.behind() == {'a': 3}
    b.answered('a', 2 * S)
    b.answered('a', 1 * S)  # an older status does not move the estimator back
    b.answered('zz', 3 * S)  # not an estimator this node watches
    assert b.behind() == {'a': 1}


@pytest.mark.parametrize('high, low', [(2, 2), (1, 3), (3, -1)])
def test_water_marks_must_be_ordered(high, low):
    with pytest.raises(ValueError, match='low_water < high_water'):
        Backlog(['a'], high_water=high, low_water=low)


@settings(max_examples=200, deadline=None)
@given(
    published=st.lists(st.integers(0, 50), max_size=60),
    answers=st.lists(st.tuples(st.sampled_from('ab'), st.integers(0, 50)), max_size=60),
)
def test_behind_matches_a_direct_count(published, answers):
    """Against a direct count over all stamps: frames published after the newest answer."""
    b = Backlog(['a', 'b'], high_water=5, low_water=1)
    pub, done = [], {'a': None, 'b': None}
    events = [('p', s) for s in published] + [('s', n, s) for n, s in answers]
    for ev in sorted(events, key=lambda e: (e[-1], e[0])):  # in time order, answers after
        if ev[0] == 'p':
            b.published(ev[1] * S)
            if not pub or ev[1] > pub[-1]:
                pub.append(ev[1])
        else:
            b.answered(ev[1], ev[2] * S)
            done[ev[1]] = max(ev[2], done[ev[1]] if done[ev[1]] is not None else -1)
    want = {n: sum(1 for s in pub if d is None or s > d) for n, d in done.items()}
    assert b.behind() == want
    assert b.should_pause() == (max(want.values()) >= 5)
