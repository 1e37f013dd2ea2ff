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

"""Frames and angle conventions against the paper's printed formulas and first principles."""

import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
import pytest

angles = st.floats(-720, 720, allow_nan=False)
tilt = st.floats(-60, 60, allow_nan=False)


def eq21_as_printed(psi_deg, alpha_deg, beta_deg):
    """Eq 21 element by element, as printed in the paper (an independent transcription)."""
    p, a, b = np.radians([psi_deg, alpha_deg, beta_deg])
    c, s = np.cos, np.sin
    return np.array(
        [
            [c(b) * c(p) + s(b) * s(a) * s(p), c(a) * s(p), s(b) * c(p) - c(b) * s(a) * s(p)],
            [-c(b) * s(p) + s(b) * s(a) * c(p), c(a) * c(p), -s(b) * s(p) - c(b) * s(a) * c(p)],
            [-s(b) * c(a), s(a), c(b) * c(a)],
        ]
    )


@given(angles)
def test_wrap_ranges(a):
    w = cv.wrap_180_deg(a)
    assert -180 < w <= 180 and math.isclose(
        math.cos(math.radians(w)), math.cos(math.radians(a)), abs_tol=1e-9
    )
    w = cv.wrap_360_deg(a)
    assert 0 <= w < 360 and math.isclose(
        math.sin(math.radians(w)), math.sin(math.radians(a)), abs_tol=1e-9
    )
    f = cv.fold_axial_deg(a)
    assert -90 < f <= 90 and math.isclose(
        math.cos(math.radians(2 * f)), math.cos(math.radians(2 * a)), abs_tol=1e-9
    )


def test_wrap_edges():
    assert cv.wrap_180_deg(-180.0) == 180.0 and cv.wrap_180_deg(540.0) == 180.0
    assert cv.wrap_360_deg(-1e-20) == 0.0 and cv.wrap_360_deg(360.0) == 0.0
    assert cv.fold_axial_deg(-90.0) == 90.0 and cv.fold_axial_deg(270.0) == 90.0
    a = cv.fold_aop_rad(np.array([np.pi / 2, -np.pi / 2, np.pi, 3 * np.pi / 2], dtype=np.float32))
    assert a.dtype == np.float32
    assert np.all(a >= -np.pi / 2) and np.all(a < np.pi / 2)


@given(angles)
def test_float_wraps_have_the_range_and_the_bits_of_the_numpy_wraps(a):
    """
    The float wraps have the range and the bits of the numpy wraps.

    The per-estimate / numba forms: the range and the angle (cos, sin) checked independently, and
    the same bits as the numpy forms (an independent implementation: np.mod).
    """
    w = cv.wrap_180_deg_float(a)
    assert -180 < w <= 180 and math.isclose(
        math.cos(math.radians(w)), math.cos(math.radians(a)), abs_tol=1e-9
    )
    assert w == cv.wrap_180_deg(a) and math.copysign(1.0, w) == math.copysign(
        1.0, cv.wrap_180_deg(a)
    )
    w = cv.wrap_360_deg_float(a)
    assert 0 <= w < 360 and math.isclose(
        math.sin(math.radians(w)), math.sin(math.radians(a)), abs_tol=1e-9
    )
    assert w == cv.wrap_360_deg(a)
    r = math.radians(a)
    f = cv.fold_axial_rad_float(r)
    assert -math.pi / 2 < f <= math.pi / 2 and math.isclose(
        math.cos(2 * f), math.cos(2 * r), abs_tol=1e-9
    )
    assert f == cv.fold_axial_rad(r)


def test_float_wrap_edges():
    assert cv.wrap_180_deg_float(-180.0) == 180.0 and cv.wrap_180_deg_float(540.0) == 180.0
    assert cv.wrap_360_deg_float(-1e-20) == 0.0 and cv.wrap_360_deg_float(360.0) == 0.0
    assert (
        cv.fold_axial_rad_float(-math.pi / 2) == math.pi / 2
        and cv.fold_axial_rad_float(math.pi / 2) == math.pi / 2
    )


@given(angles, tilt, tilt)
def test_eq21_matches_printed_matrix_and_is_a_rotation(psi, alpha, beta):
    R = cv.R_sun_cam_from_attitude(psi, alpha, beta)
    np.testing.assert_allclose(R, eq21_as_printed(psi, alpha, beta), atol=1e-12)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert math.isclose(np.linalg.det(R), 1.0, abs_tol=1e-12)


def test_eq31_optical_axis_and_eq32_roll_pitch_shift():
    """
    Eq 31 gives the optical axis in the sun frame; eq 32 shifts roll and pitch.

    Eq 32: (psi, alpha, 0) and (psi+90, 0, alpha) share the optical axis.
    """
    for psi, alpha in [(10.0, -20.0), (-130.0, 25.0), (75.0, 5.0)]:
        axis1 = cv.R_sun_cam_from_attitude(psi, alpha, 0.0) @ [0, 0, 1]
        p, a = math.radians(psi), math.radians(alpha)
        np.testing.assert_allclose(
            axis1,
            [-math.sin(a) * math.sin(p), -math.sin(a) * math.cos(p), math.cos(a)],
            atol=1e-12,
        )
        axis2 = cv.R_sun_cam_from_attitude(psi + 90.0, 0.0, alpha) @ [0, 0, 1]
        np.testing.assert_allclose(axis1, axis2, atol=1e-12)


