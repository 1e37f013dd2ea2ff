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
The ground below the horizon (ground.py) against independent expectations.

Fresnel coefficients against Born & Wolf's sine/tangent forms and published reflectances (glass
at 45 deg), Brewster's angle (53.06 deg for water: reflected unpolarized light fully s-polarized,
E-vector horizontal), the DoP of reflected unpolarized light against (R_s - R_p)/(R_s + R_p) over
the incidence angle, the E-vector kept by a mirror at normal incidence, a Jones-calculus
cross-check of the polarized sky's reflection, the diffuse part against a fine quadrature of the
sky dome, reflected skyline obstacles, the sensor mosaic, the budget source, validation and zero
cost when undeclared.
"""

import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass import instrumentation
from polarization_compass.budget_config import BudgetConfig, declared_sources, SOURCES, without
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.ground import (
    brewster_angle_deg,
    fresnel_amplitudes,
    fresnel_reflection_mueller,
)
from polarization_compass.radiance import make_radiance_model
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, scene_from_dict, SceneError
import pytest

SUN = SunDirection(40.0, 35.0)
#: a level fisheye that sees down to the nadir: r = f theta, theta = 180 deg at 188 px
FISHEYE_180 = CameraModel(
    model='fisheye_equidistant',
    width_px=400,
    height_px=400,
    focal_length_mm=0.45,
    pixel_pitch_x_um=7.5,
    pixel_pitch_y_um=7.5,
    max_field_angle_deg=180.0,
)
WATER = {'albedo': 0.0, 'specular': {'fraction': 1.0, 'refractive_index': 1.33}}
#: thick overcast: an unpolarized sky of uniform radiance 1.7 (T = exp(-25))
OVERCAST = {'coverage': 1.0, 'optical_thickness': 25.0, 'brightness': 1.7}


def render(atmosphere, camera=FISHEYE_180, att=(0, 0, 0), pixels=None, sun=SUN, sky=None, **kw):
    scene = Scene(
        pixels=pixels or PixelSelection.full(),
        camera=camera,
        sky=sky or {'model': 'rayleigh', 'dop_max': 0.8},
        atmosphere=atmosphere,
        **kw,
    )
    return Renderer(scene).render(attitude=cv.CameraAttitude(*att), sun=sun)


def geometry(frame):
    """ENU rays (N, 3), R (camera to ENU) and the ground mask of a frame (float64)."""
    a = frame.attitude
    R = cv.R_enu_cam_from_attitude(a.bearing_deg, a.pitch_deg, a.roll_deg)
    r = (R @ frame.rays_cam.astype(float)).T
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    ground = (r[:, 2] < 0) & frame.pixels.has_ray.reshape(-1)
    return r, R, ground


def snell(theta_i, n):
    return np.arcsin(np.sin(theta_i) / n)


def bw_reflectances(theta_i, n):
    """Born & Wolf 1.5 (21): R_s = sin^2(i - t)/sin^2(i + t), R_p = tan^2(i - t)/tan^2(i + t)."""
    t = snell(theta_i, n)
    return (np.sin(theta_i - t) / np.sin(theta_i + t)) ** 2, (
        np.tan(theta_i - t) / np.tan(theta_i + t)
    ) ** 2


def horizontal_aop(rays_enu, R):
    """Eq 28 AoP of a horizontal E-vector perpendicular to each ray (s-polarization)."""
    s = np.cross(np.array([0.0, 0.0, 1.0]), rays_enu)
    return cv.aop_from_evector_cam_rad((R.T @ s.T).T)


# --------------------------------------------------------------------------------------- Fresnel
def test_fresnel_amplitudes_are_born_and_wolf_sine_and_tangent_forms():
    theta = np.radians(np.linspace(1.0, 89.0, 89))
    n = 1.33
    t = snell(theta, n)
    r_s, r_p = fresnel_amplitudes(np.cos(theta), n)
    np.testing.assert_allclose(r_s, -np.sin(theta - t) / np.sin(theta + t), rtol=1e-12)
    # the along-the-surface convention: minus Born & Wolf's r_parallel
    np.testing.assert_allclose(r_p, -np.tan(theta - t) / np.tan(theta + t), atol=1e-14)
    # normal incidence: both (1 - n)/(1 + n)
    np.testing.assert_allclose(fresnel_amplitudes(1.0, n), [(1 - n) / (1 + n)] * 2, rtol=1e-14)


def test_published_reflectances_of_glass():
    """Glass, n = 1.5: 4 % at normal incidence; R_s = 9.2 %, R_p = 0.85 % at 45 deg (Hecht)."""
    r_s, r_p = fresnel_amplitudes(1.0, 1.5)
    assert r_s**2 == pytest.approx(0.04, abs=1e-12) and r_p**2 == pytest.approx(0.04, abs=1e-12)
    r_s, r_p = fresnel_amplitudes(math.cos(math.radians(45.0)), 1.5)
    assert r_s**2 == pytest.approx(0.0920, abs=5e-5)
    assert r_p**2 == pytest.approx(0.00846, abs=5e-5)


def test_brewster_angle_of_water_and_zero_p_reflectance():
    assert brewster_angle_deg(1.33) == pytest.approx(53.06, abs=0.01)
    _, r_p = fresnel_amplitudes(math.cos(math.radians(brewster_angle_deg(1.33))), 1.33)
    assert abs(r_p) < 1e-15


def test_mueller_dop_of_reflected_unpolarized_light_is_the_closed_form():
    theta = np.radians(np.linspace(0.5, 89.5, 179))
    for n in (1.33, 1.5, 2.4):
        M = fresnel_reflection_mueller(np.cos(theta), n)
        out = M @ np.array([1.0, 0.0, 0.0])
        rs, rp = bw_reflectances(theta, n)
        np.testing.assert_allclose(out[:, 0], 0.5 * (rs + rp), rtol=1e-10)
        np.testing.assert_allclose(out[:, 1] / out[:, 0], (rs - rp) / (rs + rp), atol=1e-10)
        assert np.all(out[:, 2] == 0)
        # s-polarized light stays s-polarized with R_s, p with R_p
        np.testing.assert_allclose((M @ np.array([1.0, 1.0, 0.0]))[:, 0], rs, rtol=1e-10)
        np.testing.assert_allclose((M @ np.array([1.0, -1.0, 0.0]))[:, 0], rp, atol=1e-14)


# --------------------------------------------------------------------------------------- render
def test_unpolarized_sky_reflected_by_water_dop_vs_incidence_and_brewster():
    """
    Under a thick overcast (unpolarized, radiance 1.7) water reflects with R = (R_s + R_p)/2.

    DoP (R_s - R_p)/(R_s + R_p) polarized horizontally (E perpendicular to the plane of
    incidence); fully polarized at Brewster's angle (53.06 deg incidence, elevation -36.94 deg).
    """
    f = render({'clouds': OVERCAST, 'ground': WATER})
    r, R, g = geometry(f)
    assert g.sum() > 10000
    theta = np.arccos(np.clip(-r[g, 2], 0.0, 1.0))  # incidence from the normal (up)
    rs, rp = bw_reflectances(np.maximum(theta, 1e-6), 1.33)
    dop = f.dop.reshape(-1)[g]
    inten = f.intensity.reshape(-1)[g]
    np.testing.assert_allclose(inten, 1.7 * 0.5 * (rs + rp), rtol=2e-4, atol=1e-6)
    far = theta > np.radians(3.0)  # near the nadir (R_s = R_p) the E-vector is undefined
    np.testing.assert_allclose(dop[far], ((rs - rp) / (rs + rp))[far], atol=2e-4)
    d = cv.axial_difference_deg(
        np.degrees(f.aop_rad.reshape(-1)[g][far]), np.degrees(horizontal_aop(r[g][far], R))
    )
    assert np.abs(d).max() < 0.05
    # Brewster: the pixels within 0.3 deg of 53.06 deg incidence are (nearly) fully polarized
    b = np.abs(np.degrees(theta) - brewster_angle_deg(1.33)) < 0.3
    assert b.sum() > 50
    assert dop[b].min() > 0.999
    assert not f.valid.reshape(-1)[g].any()  # ground is never sky


@pytest.mark.parametrize(
    'sky',
    [
        {'model': 'rayleigh', 'dop_max': 0.8},
        {'model': 'berry_dennis_lee', 'separation_deg': 18.0, 'dop_max': 0.75},
    ],
)
def test_at_brewster_any_polarized_sky_is_reflected_fully_s_polarized(sky):
    """
    R_p = 0 at Brewster's angle: whatever the sky's polarization there, only E along s is left.

    Off Brewster by x the sky's U leaks in through r_s r_p ~ x: the E-vector turns away from the
    horizontal by O(x) (about 0.9 deg per deg here), so the bound grows with x.
    """
    f = render({'ground': WATER}, sky=sky)
    r, R, g = geometry(f)
    theta = np.degrees(np.arccos(np.clip(-r[:, 2], 0.0, 1.0)))
    off = np.abs(theta - brewster_angle_deg(1.33))
    b = g & (off < 0.2)
    assert b.sum() > 50 and (off[b] < 0.02).sum() > 10
    dop = f.dop.reshape(-1)[b]
    assert dop.min() > 0.999 and dop.max() <= 1.0
    d = cv.axial_difference_deg(
        np.degrees(f.aop_rad.reshape(-1)[b]), np.degrees(horizontal_aop(r[b], R))
    )
    assert np.all(np.abs(d) < 0.02 + 1.2 * off[b])


def test_a_mirror_at_normal_incidence_keeps_the_zenith_sky_e_vector():
    """
    A camera looking straight down sees the zenith's light with its E-vector kept in the lab.

    r_s = r_p = (1 - n)/(1 + n): R_0 = ((n - 1)/(n + 1))^2 times the zenith's radiance, the same
    DoP, and the same E-vector in ENU as an upward camera measures at the zenith.
    """
    cam = CameraModel(width_px=64, height_px=48)  # pinhole, small field
    pix = PixelSelection(mode='region', region=(31, 23, 2, 2))
    sun = SunDirection(70.0, 40.0)
    down = render({'ground': WATER}, camera=cam, att=(30.0, 180.0, 0.0), pixels=pix, sun=sun)
    rd, Rd, g = geometry(down)
    assert g.all() and rd[:, 2].max() < -0.9999
    r0 = ((1.33 - 1) / (1.33 + 1)) ** 2
    np.testing.assert_allclose(down.intensity.reshape(-1), r0, rtol=1e-3)
    # the sky at the mirror rays (Rayleigh: E = sun x ray, DoP = 0.8 sin^2 g / (1 + cos^2 g))
    m = rd * np.array([1.0, 1.0, -1.0])
    s = cv.enu_direction(sun.azimuth_deg, sun.altitude_deg)
    cg = m @ s
    np.testing.assert_allclose(down.dop.reshape(-1), 0.8 * (1 - cg**2) / (1 + cg**2), rtol=1e-4)
    e_sky = np.cross(s, m)
    e_sky /= np.linalg.norm(e_sky, axis=1, keepdims=True)
    # and an upward camera measures the same E-vector at the zenith (eq 28 AoP lifted to 3-D)
    up = render(None, camera=cam, att=(30.0, 0.0, 0.0), pixels=pix, sun=sun)
    _, Ru, _ = geometry(up)
    e_down = (Rd @ cv.evector_cam_from_aop(down.aop_rad.reshape(-1), down.rays_cam.T).T).T
    e_up = (Ru @ cv.evector_cam_from_aop(up.aop_rad.reshape(-1), up.rays_cam.T).T).T

    def along_surface_deg(e1, e2):  # axial angle between the horizontal (E, N) components
        a1 = np.degrees(np.arctan2(e1[:, 0], e1[:, 1]))
        a2 = np.degrees(np.arctan2(e2[:, 0], e2[:, 1]))
        return np.abs(cv.axial_difference_deg(a1, a2))

    # at 0.03-0.06 deg from the nadir: the component along the surface kept to O(angle^2)
    assert along_surface_deg(e_down, e_sky).max() < 1e-3
    assert along_surface_deg(e_down, e_up).max() < 0.5  # the pixels see slightly different sky


def test_reflected_polarized_sky_matches_a_jones_calculus():
    """
    The Rayleigh sky (E = sun x ray, DoP = d_max sin^2 g/(1 + cos^2 g)) reflected by water.

    The fully polarized part as a Jones vector in 3-D (r_s along s, r_p along the p axes that
    share their component along the surface, so that a normal-incidence mirror keeps E), the
    unpolarized part with (R_s + R_p)/2, (R_s - R_p)/2; summed Stokes -> DoP, AoP, radiance.
    """
    half = 0.5
    water = {'albedo': 0.3, 'specular': {'fraction': half, 'refractive_index': 1.5}}
    f = render({'ground': water})
    r, R, g = geometry(f)
    d = r[g]
    up = np.array([0.0, 0.0, 1.0])
    m = d * np.array([1.0, 1.0, -1.0])
    sun = cv.enu_direction(SUN.azimuth_deg, SUN.altitude_deg)
    cg = m @ sun
    dop_sky = 0.8 * (1 - cg**2) / (1 + cg**2)
    e = np.cross(sun, m)
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    s = np.cross(up, d)
    keep = np.linalg.norm(s, axis=1) > 0.05  # away from the nadir
    d, m, e, dop_sky, s = d[keep], m[keep], e[keep], dop_sky[keep], s[keep]
    s /= np.linalg.norm(s, axis=1, keepdims=True)
    h = d - d[:, 2:3] * up  # horizontal part, shared by d and m
    h /= np.linalg.norm(h, axis=1, keepdims=True)

    def p_axis(k):  # unit vector perpendicular to k and s with a positive component along h
        p = np.cross(s, k)
        return p * np.sign(np.sum(p * h, axis=1))[:, None]

    cos_i = m[:, 2]
    theta = np.arccos(cos_i)
    t = snell(theta, 1.5)
    r_s = -np.sin(theta - t) / np.sin(theta + t)
    r_p = -np.tan(theta - t) / np.tan(theta + t)
    jones = (r_s * np.sum(e * s, axis=1))[:, None] * s + (r_p * np.sum(e * p_axis(m), axis=1))[
        :, None
    ] * p_axis(d)
    # Stokes of the reflected fully polarized part, in a fixed basis (s, p_d) of the viewing ray
    a_s, a_p = np.sum(jones * s, axis=1), np.sum(jones * p_axis(d), axis=1)
    i_pol = dop_sky * (a_s**2 + a_p**2)
    q_pol = dop_sky * (a_s**2 - a_p**2)
    u_pol = dop_sky * 2 * a_s * a_p
    i_unp = (1 - dop_sky) * 0.5 * (r_s**2 + r_p**2)
    q_unp = (1 - dop_sky) * 0.5 * (r_s**2 - r_p**2)
    i_tot = half * (i_pol + i_unp) + (1 - half) * 0.3 * 1.0  # uniform dome radiance 1
    q_tot, u_tot = half * (q_pol + q_unp), half * u_pol
    dop_exp = np.hypot(q_tot, u_tot) / i_tot
    chi = 0.5 * np.arctan2(u_tot, q_tot)
    e_out = np.cos(chi)[:, None] * s + np.sin(chi)[:, None] * p_axis(d)
    aop_exp = cv.aop_from_evector_cam_rad((R.T @ e_out.T).T)
    np.testing.assert_allclose(f.intensity.reshape(-1)[g][keep], i_tot, rtol=2e-4)
    np.testing.assert_allclose(f.dop.reshape(-1)[g][keep], dop_exp, atol=3e-4)
    pol = dop_exp > 0.02  # the AoP of a nearly unpolarized pixel is noise
    da = cv.axial_difference_deg(
        np.degrees(f.aop_rad.reshape(-1)[g][keep][pol]), np.degrees(aop_exp[pol])
    )
    assert pol.sum() > 5000 and np.abs(da).max() < 0.1


def test_diffuse_ground_is_albedo_times_the_cosine_weighted_dome_radiance():
    # uniform sky radiance 1: exactly the albedo, unpolarized
    f = render({'ground': {'albedo': 0.35}})
    _, _, g = geometry(f)
    np.testing.assert_allclose(f.intensity.reshape(-1)[g], 0.35, rtol=1e-6)
    assert (f.dop.reshape(-1)[g] == 0).all() and (f.aop_rad.reshape(-1)[g] == 0).all()
    # a CIE clear sky: (1/pi) int L cos(z) dOmega by a fine midpoint rule in zenith angle/azimuth
    radiance = {'model': 'cie_clear', 'type': 12}
    f = render({'ground': {'albedo': 0.35}}, radiance=radiance, att=(20.0, 10.0, 5.0))
    r, R, g = geometry(f)
    model = make_radiance_model(radiance)
    z = np.radians(np.linspace(0.0, 90.0, 361)[:-1] + 0.125)
    az = np.radians(np.arange(720) * 0.5 + 0.25)
    Z, A = np.meshgrid(z, az, indexing='ij')
    enu = np.stack([np.sin(Z) * np.sin(A), np.sin(Z) * np.cos(A), np.cos(Z)]).reshape(3, -1)
    sun = cv.enu_direction(SUN.azimuth_deg, SUN.altitude_deg)
    L = np.asarray(model.radiance(R.T @ sun, R[2], (R.T @ enu).astype(np.float32)), float)
    w = (np.cos(Z) * np.sin(Z)).reshape(-1)
    lbar = float(np.sum(L * w) / np.sum(w))
    assert g.sum() > 1000
    np.testing.assert_allclose(f.intensity.reshape(-1)[g], 0.35 * lbar, rtol=5e-3)


def test_skyline_obstacles_stay_opaque_above_the_horizon_and_are_reflected_below():
    """A 20 deg tree line of radiance 0.3 under an unpolarized overcast: seen in the water too."""
    atm = {
        'clouds': OVERCAST,
        'skyline': {'elevation_deg': 20.0, 'ground_radiance': 0.3},
        'ground': WATER,
    }
    f = render(atm)
    r, _, g = geometry(f)
    elev = np.degrees(np.arcsin(np.clip(r[:, 2], -1, 1)))
    has = f.pixels.has_ray.reshape(-1)
    trees = has & (elev > 0.05) & (elev < 19.95)
    np.testing.assert_allclose(f.intensity.reshape(-1)[trees], 0.3)
    assert (f.dop.reshape(-1)[trees] == 0).all()
    theta = np.arccos(np.clip(-r[:, 2], 0, 1))
    rs, rp = bw_reflectances(np.maximum(theta, 1e-6), 1.33)
    tree_image = g & (elev > -19.95) & (elev < -0.05)
    sky_image = g & (elev < -20.05)
    assert tree_image.sum() > 1000 and sky_image.sum() > 1000
    np.testing.assert_allclose(
        f.intensity.reshape(-1)[tree_image], (0.3 * 0.5 * (rs + rp))[tree_image], rtol=2e-4
    )
    np.testing.assert_allclose(
        f.intensity.reshape(-1)[sky_image], (1.7 * 0.5 * (rs + rp))[sky_image], rtol=2e-4
    )


def test_a_tilted_pinhole_camera_sees_the_ground_and_the_mosaic_shows_its_polarization():
    """Optical axis 20 deg below the horizon: mostly water; its mosaic keeps Malus' law."""
    cam = CameraModel(width_px=96, height_px=80, focal_length_mm=0.3)  # +-29 deg across
    sensor = {'mosaic': {'layout': [[90, 45], [135, 0]]}, 'quantization': {'bits': 16}}
    f = render({'clouds': OVERCAST, 'ground': WATER}, camera=cam, att=(0, 110, 0), sensor=sensor)
    r, R, g = geometry(f)
    assert 0.5 < g.mean() < 0.95
    # the noise-free values are the ground's: Brewster-like strong horizontal polarization
    dop_i = f.dop_ideal.reshape(-1)[g]
    theta = np.arccos(np.clip(-r[g, 2], 0, 1))
    rs, rp = bw_reflectances(theta, 1.33)
    np.testing.assert_allclose(dop_i, (rs - rp) / (rs + rp), atol=2e-4)
    # the mosaic: each pixel behind its analyser phi (from +x_cam, sensor.py) reads
    # N0 S0 (1 - DoP (cos 2phi cos 2AoP - sin 2phi sin 2AoP)) with the ground's S0, DoP, AoP
    phi = np.radians(np.tile(np.array([[90.0, 45.0], [135.0, 0.0]]), (40, 48)))
    a = f.aop_ideal_rad.astype(float)
    p = f.dop_ideal.astype(float)
    expected = f.intensity.astype(float) * (
        1 - p * (np.cos(2 * phi) * np.cos(2 * a) - np.sin(2 * phi) * np.sin(2 * a))
    )
    # the 0 and 90 deg analysers (the 45/135 ones also depend on the layout's pol45_toward)
    ground_img = g.reshape(f.dop_ideal.shape) & (np.cos(2 * phi) ** 2 > 0.5)
    ratio = f.mosaic.astype(float)[ground_img] / expected[ground_img]
    bright = f.mosaic[ground_img] > 2000  # counts: quantisation below 2.5e-4
    assert bright.sum() > 500 and np.median(p[ground_img]) > 0.3
    assert ratio[bright].max() / ratio[bright].min() - 1 < 2e-3
    # unpolarized ground (no specular part) would read N0 S0 on every analyser: not what we see
    unpolarized = f.mosaic.astype(float)[ground_img] / f.intensity.astype(float)[ground_img]
    assert unpolarized[bright].max() / unpolarized[bright].min() > 2


