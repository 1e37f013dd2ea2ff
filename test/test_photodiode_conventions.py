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
Unit viewing axes and polarizer angles to body-frame E-vectors.

The conventions module's conversion against hand-derived geometry, the camera's eq 28 convention
and the paper's own Rayleigh formulas.
"""

import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.photodiode.geometry import geometry_from_dict
from polarization_compass.photodiode.simulate import simulate_unit_stokes, sun_body
from polarization_compass.sky import rayleigh_reference
import pytest

COMBOS = [(z, s) for z in cv.ANGLE_ZEROS for s in cv.ANGLE_SENSES]


def _parallel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return abs(abs(float(a @ b)) / (np.linalg.norm(a) * np.linalg.norm(b)) - 1.0) < 1e-12


def test_axis_azimuth_is_clockwise_from_the_front():
    # REP-103 body: x forward, y left. Clockwise seen from above: 90 deg is the right-hand side,
    # -y.
    np.testing.assert_allclose(cv.unit_axis_body(0.0, 0.0), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(cv.unit_axis_body(90.0, 0.0), [0, -1, 0], atol=1e-15)
    np.testing.assert_allclose(cv.unit_axis_body(123.0, 90.0), [0, 0, 1], atol=1e-15)
    s = math.sqrt(0.5)
    np.testing.assert_allclose(cv.unit_axis_body(270.0, 45.0), [0, s, s], atol=1e-15)


def test_forward_looking_unit_by_hand():
    # Looking out forward and level, head up: the meridian zero is straight up (+z); a clockwise
    # quarter turn (12 -> 3 o'clock as the viewer sees it) points to the viewer's right, body -y.
    zero, quarter = cv.unit_polarizer_frame_body(0.0, 0.0, 'meridian', 'cw')
    np.testing.assert_allclose(zero, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(quarter, [0, -1, 0], atol=1e-15)
    zero, quarter = cv.unit_polarizer_frame_body(0.0, 0.0, 'horizontal', 'ccw')
    np.testing.assert_allclose(zero, [0, -1, 0], atol=1e-15)  # horizontal, on the right
    np.testing.assert_allclose(
        quarter, [0, 0, 1], atol=1e-15
    )  # counter-clockwise from 3 o'clock: 12 o'clock


@pytest.mark.parametrize('zero_kind,sense', COMBOS)
@given(az=st.floats(-360, 360), el=st.floats(-89, 89.9))
def test_frame_is_orthonormal_and_perpendicular_to_the_axis(zero_kind, sense, az, el):
    axis = cv.unit_axis_body(az, el)
    zero, quarter = cv.unit_polarizer_frame_body(az, el, zero_kind, sense)
    for v in (zero, quarter):
        assert abs(np.linalg.norm(v) - 1) < 1e-12 and abs(v @ axis) < 1e-12
    assert abs(zero @ quarter) < 1e-12
    handed = float(np.linalg.det(np.stack([zero, quarter, axis])))
    assert handed == pytest.approx(1.0 if sense == 'cw' else -1.0, abs=1e-12)
    if zero_kind == 'horizontal':
        assert abs(zero[2]) < 1e-12
    else:  # in the vertical plane through the axis, pointing up
        assert abs(zero @ np.cross([0, 0, 1.0], axis)) < 1e-12 and zero[2] > 0


@pytest.mark.parametrize('zero_kind,sense', COMBOS)
@given(
    az=st.floats(-180, 180),
    el=st.floats(-60, 90),
    delta=st.floats(-180, 180),
    ang=st.floats(-3, 3),
)
def test_symmetry_under_azimuth_rotation(zero_kind, sense, az, el, delta, ang):
    # Turning a unit clockwise (seen from above) by delta is the body rotation Rz(-delta).
    R = cv.rot_z(-math.radians(delta))
    e1 = cv.unit_evector_body(ang, az + delta, el, zero_kind, sense)
    e0 = cv.unit_evector_body(ang, az, el, zero_kind, sense)
    np.testing.assert_allclose(e1, R @ e0, atol=1e-12)


@given(a=st.floats(-1.5, 1.5))
def test_zenith_unit_reduces_to_the_camera_case(a):
    # A unit looking at the zenith with azimuth 0, meridian zero, counter-clockwise angles measures
    # the camera's eq 28 AoP of the default mounting (camera +y = body front).
    e_cam = cv.evector_cam_from_aop(a, np.array([0.0, 0.0, 1.0]))
    e_body = cv.R_BODY_CAM_DEFAULT @ e_cam
    assert _parallel(cv.unit_evector_body(a, 0.0, 90.0, 'meridian', 'ccw'), e_body)
    got = cv.unit_angle_from_evector_body_rad(e_body, 0.0, 90.0, 'meridian', 'ccw')
    assert abs(float(cv.fold_axial_rad(got - cv.aop_from_evector_cam_rad(e_cam)))) < 1e-12


@pytest.mark.parametrize('zero_kind,sense', COMBOS)
@given(az=st.floats(0, 360), el=st.floats(-80, 90), a=st.floats(-1.5, 1.5))
def test_angle_round_trip(zero_kind, sense, az, el, a):
    e = cv.unit_evector_body(a, az, el, zero_kind, sense)
    back = cv.unit_angle_from_evector_body_rad(e, az, el, zero_kind, sense)
    assert abs(float(cv.fold_axial_rad(back - a))) < 1e-9


def test_unknown_convention_raises():
    with pytest.raises(ValueError, match='angle_zero'):
        cv.unit_polarizer_frame_body(0, 45, 'vertical', 'cw')
    with pytest.raises(ValueError, match='angle_sense'):
        cv.unit_polarizer_frame_body(0, 45, 'meridian', 'left')


@pytest.mark.parametrize('zero_kind,sense', COMBOS)
def test_simulated_unit_matches_the_papers_rayleigh_formulas(zero_kind, sense):
    # A level body, front at bearing B: a unit at (az, el) looks at compass azimuth B + az. The
    # paper's eqs (sky.rayleigh_reference, ENU) give E and DoP there; mapped into the body frame
    # and projected on the unit, they must equal the simulator's point-sample (no acceptance cone).
    units = [
        {'azimuth_deg': a, 'elevation_deg': e, 'channels_deg': [0, 60, 120], 'acceptance_deg': 5}
        for a, e in ((0, 45), (75, 30), (200, 60), (300, 10))
    ]
    g = geometry_from_dict({'angle_zero': zero_kind, 'angle_sense': sense, 'units': units})
    sun_az, sun_alt, B = 130.0, 35.0, 40.0
    st_ = simulate_unit_stokes(g, sun_body(sun_az, sun_alt, B), dop_max=0.8, integrate=False)
    R_enu_body = cv.R_enu_cam_from_attitude(B, 0.0, 0.0) @ cv.R_BODY_CAM_DEFAULT.T
    for u, d in enumerate(units):
        e_enu, dop = rayleigh_reference(
            sun_az, sun_alt, B + d['azimuth_deg'], d['elevation_deg'], 0.8
        )
        e_body = R_enu_body.T @ e_enu
        want = cv.unit_angle_from_evector_body_rad(
            e_body, d['azimuth_deg'], d['elevation_deg'], zero_kind, sense
        )
        got = 0.5 * math.atan2(st_[u, 2], st_[u, 1])
        assert abs(float(cv.fold_axial_rad(got - want))) < 1e-9
        assert math.hypot(st_[u, 1], st_[u, 2]) / st_[u, 0] == pytest.approx(float(dop), abs=1e-9)