@given(st.floats(0, 360, exclude_max=True), st.floats(-85, 85), st.floats(-170, 170))
def test_attitude_round_trip(bearing, pitch, roll):
    R = cv.R_enu_cam_from_attitude(bearing, pitch, roll)
    att = cv.attitude_from_R_enu_cam(R)
    assert not att.gimbal_lock
    np.testing.assert_allclose(
        cv.R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg), R, atol=1e-9
    )
    assert abs(cv.wrap_180_deg(att.bearing_deg - bearing)) < 1e-7
    assert abs(att.pitch_deg - pitch) < 1e-7 and abs(att.roll_deg - roll) < 1e-7


def test_attitude_gimbal_lock_is_flagged_not_nan():
    att = cv.attitude_from_R_enu_cam(cv.R_enu_cam_from_attitude(40.0, 90.0, 10.0))
    assert att.gimbal_lock and all(
        math.isfinite(v) for v in (att.bearing_deg, att.pitch_deg, att.roll_deg)
    )
    # the returned angles still describe the same rotation
    np.testing.assert_allclose(
        cv.R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg),
        cv.R_enu_cam_from_attitude(40.0, 90.0, 10.0),
        atol=1e-6,
    )


@given(st.floats(0, 360, exclude_max=True))
def test_level_camera_y_axis_has_the_bearing(bearing):
    """
    The camera +y axis of a level camera has the bearing A_sun + psi.

    Physics notes: the camera +y axis has true bearing A_sun + psi; here directly: +y_cam points at
    B.
    """
    y_enu = cv.R_enu_cam_from_attitude(bearing, 0, 0) @ [0, 1, 0]
    np.testing.assert_allclose(y_enu, cv.enu_direction(bearing, 0.0), atol=1e-12)
    az, alt = cv.azimuth_altitude_from_enu(y_enu)
    assert abs(cv.wrap_180_deg(az - bearing)) < 1e-9 and abs(alt) < 1e-9


def test_sun_frame_is_enu_rotated_by_sun_azimuth():
    """Eq 1: C_g^a maps the sun's horizontal direction onto +y_a; enu = Rz(-A_sun) sun-frame."""
    for a_sun in (0.0, 37.0, 200.0):
        c, s = math.cos(math.radians(a_sun)), math.sin(math.radians(a_sun))
        C_g_a = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])  # eq 1 as printed
        np.testing.assert_allclose(C_g_a @ cv.enu_direction(a_sun, 0.0), [0, 1, 0], atol=1e-12)
        # R_enu_cam(bearing = psi + A_sun) == C_a^g R_sun_cam(psi)
        psi, pitch, roll = 23.0, -11.0, 7.0
        np.testing.assert_allclose(
            cv.R_enu_cam_from_attitude(psi + a_sun, pitch, roll),
            C_g_a.T @ cv.R_sun_cam_from_attitude(psi, pitch, roll),
            atol=1e-12,
        )


def test_rep103_yaw():
    assert cv.bearing_to_yaw_enu_deg(0.0) == 90.0  # facing North = +90 deg from East
    assert cv.bearing_to_yaw_enu_deg(90.0) == 0.0  # facing East
    assert cv.bearing_to_yaw_enu_deg(270.0) == 180.0
    assert cv.yaw_enu_to_bearing_deg(-90.0) == 180.0  # facing South
    # the body's x axis under a pure REP-103 yaw points at the bearing 90 - yaw
    for yaw in (-170.0, -30.0, 0.0, 60.0, 179.0):
        R = cv.quat_to_matrix(cv.yaw_enu_quaternion(math.radians(yaw)))
        np.testing.assert_allclose(
            R @ [1, 0, 0], cv.enu_direction(cv.yaw_enu_to_bearing_deg(yaw), 0), atol=1e-12
        )


def test_default_mounting_puts_camera_y_forward():
    R = cv.R_BODY_CAM_DEFAULT
    np.testing.assert_allclose(R @ R.T, np.eye(3))
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ [0, 1, 0], [1, 0, 0])  # camera +y = body forward
    np.testing.assert_allclose(R @ [0, 0, 1], [0, 0, 1])  # looking up


@given(st.lists(st.floats(-1, 1), min_size=4, max_size=4))
def test_quaternion_round_trip(q):
    q = np.array(q)
    if np.linalg.norm(q) < 1e-3:
        return
    q = q / np.linalg.norm(q)
    R = cv.quat_to_matrix(q)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    q2 = cv.matrix_to_quat(R)
    assert min(np.abs(q2 - q).max(), np.abs(q2 + q).max()) < 1e-9


