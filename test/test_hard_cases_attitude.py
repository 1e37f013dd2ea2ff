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
Hard cases of attitudes and quaternions (docs/hard-cases.md).

Quaternions that are not unit, zero, NaN or inf; q and -q; gimbal lock at pitch +-90 deg; yaw wrap
at +-180 deg in the REP-103 conversions.

Covered elsewhere and not repeated:
test_conventions.py::test_bad_quaternions_are_rejected_with_reason (zero, NaN, norm 2, 3
components), ::test_attitude_gimbal_lock_is_flagged_not_nan (one locked case), ::test_rep103_yaw;
test_bag.py::test_orientation_decoding_reasons (message-level reasons).
"""

import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.bag import decode_orientation, MessageError
from polarization_compass.conventions import camera_attitude_from_body_quat
import pytest


class _Q:
    """A geometry_msgs/Quaternion stand-in."""

    def __init__(self, q):
        self.x, self.y, self.z, self.w = q


class _QuatStamped:
    """A geometry_msgs/QuaternionStamped stand-in."""

    def __init__(self, q):
        self.quaternion = _Q(q)


def axis_angle_matrix(axis, angle_rad):
    """Rodrigues' formula, written out here: an independent rotation for quaternion checks."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle_rad) * K + (1 - math.cos(angle_rad)) * K @ K


@pytest.mark.parametrize(
    'q, reason',
    [
        ([0, 0, 0, float('inf')], 'NaN or inf'),
        ([float('-inf'), 0, 0, 1], 'NaN or inf'),
        ([0, 0, 0, 1e-13], 'zero'),
        ([0, 0, 0, 1 + 1.5e-3], 'not unit'),
        ([0.5, 0.5, 0.5, 0.4], 'not unit'),
        ([1e150, 1e150, 0, 0], 'not unit'),
        ([0, 0, 0, 0, 1], '4 components'),
        ([], '4 components'),
    ],
)
def test_unusable_quaternions_are_refused_with_their_reason(q, reason):
    with pytest.raises(cv.QuaternionError, match=reason):
        cv.validate_quaternion(q)


def test_quaternions_within_the_unit_tolerance_are_normalised():
    for n in (1 - 9e-4, 1 + 9e-4):
        q = cv.validate_quaternion([0, 0, 0.6 * n, 0.8 * n])
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(q, [0, 0, 0.6, 0.8], atol=1e-15)


def test_q_and_minus_q_are_the_same_attitude():
    q = np.array([0.1, -0.2, 0.3, -0.9])
    q /= np.linalg.norm(q)
    a, b = camera_attitude_from_body_quat(q), camera_attitude_from_body_quat(-q)
    assert (a.bearing_deg, a.pitch_deg, a.roll_deg) == pytest.approx(
        (b.bearing_deg, b.pitch_deg, b.roll_deg), abs=1e-9
    )


def test_a_quaternion_with_huge_components_is_refused_without_a_numpy_warning():
    with pytest.raises(cv.QuaternionError, match='not unit'):
        cv.validate_quaternion([0.0, 0.0, 0.0, 1.4e154])


@given(
    st.lists(
        st.one_of(
            st.floats(-1e150, 1e150), st.sampled_from([float('nan'), float('inf'), -float('inf')])
        ),
        min_size=4,
        max_size=4,
    )
)
def test_any_four_numbers_give_a_unit_quaternion_or_a_quaternion_error(q):
    try:
        u = cv.validate_quaternion(q)
    except cv.QuaternionError:
        return
    assert np.all(np.isfinite(u)) and abs(np.linalg.norm(u) - 1) < 1e-12


@given(st.lists(st.floats(-1, 1), min_size=4, max_size=4))
def test_message_decoding_gives_a_quaternion_or_a_counted_reason(q):
    """
    Message decoding gives a quaternion or a counted reason.

    What a node sees: MessageError with a reason (counted and dropped), never another exception.
    """
    try:
        u = decode_orientation(_QuatStamped(q))
    except MessageError as exc:
        assert exc.reason in ('bad_quaternion', 'non_finite')
        return
    assert abs(np.linalg.norm(u) - 1) < 1e-12


@given(
    st.floats(0, 360),
    st.sampled_from([90.0, -90.0, 90.0 - 1e-7, -90.0 + 1e-7, 89.9999999999]),
    st.floats(-180, 180),
)
def test_attitude_from_matrix_at_gimbal_lock_is_finite_and_reproduces_the_rotation(
    bearing, pitch, roll
):
    R = cv.R_enu_cam_from_attitude(bearing, pitch, roll)
    att = cv.attitude_from_R_enu_cam(R)
    assert all(math.isfinite(v) for v in (att.bearing_deg, att.pitch_deg, att.roll_deg))
    assert (
        0.0 <= att.bearing_deg < 360.0
        and -90.0 <= att.pitch_deg <= 90.0
        and -180.0 <= att.roll_deg <= 180.0
    )
    np.testing.assert_allclose(
        cv.R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg), R, atol=1e-6
    )


@given(
    st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3),
    st.floats(-2 * math.pi, 2 * math.pi),
)
def test_quaternion_to_matrix_against_rodrigues(axis, angle):
    k = np.asarray(axis) / np.linalg.norm(axis)
    q = np.concatenate([k * math.sin(angle / 2), [math.cos(angle / 2)]])
    np.testing.assert_allclose(cv.quat_to_matrix(q), axis_angle_matrix(k, angle), atol=1e-12)
    R = cv.quat_to_matrix(q)
    q2 = cv.matrix_to_quat(R)
    assert abs(abs(float(q2 @ q)) - 1.0) < 1e-9  # q and -q are the same rotation
    assert q2[3] >= 0


@pytest.mark.parametrize('bearing', [180.0, -180.0, 180.0 - 1e-12, 540.0, -1e-12, 359.9999999999])
def test_bearing_and_rep103_yaw_wrap(bearing):
    yaw = cv.bearing_to_yaw_enu_deg(bearing)
    assert -180.0 < yaw <= 180.0
    back = cv.yaw_enu_to_bearing_deg(yaw)
    assert 0.0 <= back < 360.0
    assert abs(cv.wrap_180_deg(back - bearing)) < 1e-9
    # REP-103: yaw = 90 - bearing; checked by the direction it points to
    b, y = math.radians(bearing), math.radians(yaw)
    assert (math.sin(b), math.cos(b)) == pytest.approx((math.cos(y), math.sin(y)), abs=1e-12)
