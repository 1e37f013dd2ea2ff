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
Property-based tests of the renderer.

Inputs are random suns, attitudes, cameras, pixel sets and sky models.

Every output must be finite, in its documented range ([-pi/2, pi/2) for AoP, [0, 1] for DoP,
invalid pixels 0/0), agree with an independent float64 cross-product computation written here, and
change continuously with the attitude (no jumps away from the sun and anti-sun, where the AoP is
undefined). numpy warnings are errors (pytest.ini, conftest.py).
"""

import math

from hypothesis import assume, given
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, Validity

HALF_PI = np.float32(np.pi / 2)

sun_az = st.floats(-360.0, 720.0, allow_nan=False)
sun_alt = st.one_of(
    st.floats(-90.0, 90.0), st.sampled_from([-90.0, -1e-9, 0.0, 1e-9, 89.5, 89.999999, 90.0])
)
bearing = st.one_of(
    st.floats(-360.0, 720.0), st.sampled_from([-180.0, 180.0, -180.0 + 1e-9, 180.0 - 1e-9, 540.0])
)
pitch = st.one_of(st.floats(-90.0, 90.0), st.sampled_from([-90.0, 90.0, 89.9999999, -89.9999999]))
roll = st.one_of(st.floats(-180.0, 180.0), st.sampled_from([-180.0, 180.0, -90.0, 90.0]))


@st.composite
def cameras(draw):
    model = draw(st.sampled_from(['pinhole', 'fisheye_equidistant']))
    w = draw(st.integers(1, 41))
    h = draw(st.integers(1, 33))
    if model == 'pinhole':
        f = draw(st.floats(0.05, 20.0))
        return CameraModel(model, w, h, f, 3.45, 3.45)
    # fisheye: choose the focal length so that the image reaches 40..120 deg off axis
    reach_deg = draw(st.floats(40.0, 120.0))
    half_diag_mm = math.hypot(w, h) * 3.45e-3 / 2
    f = max(half_diag_mm / math.radians(reach_deg), 1e-4)
    return CameraModel(
        model, w, h, f, 3.45, 3.45, max_field_angle_deg=draw(st.floats(30.0, 180.0))
    )


@st.composite
def selections(draw, camera):
    kind = draw(st.sampled_from(['full', 'list', 'grid']))
    if kind == 'full':
        return PixelSelection.full()
    if kind == 'grid':
        return PixelSelection.grid(
            draw(st.integers(1, camera.width_px)), draw(st.integers(1, camera.height_px))
        )
    n = draw(st.integers(1, 30))
    xs = draw(st.lists(st.integers(1, camera.width_px), min_size=n, max_size=n))
    ys = draw(st.lists(st.integers(1, camera.height_px), min_size=n, max_size=n))
    return PixelSelection.explicit(xs, ys)


skies = st.one_of(
    st.builds(lambda d: {'model': 'rayleigh', 'dop_max': d}, st.floats(1e-6, 1.0)),
    st.builds(
        lambda s, d: {'model': 'berry_dennis_lee', 'separation_deg': s, 'dop_max': d},
        st.floats(0.0, 40.0),
        st.floats(1e-6, 1.0),
    ),
)
validities = st.builds(Validity, st.floats(0.0, 90.0), st.floats(-90.0, 90.0), st.floats(0.0, 1.0))


def independent_rayleigh(frame, dop_max):
    """
    Return AoP by an independent float64 cross product E = S x P.

    float64: E = S x P in ENU (numpy cross product), rotated into the camera, AoP = atan2(E_x,
    E_y).
    """
    att = frame.attitude
    R = cv.R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg)
    rays = frame.rays_cam.astype(np.float64)
    rays /= np.linalg.norm(rays, axis=0, keepdims=True)
    p_enu = (R @ rays).T
    s_enu = cv.enu_direction(frame.sun.azimuth_deg, frame.sun.altitude_deg)
    e_cam = np.cross(s_enu, p_enu) @ R
    aop = np.arctan2(e_cam[:, 0], e_cam[:, 1])
    cos_g = np.clip(p_enu @ s_enu, -1.0, 1.0)
    sin_g = np.linalg.norm(np.cross(s_enu, p_enu), axis=1)
    dop = dop_max * (1 - cos_g**2) / (1 + cos_g**2)
    alt_sin = p_enu[:, 2]
    return aop, dop, cos_g, sin_g, alt_sin


def check_ranges(frame):
    aop, dop, valid = frame.aop_rad, frame.dop, frame.valid
    assert aop.dtype == np.float32 and dop.dtype == np.float32 and valid.dtype == np.bool_
    assert aop.shape == dop.shape == valid.shape == frame.pixels.shape
    assert np.all(np.isfinite(aop)) and np.all(np.isfinite(dop))
    assert np.all(aop >= -HALF_PI) and np.all(aop < HALF_PI)
    assert np.all(dop >= 0.0) and np.all(dop <= 1.0)
    assert np.all(aop[~valid] == 0.0) and np.all(
        dop[~valid] == 0.0
    )  # incl. fisheye pixels outside the field
    assert np.all(np.isfinite(frame.sun_cam)) and np.all(np.isfinite(frame.zenith_cam))
    assert (
        abs(np.linalg.norm(frame.sun_cam) - 1) < 1e-12
        and abs(np.linalg.norm(frame.zenith_cam) - 1) < 1e-12
    )


@given(st.data(), sun_az, sun_alt, bearing, pitch, roll, skies, validities)
def test_every_output_is_finite_and_in_its_range(data, az, alt, b, p, r, sky, validity):
    cam = data.draw(cameras())
    sel = data.draw(selections(cam))
    scene = Scene(camera=cam, pixels=sel, sky=sky, validity=validity)
    f = Renderer(scene).render(attitude=cv.CameraAttitude(b, p, r), sun=SunDirection(az, alt))
    check_ranges(f)
    assert -180.0 < f.psi_deg <= 180.0
    if sky['model'] == 'berry_dennis_lee':
        assert np.all(f.dop <= sky['dop_max'] * (1 + 1e-6))


@given(st.data(), sun_az, sun_alt, bearing, pitch, roll, st.floats(1e-3, 1.0))
def test_rayleigh_matches_an_independent_cross_product_everywhere_it_is_defined(
    data, az, alt, b, p, r, dop_max
):
    """
    Rayleigh matches an independent cross product wherever it is defined.

    Exclusion 0, min altitude -90, min DoP 0: every pixel with a ray is valid and checked,
    including rays within a hair of the sun/anti-sun (where only DoP -> 0 is promised) and AoP
    values at +-90 deg.
    """
    cam = data.draw(cameras())
    sel = data.draw(selections(cam))
    scene = Scene(
        camera=cam,
        pixels=sel,
        sky={'model': 'rayleigh', 'dop_max': dop_max},
        validity=Validity(0.0, -90.0, 0.0),
    )
    f = Renderer(scene).render(attitude=cv.CameraAttitude(b, p, r), sun=SunDirection(az, alt))
    check_ranges(f)
    aop_ref, dop_ref, cos_g, sin_g, _ = independent_rayleigh(f, dop_max)
    has_ray = f.pixels.has_ray.reshape(-1)
    got_valid = f.valid.reshape(-1)
    # valid iff the pixel has a ray, up to float32 rounding exactly at the sun/anti-sun (DoP 0
    # there)
    assert np.all(got_valid[has_ray] | (sin_g[has_ray] < 1e-3))
    assert not np.any(got_valid[~has_ray])
    ok = got_valid & has_ray
    np.testing.assert_allclose(f.dop.reshape(-1)[ok], dop_ref[ok], atol=2e-6)
    defined = ok & (sin_g > 0.02)
    d = cv.fold_axial_rad(f.aop_rad.reshape(-1)[defined].astype(np.float64) - aop_ref[defined])
    assert np.all(np.abs(d) < 5e-5), np.abs(d).max()


@given(st.data(), sun_az, sun_alt, bearing, pitch, roll)
def test_validity_mask_follows_its_three_limits(data, az, alt, b, p, r):
    cam = data.draw(cameras())
    sel = data.draw(selections(cam))
    v = data.draw(validities)
    scene = Scene(camera=cam, pixels=sel, validity=v)
    f = Renderer(scene).render(attitude=cv.CameraAttitude(b, p, r), sun=SunDirection(az, alt))
    _, dop_ref, cos_g, _, alt_sin = independent_rayleigh(f, 1.0)
    ang_sun = np.degrees(np.arccos(cos_g))
    alt_deg = np.degrees(np.arcsin(np.clip(alt_sin, -1, 1)))
    expected = (
        (ang_sun >= v.sun_exclusion_deg) & (alt_deg >= v.min_altitude_deg) & (dop_ref >= v.min_dop)
    )
    expected &= f.pixels.has_ray.reshape(-1)
    clear = (
        (np.abs(ang_sun - v.sun_exclusion_deg) > 1e-3)
        & (np.abs(alt_deg - v.min_altitude_deg) > 1e-3)
        & (np.abs(dop_ref - v.min_dop) > 1e-5)
    )
    np.testing.assert_array_equal(f.valid.reshape(-1)[clear], expected[clear])


@given(
    sun_az,
    sun_alt,
    bearing,
    pitch,
    roll,
    st.sampled_from(['bearing', 'pitch', 'roll', 'sun_az', 'sun_alt']),
)
def test_aop_is_continuous_in_attitude_and_sun(az, alt, b, p, r, which):
    """
    The AoP is continuous in attitude and sun.

    A 1e-4 deg change of any input moves each AoP by at most ~1e-4 deg / sin(angle to the sun) (the
    pattern's gradient), never by a jump; folding at +-90 deg is measured axially.
    """
    cam = CameraModel('fisheye_equidistant', 33, 25, 0.08, 3.45, 3.45, max_field_angle_deg=180.0)
    r0 = Renderer(Scene(camera=cam, validity=Validity(0.0, -90.0, 0.0)))
    eps = 1e-4
    kw = {'bearing': b, 'pitch': p, 'roll': r, 'sun_az': az, 'sun_alt': alt}
    kw2 = dict(kw)
    kw2[which] += eps if which != 'sun_alt' or alt < 90.0 - eps else -eps
    if which == 'pitch' and abs(kw2['pitch']) > 90.0:
        kw2['pitch'] = kw['pitch'] - math.copysign(eps, kw['pitch'])
    f1 = r0.render(
        attitude=cv.CameraAttitude(kw['bearing'], kw['pitch'], kw['roll']),
        sun=SunDirection(kw['sun_az'], kw['sun_alt']),
    )
    f2 = r0.render(
        attitude=cv.CameraAttitude(kw2['bearing'], kw2['pitch'], kw2['roll']),
        sun=SunDirection(kw2['sun_az'], kw2['sun_alt']),
    )
    _, _, _, sin_g, _ = independent_rayleigh(f1, 1.0)
    away = (sin_g > 0.05) & f1.valid.reshape(-1) & f2.valid.reshape(-1)
    assume(away.sum() > 10)
    d = np.abs(
        cv.fold_axial_rad(
            f1.aop_rad.reshape(-1)[away].astype(np.float64)
            - f2.aop_rad.reshape(-1)[away].astype(np.float64)
        )
    )
    bound = 3 * math.radians(eps) / sin_g[away] + 2e-6
    assert np.all(d <= bound), (d / bound).max()