def test_quaternion_matches_axis_angle():
    """Independent: rotation by t about +z is (0, 0, sin t/2, cos t/2) and equals rot_z(t)."""
    t = 0.7
    np.testing.assert_allclose(
        cv.quat_to_matrix([0, 0, math.sin(t / 2), math.cos(t / 2)]), cv.rot_z(t), atol=1e-12
    )
    np.testing.assert_allclose(
        cv.quat_to_matrix([math.sin(t / 2), 0, 0, math.cos(t / 2)]), cv.rot_x(t), atol=1e-12
    )


@pytest.mark.parametrize(
    'q,msg',
    [
        ([0, 0, 0, 0], 'zero'),
        ([0, 0, float('nan'), 1], 'NaN'),
        ([0, 0, 0, 2], 'not unit'),
        ([0, 0, 1], '4 components'),
    ],
)
def test_bad_quaternions_are_rejected_with_reason(q, msg):
    with pytest.raises(cv.QuaternionError, match=msg):
        cv.validate_quaternion(q)


@given(st.floats(-89, 89), st.floats(0, 360), st.floats(-math.pi, math.pi))
def test_aop_evector_round_trip(theta_deg, phi_deg, angle_rad):
    """Any E perpendicular to a ray -> AoP (eq 28) -> lifted E' is parallel to E (axial)."""
    th, ph = math.radians(theta_deg), math.radians(phi_deg)
    r = np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
    if r[2] < 0.05:
        return
    u = np.cross(r, [1.0, 0.3, 0.2])
    u /= np.linalg.norm(u)
    v = np.cross(r, u)
    e = math.cos(angle_rad) * u + math.sin(angle_rad) * v
    aop = cv.aop_from_evector_cam_rad(e)
    e2 = cv.evector_cam_from_aop(aop, r)
    assert abs(abs(float(e2 @ e)) - 1.0) < 1e-9
    assert abs(float(e2 @ r)) < 1e-12


def test_lift_handles_rays_at_90_deg_off_axis():
    """Fisheye rays with r_z = 0 must not divide by zero."""
    r = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    e = cv.evector_cam_from_aop(np.array([0.0, 0.5]), r)
    assert np.all(np.isfinite(e))
    np.testing.assert_allclose(np.abs(np.sum(e * r, axis=1)), 0, atol=1e-12)


def test_axial_mean_wraps_and_measures_concentration():
    a = np.radians([89.0, -89.0, 90.0])  # all near the +-90 axis
    m, R = cv.axial_mean_rad(a)
    assert abs(cv.fold_axial_deg(math.degrees(m) - 90.0)) < 1.0 and R > 0.99
    m, R = cv.axial_mean_rad(np.radians([0.0, 90.0]))  # orthogonal axes cancel
    assert R < 1e-12
    assert cv.axial_difference_deg(179.0, 1.0) == pytest.approx(-2.0)


def test_scalar_rotations_equal_the_vectorised_ones():
    """
    Scalar rotations equal the vectorised ones.

    rot_x/y/z of a Python or numpy scalar (a fast path) equal the same rotation from a 0-d array,
    and an elementary rotation by theta then -theta is the identity.
    """
    rng = np.random.default_rng(11)
    for theta in rng.uniform(-7.0, 7.0, 50):
        for rot in (cv.rot_x, cv.rot_y, cv.rot_z):
            a, b, c = rot(float(theta)), rot(np.float64(theta)), rot(np.array(theta))
            assert a.shape == b.shape == c.shape == (3, 3)
            np.testing.assert_allclose(a, c, rtol=0, atol=1e-15)
            np.testing.assert_allclose(b, c, rtol=0, atol=1e-15)
            np.testing.assert_allclose(
                rot(float(theta)) @ rot(-float(theta)), np.eye(3), atol=1e-15
            )
    assert cv.rot_z(1).shape == (3, 3) and np.allclose(cv.rot_z(1), cv.rot_z(np.array(1.0)))


def test_scalar_axial_fold_equals_the_vectorised_one():
    """
    The scalar axial fold equals the vectorised one, bit for bit.

    fold_axial_deg of a Python float (a fast path) gives the same bits as for an array, in (-90,
    90].
    """
    rng = np.random.default_rng(12)
    xs = list(rng.uniform(-1e4, 1e4, 2000)) + [
        -270.0,
        -90.0,
        -0.0,
        0.0,
        90.0,
        180.0,
        270.0,
        1e12,
        -1e12,
    ]
    got = np.array([cv.fold_axial_deg(float(x)) for x in xs])
    want = cv.fold_axial_deg(np.array(xs))
    assert np.array_equal(got, want)
    assert np.all((got > -90.0) & (got <= 90.0))
    assert isinstance(cv.fold_axial_deg(-90.0), float) and cv.fold_axial_deg(-90.0) == 90.0