def test_ground_is_a_budget_source():
    cfg = BudgetConfig(scene=Scene(atmosphere={'ground': {'albedo': 0.2}}))
    assert 'ground' in SOURCES and declared_sources(cfg) == ['ground']
    off = without(cfg, 'ground')
    assert off.scene.atmosphere is None and declared_sources(off) == []
    both = BudgetConfig(scene=Scene(atmosphere={'ground': {}, 'skyline': {'elevation_deg': 5}}))
    assert without(both, 'ground').scene.atmosphere == {'skyline': {'elevation_deg': 5}}


def test_undeclared_ground_costs_nothing_and_a_declared_one_runs_once():
    instrumentation.reset()
    f = render({'skyline': {'elevation_deg': 5.0}})
    assert 'atmosphere.ground' not in instrumentation.counts()
    assert set(f.meta['atmosphere']) == {'skyline'}
    instrumentation.reset()
    f = render({'ground': {'albedo': 0.1, 'specular': {'refractive_index': 1.5}}})
    assert instrumentation.counts().get('atmosphere.ground') == 1
    assert f.meta['atmosphere']['ground'] == {
        'albedo': 0.1,
        'specular': {'fraction': 1.0, 'refractive_index': 1.5},
    }


def test_a_camera_that_sees_no_ground_is_unchanged():
    cam = CameraModel(width_px=64, height_px=48)
    a = render({'ground': WATER}, camera=cam, att=(0, 60, 0))
    b = render(None, camera=cam, att=(0, 60, 0))
    np.testing.assert_array_equal(a.aop_rad, b.aop_rad)
    np.testing.assert_array_equal(a.dop, b.dop)
    np.testing.assert_array_equal(a.valid, b.valid)


