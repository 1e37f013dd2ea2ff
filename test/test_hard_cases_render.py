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
Hard cases of the rendered sky (docs/hard-cases.md).

Sun at and near the zenith, on and around the horizon, pixels at the sun and the anti-sun, a camera
looking at the sun, pitch/roll of +-90 deg, yaw wrap at +-180 deg, AoP wrap at +-90 deg and a DoP
of 0.

Reference values are derived by hand in each docstring (closed forms for special geometries) or
computed here with a float64 cross product; never with the renderer's own kernel.
"""

import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.fastmath import axial_atan2_array
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, SceneError, Validity
from polarization_compass.scene_load import scene_from_dict
import pytest

FISHEYE = CameraModel('fisheye_equidistant', 41, 31, 0.1, 3.45, 3.45, max_field_angle_deg=85.0)
PINHOLE = CameraModel('pinhole', 31, 21, 0.05)  # ~94 x 72 deg field
OPEN = Validity(0.0, -90.0, 0.0)  # every pixel with a ray is valid


def render(
    camera=FISHEYE, validity=OPEN, sky=None, att=(0.0, 0.0, 0.0), sun=(0.0, 45.0), pixels=None
):
    scene = Scene(
        camera=camera,
        validity=validity,
        pixels=pixels or PixelSelection.full(),
        sky=sky or {'model': 'rayleigh', 'dop_max': 1.0},
    )
    return Renderer(scene).render(attitude=cv.CameraAttitude(*att), sun=SunDirection(*sun))


def axial_deg(a_rad, b_rad):
    return np.degrees(
        np.abs(cv.fold_axial_rad(np.asarray(a_rad, float) - np.asarray(b_rad, float)))
    )


def tangential_aop(rays):
    """
    Return the tangential AoP pattern of a sun on the optical axis.

    Sun on the optical axis, S = (0, 0, 1) in the camera: E = S x P = (-P_y, P_x, 0), so by eq 28
    AoP = atan2(-P_y, P_x): the E-vectors are tangent to circles about the image centre.
    """
    r = np.asarray(rays, float)
    return np.arctan2(-r[1], r[0])


def angle_to(frame, direction_cam):
    r = frame.rays_cam.astype(float)
    r /= np.linalg.norm(r, axis=0)
    return np.degrees(np.arccos(np.clip(np.asarray(direction_cam) @ r, -1, 1)))


# --------------------------------------------------------------------------------------------
# Sun at the zenith and within 0.5 deg of it
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('bearing', [0.0, 137.0, -180.0])
def test_sun_at_the_zenith_gives_the_tangential_pattern_for_any_azimuth(bearing):
    """
    The sun at the zenith gives the tangential pattern for any azimuth.

    Level camera, sun altitude 90: S_cam = (0, 0, 1); AoP = atan2(-P_y, P_x), DoP =
    (1-P_z^2)/(1+P_z^2). The sun's azimuth and the camera bearing must not matter (both undefined
    at the zenith).
    """
    frames = [render(att=(bearing, 0.0, 0.0), sun=(az, 90.0)) for az in (0.0, 90.0, 233.7)]
    r = frames[0].rays_cam.astype(float)
    expect_aop = tangential_aop(r)
    expect_dop = (1 - r[2] ** 2) / (1 + r[2] ** 2)
    sin_g = np.hypot(r[0], r[1])
    for f in frames:
        assert np.all(f.valid)
        d = axial_deg(f.aop_rad.reshape(-1), expect_aop)
        # rotating the pattern by the bearing must not change it: the pattern is rotation-invariant
        assert np.all(d[sin_g > 0.02] < 2e-3)
        np.testing.assert_allclose(f.dop.reshape(-1), expect_dop, atol=2e-6)


def test_sun_within_half_a_degree_of_the_zenith_changes_the_pattern_smoothly():
    """
    The pattern changes smoothly within half a degree of the zenith.

    From altitude 90 down to 89.5 the AoP at a pixel gamma from the sun moves by at most ~ (90 -
    alt) / sin(gamma) (the pattern's gradient); no jump from the undefined solar meridian.
    """
    ref = render(sun=(0.0, 90.0), att=(30.0, 0.0, 0.0))
    for alt in (89.999999, 89.99, 89.9, 89.5):
        for az in (0.0, 179.0):
            f = render(sun=(az, alt), att=(30.0, 0.0, 0.0))
            gamma = angle_to(ref, ref.sun_cam)
            far = gamma > 10.0
            d = axial_deg(f.aop_rad.reshape(-1), ref.aop_rad.reshape(-1))
            assert np.all(d[far] <= 1.5 * (90.0 - alt) / np.sin(np.radians(gamma[far])) + 2e-3)
            assert np.all(np.isfinite(f.aop_rad)) and np.all(np.isfinite(f.dop))


# --------------------------------------------------------------------------------------------
# Sun on, just above and just below the horizon
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('alt', [0.0, 1e-9, -1e-9, 0.01, -0.01, -0.8334, -5.0])
def test_sun_on_and_around_the_horizon_renders_the_full_pattern(alt):
    """
    A sun on and around the horizon renders the full pattern.

    The renderer is geometric: a sun at or below the horizon still gives a finite Rayleigh pattern
    (estimators, not the renderer, report ``sun_below_horizon``). Level camera: the zenith pixel is
    90 - alt from the sun, so its DoP is (1 - sin^2 alt) / (1 + sin^2 alt).
    """
    f = render(camera=CameraModel('fisheye_equidistant', 5, 5, 0.1, 3.45, 3.45), sun=(70.0, alt))
    c = f.dop[2, 2]
    s2 = math.sin(math.radians(alt)) ** 2
    assert c == pytest.approx((1 - s2) / (1 + s2), abs=1e-6)
    # zenith pixel, camera x = East, y = North: E = S x Up = (cos h cos A, -cos h sin A, 0) in ENU,
    # so AoP = atan2(E_x, E_y) = atan2(cos A, -sin A) = A + 90 deg (E perpendicular to the sun's
    # azimuth)
    expect = math.atan2(math.cos(math.radians(70.0)), -math.sin(math.radians(70.0)))
    assert axial_deg(f.aop_rad[2, 2], expect) < 1e-4


def test_the_pattern_is_continuous_through_the_horizon():
    a = render(sun=(200.0, -1e-7), att=(10.0, -30.0, 5.0))
    b = render(sun=(200.0, 1e-7), att=(10.0, -30.0, 5.0))
    far = angle_to(a, a.sun_cam) > 5.0
    assert axial_deg(a.aop_rad.reshape(-1), b.aop_rad.reshape(-1))[far].max() < 1e-4
    np.testing.assert_allclose(a.dop, b.dop, atol=1e-6)


def test_horizon_mask_with_the_sun_on_the_horizon():
    """
    The horizon mask works with the sun on the horizon.

    Default validity: pixels below altitude 0 are invalid; pitched -80 deg the horizon crosses the
    view.
    """
    f = render(camera=PINHOLE, validity=Validity(), att=(0.0, -80.0, 0.0), sun=(0.0, 0.0))
    R = cv.R_enu_cam_from_attitude(0.0, -80.0, 0.0)
    alt = np.degrees(np.arcsin(np.clip((R @ f.rays_cam.astype(float))[2], -1, 1)))
    gamma = angle_to(f, f.sun_cam)
    clear = (np.abs(alt) > 1e-3) & (np.abs(gamma - 3.0) > 1e-3)
    np.testing.assert_array_equal(f.valid.reshape(-1)[clear], ((alt >= 0) & (gamma >= 3.0))[clear])
    assert 0 < f.valid.mean() < 1


# --------------------------------------------------------------------------------------------
# Pixels at the sun and at the anti-sun; DoP of 0
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('alt', [90.0, -90.0])
def test_pixel_exactly_at_the_sun_or_anti_sun_has_dop_0_and_a_finite_aop(alt):
    """
    Odd image, principal point at pixel (3, 3): its ray is exactly (0, 0, 1).

    With the sun at the zenith (or nadir) S x P ~ 0 (cos 90 deg = 6e-17 leaves a crumb): the AoP is
    undefined, so any value in [-pi/2, pi/2) is allowed, but it must be finite, and DoP must be
    exactly 0.
    """
    cam = CameraModel('fisheye_equidistant', 5, 5, 0.1, 3.45, 3.45)
    f = render(camera=cam, sun=(0.0, alt))
    assert f.dop[2, 2] == 0.0 and -np.pi / 2 <= f.aop_rad[2, 2] < np.pi / 2
    assert f.valid[2, 2]  # exclusion 0: valid, with DoP 0
    g = render(camera=cam, validity=Validity(), sun=(0.0, alt))
    if alt > 0:  # default validity excludes 3 deg around the sun ...
        assert not g.valid[2, 2] and g.dop[2, 2] == 0.0 and g.aop_rad[2, 2] == 0.0
    else:  # ... but has no anti-sun exclusion: valid with DoP 0 (min_dop > 0 removes it)
        assert g.valid[2, 2] and g.dop[2, 2] == 0.0


def test_dop_zero_ring_and_min_dop_mask_around_the_sun():
    """
    The min_dop mask removes exactly the pixels near the sun and anti-sun.

    With min_dop = m > 0: DoP < m <=> |cos g| > sqrt((1-m)/(1+m)).
    """
    m = 0.05
    f = render(validity=Validity(0.0, -90.0, m), att=(0.0, -60.0, 0.0), sun=(0.0, 30.0))
    c = np.cos(np.radians(angle_to(f, f.sun_cam)))
    lim = math.sqrt((1 - m) / (1 + m))
    clear = np.abs(np.abs(c) - lim) > 1e-4
    np.testing.assert_array_equal(f.valid.reshape(-1)[clear], (np.abs(c) <= lim)[clear])
    assert (~f.valid).any()


def test_tiny_dop_max_keeps_the_aop():
    """
    A vanishing DoP must not disturb the AoP.

    A DoP -> 0 everywhere (dop_max 1e-9) must not disturb the AoP (it does not depend on DoP).
    """
    a = render(
        sky={'model': 'rayleigh', 'dop_max': 1e-9}, sun=(40.0, 35.0), att=(5.0, 10.0, -10.0)
    )
    b = render(sky={'model': 'rayleigh', 'dop_max': 1.0}, sun=(40.0, 35.0), att=(5.0, 10.0, -10.0))
    np.testing.assert_array_equal(a.aop_rad, b.aop_rad)
    assert np.all(a.dop <= 1e-9) and np.all(a.dop >= 0)


@pytest.mark.parametrize(
    'sky',
    [
        {'model': 'rayleigh', 'dop_max': 0.0},
        {'model': 'rayleigh', 'dop_max': -0.1},
        {'model': 'rayleigh', 'dop_max': float('nan')},
        {'model': 'berry_dennis_lee', 'dop_max': 0.0},
    ],
)
def test_zero_or_bad_dop_max_is_a_scene_error(sky):
    with pytest.raises(SceneError, match='dop_max'):
        scene_from_dict({'sky': sky})


def test_berry_dennis_lee_sun_and_anti_sun_pixels():
    """
    Berry-Dennis-Lee sun and anti-sun pixels are not singular.

    BDL: the sun and anti-sun are not singular (the neutral points are), so DoP there is finite and
    the pixel keeps a definite AoP; at a neutral point DoP = 0 (covered by test_sky_models).
    """
    cam = CameraModel('fisheye_equidistant', 5, 5, 0.1, 3.45, 3.45)
    for alt in (90.0, -90.0, 0.0):
        f = render(
            camera=cam,
            sky={'model': 'berry_dennis_lee', 'separation_deg': 18.0, 'dop_max': 0.75},
            sun=(0.0, alt),
        )
        assert np.all(np.isfinite(f.aop_rad)) and np.all((f.dop >= 0) & (f.dop <= 0.75 + 1e-6))


# --------------------------------------------------------------------------------------------
# Camera looking straight at the sun
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('sun_az, sun_alt', [(0.0, 50.0), (123.0, 5.0), (300.0, 89.0)])
def test_camera_looking_straight_at_the_sun(sun_az, sun_alt):
    """
    A camera looking straight at the sun sees the tangential pattern.

    R = Rz(-B) Rx(p): the optical axis in ENU is (-sin p sin B, -sin p cos B, cos p), which is the
    sun (azimuth A, altitude h) for B = A, p = -(90 - h). Then S_cam = (0, 0, 1): the pattern is
    the tangential one, the sun-exclusion disk is centred, and no pixel is NaN.
    """
    f = render(
        camera=PINHOLE,
        validity=Validity(),
        att=(sun_az, -(90.0 - sun_alt), 0.0),
        sun=(sun_az, sun_alt),
    )
    np.testing.assert_allclose(f.sun_cam, [0, 0, 1], atol=1e-12)
    gamma = angle_to(f, [0, 0, 1])
    R = cv.R_enu_cam_from_attitude(sun_az, -(90.0 - sun_alt), 0.0)
    alt_px = np.degrees(np.arcsin(np.clip((R @ f.rays_cam.astype(float))[2], -1, 1)))
    v = f.valid.reshape(-1)
    assert not v[gamma < 3.0 - 1e-3].any()
    clear = (gamma > 3.0 + 1e-3) & (np.abs(alt_px) > 1e-3)
    np.testing.assert_array_equal(v[clear], (alt_px >= 0)[clear])
    d = axial_deg(f.aop_rad.reshape(-1)[v], tangential_aop(f.rays_cam)[v])
    assert d.max() < 2e-3


# --------------------------------------------------------------------------------------------
# Pitch or roll of +-90 deg
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'att, sky_side',
    [
        ((0.0, 90.0, 0.0), 'rows_below_centre'),
        ((0.0, -90.0, 0.0), 'rows_above_centre'),
        ((0.0, 0.0, 90.0), 'cols_left_of_centre'),
        ((0.0, 0.0, -90.0), 'cols_right_of_centre'),
    ],
)
def test_pitch_or_roll_of_90_puts_the_horizon_through_the_image_centre(att, sky_side):
    """
    Rz(-B) Rx(90) maps +y_cam to Up: rows below the centre (y_px > cy) see the sky.

    Ry(90) maps +x_cam to Down: columns left of the centre see the sky. (Hand-derived from eq 21;
    also renders finite.)
    """
    f = render(camera=PINHOLE, validity=Validity(0.0, 0.0, 0.0), att=att, sun=(100.0, 30.0))
    cx, cy = PINHOLE.cx_px, PINHOLE.cy_px
    expect = {
        'rows_below_centre': f.y_px > cy,
        'rows_above_centre': f.y_px < cy,
        'cols_left_of_centre': f.x_px < cx,
        'cols_right_of_centre': f.x_px > cx,
    }[sky_side]
    off_centre = (f.y_px != cy) if sky_side.startswith('rows') else (f.x_px != cx)
    np.testing.assert_array_equal(f.valid[off_centre], expect[off_centre])
    assert np.all(np.isfinite(f.aop_rad)) and np.all(np.isfinite(f.dop))


def test_roll_180_looks_at_the_ground_and_everything_is_masked():
    f = render(camera=PINHOLE, validity=Validity(), att=(0.0, 0.0, 180.0), sun=(100.0, 30.0))
    assert not f.valid.any() and np.all(f.aop_rad == 0) and np.all(f.dop == 0)


def test_pitch_at_gimbal_lock_is_continuous():
    """
    The rendered frame is continuous at the gimbal-lock pitch.

    At pitch 90 bearing and roll mix (gimbal lock); the rendered frame must still be continuous.
    """
    a = render(att=(40.0, 90.0, 10.0), sun=(10.0, 30.0))
    b = render(att=(40.0, 90.0 - 1e-7, 10.0), sun=(10.0, 30.0))
    far = angle_to(a, a.sun_cam) > 5.0
    assert axial_deg(a.aop_rad.reshape(-1), b.aop_rad.reshape(-1))[far].max() < 1e-4


# --------------------------------------------------------------------------------------------
# Yaw wrap at +-180 deg
# --------------------------------------------------------------------------------------------
def test_bearings_differing_by_360_render_the_same_frame_and_psi_wraps_to_180():
    frames = [render(att=(b, -10.0, 5.0), sun=(0.0, 40.0)) for b in (-180.0, 180.0, 540.0)]
    for f in frames[1:]:
        assert axial_deg(f.aop_rad.reshape(-1), frames[0].aop_rad.reshape(-1)).max() < 1e-4
        np.testing.assert_allclose(f.dop, frames[0].dop, atol=1e-6)
    assert [f.psi_deg for f in frames] == [180.0, 180.0, 180.0]  # (-180, 180]
    assert render(att=(-180.0 + 1e-9, 0, 0), sun=(0.0, 40.0)).psi_deg == pytest.approx(
        -180.0 + 1e-9, abs=1e-12
    )


def test_frames_just_either_side_of_the_yaw_wrap_are_close():
    a = render(att=(180.0 - 1e-6, 0.0, 0.0), sun=(0.0, 40.0))
    b = render(att=(-180.0 + 1e-6, 0.0, 0.0), sun=(0.0, 40.0))
    far = angle_to(a, a.sun_cam) > 5.0
    assert axial_deg(a.aop_rad.reshape(-1), b.aop_rad.reshape(-1))[far].max() < 1e-3
    assert abs(cv.wrap_180_deg(a.psi_deg - b.psi_deg)) < 1e-5


# --------------------------------------------------------------------------------------------
# AoP wrap at +-90 deg
# --------------------------------------------------------------------------------------------
def test_axial_atan2_at_the_fold_never_returns_plus_90():
    """
    axial_atan2 at the fold never returns +90 deg.

    E parallel to +-x_cam: AoP is +-90 deg, which folds to -pi/2 exactly ([-pi/2, pi/2)), for
    signed zeros and subnormal y as well.
    """
    tiny = np.float32(1e-45)
    x = np.array([1, -1, 1, -1, 1, -1, 1e-30, -1e-30], np.float32)
    y = np.array([0.0, 0.0, -0.0, -0.0, tiny, -tiny, 0.0, -0.0], np.float32)
    out = np.empty_like(x)
    axial_atan2_array(x, y, out)
    assert np.all(out >= -np.float32(np.pi / 2)) and np.all(out < np.float32(np.pi / 2))
    assert np.all(np.abs(np.abs(out) - np.pi / 2) < 1e-6)


def test_rendered_aop_across_the_fold_is_axially_continuous():
    """
    The rendered AoP across the fold is axially continuous.

    Sun at azimuth 0 (North = +y_cam for a level camera): on the solar meridian (column x = cx) S
    and P lie in the y-z plane, so E = S x P is along x_cam and AoP sits exactly on the +-90 deg
    fold; the neighbouring columns fall either side of it. Raw values jump by ~pi there, axial ones
    must not.
    """
    f = render(sun=(0.0, 30.0))
    a = f.aop_rad.astype(float)
    centre = f.x_px[0] == FISHEYE.cx_px
    assert np.all(np.abs(np.abs(a[:, centre]) - np.pi / 2) < 1e-5)
    assert np.all(f.aop_rad < np.float32(np.pi / 2))
    assert np.abs(np.diff(a, axis=1)).max() > 3.0  # the fold is crossed ...
    assert axial_deg(a[:, 1:], a[:, :-1]).max() < 10.0  # ... without an axial jump
    gamma = angle_to(f, f.sun_cam).reshape(a.shape)
    far = (gamma[:, 1:] > 20) & (gamma[:, :-1] > 20)
    assert axial_deg(a[:, 1:], a[:, :-1])[far].max() < 3.0


# --------------------------------------------------------------------------------------------
# Fisheye pixels outside the lens' field
# --------------------------------------------------------------------------------------------
def test_pixels_outside_the_fisheye_field_hold_zero():
    cam = CameraModel('fisheye_equidistant', 1, 5, 0.0126, 3.45, 3.45, max_field_angle_deg=30.0)
    f = render(camera=cam, sun=(0.0, 0.0))
    outside = ~f.pixels.has_ray.reshape(f.valid.shape)
    assert outside.any() and not f.valid[outside].any()
    assert np.all(f.aop_rad[outside] == 0.0) and np.all(f.dop[outside] == 0.0)