@pytest.mark.parametrize(
    'ground, word',
    [
        ({'albedo': 1.5}, 'albedo'),
        ({'albedo': 'dark'}, 'albedo'),
        ({'albedo': True}, 'albedo'),
        ({'specular': {'refractive_index': 1.0}}, 'refractive_index'),
        ({'specular': {'refractive_index': float('nan')}}, 'refractive_index'),
        ({'specular': {'fraction': -0.1}}, 'fraction'),
        ({'specular': {'roughness': 0.1}}, 'roughness'),
        ({'specular': 0.5}, 'specular'),
        ({'colour': 'green'}, 'colour'),
        ([0.2], 'ground'),
    ],
)
def test_bad_ground_is_a_one_line_scene_error(ground, word):
    with pytest.raises(SceneError, match=word):
        scene_from_dict({'atmosphere': {'ground': ground}})


def test_the_example_lake_scene_shows_polarized_water_below_the_tree_line():
    from pathlib import Path

    from polarization_compass.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / 'config/scenes/lake_fisheye.yaml')
    f = Renderer(scene.replace(pixels=PixelSelection.grid(160, 128))).render()
    r, R, g = geometry(f)
    assert g.sum() > 500 and not f.valid.reshape(-1)[g].any()
    assert np.median(f.dop.reshape(-1)[g]) > 0.05  # the water's reflection is polarized
    assert declared_sources(BudgetConfig(scene=scene)) == ['skyline', 'ground']
