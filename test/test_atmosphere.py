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
Clouds, haze and skyline against independent expectations.

The module is atmosphere.py; the expectations: the cloud transmission law, Pomozi et al. (2001)
(clear-sky AoP under thin clouds), depolarization under thick clouds, Preetham's luminance formula
in float64, the skyline geometry from the rays, zero cost when undeclared.
"""

import datetime as dt
import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass import instrumentation
from polarization_compass.atmosphere import Atmosphere, AtmosphereError, CloudLayer
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.radiance import make_radiance_model
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, SceneError
from polarization_compass.scene_load import scene_from_dict
import pytest

GRID = PixelSelection.grid(64, 56)
SUN = SunDirection(40.0, 35.0)
FISHEYE = CameraModel(
    model='fisheye_equidistant',
    width_px=400,
    height_px=400,
    focal_length_mm=1.0,
    pixel_pitch_x_um=7.5,
    pixel_pitch_y_um=7.5,
)


def render(
    atmosphere=None, seed=0, camera=None, pixels=GRID, sky=None, att=(0, 0, 0), time_utc=None, **kw
):
    scene = Scene(
        pixels=pixels,
        seed=seed,
        atmosphere=atmosphere,
        camera=camera or CameraModel(),
        sky=sky or {'model': 'rayleigh', 'dop_max': 0.8},
        **kw,
    )
    return Renderer(scene).render(attitude=cv.CameraAttitude(*att), sun=SUN, time_utc=time_utc)


def enu_rays(frame):
    a = frame.attitude
    R = cv.R_enu_cam_from_attitude(a.bearing_deg, a.pitch_deg, a.roll_deg)
    return (R @ frame.rays_cam.astype(float)).T


def test_undeclared_atmosphere_costs_nothing():
    instrumentation.reset()
    f = render()
    c = instrumentation.counts()
    assert not [k for k in c if k.startswith('atmosphere') or k == 'radiance.preetham'], c
    assert f.intensity is None and f.meta['atmosphere'] is None


def test_declared_stages_run_once_per_frame_and_are_recorded():
    instrumentation.reset()
    f = render(
        {'haze': {'turbidity': 4}, 'clouds': {'coverage': 0.4}, 'skyline': {'elevation_deg': 5}}
    )
    c = instrumentation.counts()
    for k in ('atmosphere.haze', 'atmosphere.clouds', 'atmosphere.skyline', 'radiance.preetham'):
        assert c.get(k) == 1, (k, c)
    assert set(f.meta['atmosphere']) == {'haze', 'clouds', 'skyline'}


def test_thick_overcast_depolarizes_and_shines_with_the_cloud_brightness():
    """Tau = 25: T = exp(-25) ~ 1e-11, so DoP ~ 0 and the radiance is the cloud's own (B = 1.7)."""
    f = render({'clouds': {'coverage': 1.0, 'optical_thickness': 25.0, 'brightness': 1.7}})
    up = enu_rays(f)[:, 2] > 0
    assert up.sum() > 1000
    assert float(f.dop.reshape(-1)[up].max()) < 1e-6
    np.testing.assert_allclose(f.intensity.reshape(-1)[up], 1.7, rtol=1e-5)


def test_thin_cloud_keeps_the_clear_sky_aop_and_lowers_dop_by_the_transmission_law():
    """
    Pomozi et al. (2001): under thin clouds the AoP is the clear sky's.

    With uniform clear radiance 1,
    DoP/DoP_clear = T / (T + B (1 - T)), T = exp(-tau) (float64 here).
    """
    clear = render()
    tau, b = 0.4, 1.5
    f = render({'clouds': {'coverage': 1.0, 'optical_thickness': tau, 'brightness': b}})
    v = clear.valid & f.valid
    assert v.mean() > 0.9
    d = cv.fold_axial_rad(f.aop_rad[v].astype(float) - clear.aop_rad[v].astype(float))
    assert np.abs(d).max() == 0.0
    t = math.exp(-tau)
    ratio = t / (t + b * (1 - t))
    np.testing.assert_allclose(f.dop[v], clear.dop[v] * ratio, rtol=2e-6, atol=1e-7)
    assert np.all(f.intensity[v] > 1.0)  # the cloud (B > 1) raises the radiance


def test_broken_clouds_cover_the_declared_fraction_and_hold_the_clear_sky_between():
    layer = CloudLayer(coverage=0.3, scale_m=500.0, seed=11)
    # a region of the layer far from the one the threshold was calibrated on
    g = np.linspace(0, 200 * 500.0, 300)
    e, n = np.meshgrid(g + 3e5, g - 7e5)
    frac = float((layer.density_at(e, n) > 0).mean())
    assert abs(frac - 0.3) < 0.06, frac
    clear = render()
    f = render({'clouds': {'coverage': 0.3, 'optical_thickness': 8.0}})
    changed = f.dop != clear.dop
    assert 0.1 < changed.mean() < 0.6
    same = ~changed & clear.valid
    np.testing.assert_array_equal(f.aop_rad[same], clear.aop_rad[same])
    np.testing.assert_array_equal(f.intensity[same], 1.0)


def test_pixels_are_cloudy_where_their_ray_meets_the_moving_layer_and_wind_moves_the_pattern():
    """
    Pixels are cloudy where their ray meets the moving layer; wind moves the pattern.

    The layer point of each pixel computed in float64 from its ENU ray (height * (e, n) / u); the
    cloud at a later time is the density field shifted by wind * dt.
    """
    atm = {
        'clouds': {
            'coverage': 0.5,
            'scale_m': 600.0,
            'height_m': 1500.0,
            'optical_thickness': 5.0,
            'softness': 0.05,
            'wind_mps': [12.0, -4.0],
        }
    }
    t0 = dt.datetime(2019, 11, 15, 6, 0, 0, tzinfo=dt.timezone.utc)
    layer = Atmosphere(atm, seed=3).clouds
    for seconds in (0.0, 90.0):
        f = render(atm, seed=3, time_utc=t0 + dt.timedelta(seconds=seconds))
        r = enu_rays(f)
        k = 1500.0 / r[:, 2]
        dens = layer.density_at(r[:, 0] * k, r[:, 1] * k, dt_s=seconds)
        cloudy = f.intensity.reshape(-1) != 1.0
        clear_ok = (dens == 0) | (dens > 1e-3)  # leave out edge pixels at float32 round-off
        np.testing.assert_array_equal(cloudy[clear_ok], (dens > 0)[clear_ok])
        if seconds == 0.0:
            first = cloudy
    assert (first != cloudy).mean() > 0.02  # the pattern moved
    shifted = layer.density_at(r[:, 0] * k - 12.0 * 90, r[:, 1] * k + 4.0 * 90, 0.0)
    np.testing.assert_allclose(shifted, dens, atol=1e-12)


def test_clouds_are_reproducible_by_seed():
    atm = {'clouds': {'coverage': 0.5}}
    a, b, c = render(atm, seed=5), render(atm, seed=5), render(atm, seed=6)
    np.testing.assert_array_equal(a.intensity, b.intensity)
    np.testing.assert_array_equal(a.dop, b.dop)
    assert not np.array_equal(a.intensity, c.intensity)


def test_haze_scales_dop_max_by_two_over_turbidity():
    """
    Haze scales DoP_max by two over the turbidity.

    T = 4: the polarized (molecular) share is 1/T, half of the clearest sky's (T = 2): DoP_max 0.8
    -> 0.4.
    """
    f = render(
        {'haze': {'turbidity': 4.0}},
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.8},
    )
    cos_g = f.sun_cam @ f.rays_cam.astype(float)
    ring = np.abs(cos_g) < 2e-4
    assert ring.sum() > 50
    np.testing.assert_allclose(f.dop.reshape(-1)[ring], 0.4, atol=1e-6)


def test_preetham_luminance_against_the_paper_formula_in_float64():
    T = 4.5
    m = make_radiance_model({'model': 'preetham', 'turbidity': T})
    A, B, C, D, E = (
        0.1787 * T - 1.4630,
        -0.3554 * T + 0.4275,
        -0.0227 * T + 5.3251,
        0.1206 * T - 2.5771,
        -0.0670 * T + 0.3703,
    )

    def F(th, g):
        return (1 + A * np.exp(B / np.cos(th))) * (1 + C * np.exp(D * g) + E * np.cos(g) ** 2)

    sun_zen = math.radians(50.0)
    sun = np.array([math.sin(sun_zen), 0.0, math.cos(sun_zen)])
    rng = np.random.default_rng(0)
    th = rng.uniform(0, math.radians(85), 200)
    ph = rng.uniform(0, 2 * math.pi, 200)
    rays = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    gam = np.arccos(np.clip(sun @ rays, -1, 1))
    ref = F(th, gam) / F(0.0, sun_zen)
    got = m.radiance(sun, np.array([0.0, 0.0, 1.0]), rays)
    np.testing.assert_allclose(got, ref, rtol=2e-4)
    assert (
        abs(
            float(m.radiance(sun, np.array([0.0, 0.0, 1.0]), np.array([[0.0], [0.0], [1.0]]))[0])
            - 1
        )
        < 1e-5
    )


def test_skyline_masks_what_lies_below_it():
    atm = {'skyline': {'elevation_deg': [10.0, 30.0, 10.0, 10.0], 'ground_radiance': 0.25}}
    f = render(atm, camera=FISHEYE, pixels=PixelSelection.full())
    clear = render(None, camera=FISHEYE, pixels=PixelSelection.full())
    r = enu_rays(f)
    az = np.degrees(np.arctan2(r[:, 0], r[:, 1])) % 360
    elev = np.degrees(np.arctan2(r[:, 2], np.hypot(r[:, 0], r[:, 1])))
    # the declared skyline, interpolated linearly in tan(elevation) between the 4 azimuths 0, 90,
    # 180, 270
    tans = np.tan(np.radians([10.0, 30.0, 10.0, 10.0, 10.0]))
    sky_el = np.degrees(np.arctan(np.interp(az, [0, 90, 180, 270, 360], tans)))
    has = clear.pixels.has_ray.reshape(-1)
    below = (elev < sky_el - 0.01) & has
    above = (elev > sky_el + 0.01) & has
    assert below.sum() > 1000 and above.sum() > 1000
    assert not f.valid.reshape(-1)[below].any()
    np.testing.assert_array_equal(f.valid.reshape(-1)[above], clear.valid.reshape(-1)[above])
    np.testing.assert_allclose(f.intensity.reshape(-1)[below], 0.25)
    assert (f.dop.reshape(-1)[below] == 0).all()


def test_random_skyline_is_seeded():
    a = Atmosphere({'skyline': {'max_elevation_deg': 20}}, seed=1).skyline.elevation_at(
        np.arange(360)
    )
    b = Atmosphere({'skyline': {'max_elevation_deg': 20}}, seed=1).skyline.elevation_at(
        np.arange(360)
    )
    c = Atmosphere({'skyline': {'max_elevation_deg': 20}}, seed=2).skyline.elevation_at(
        np.arange(360)
    )
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c) and a.max() <= 20 and a.min() >= 0


@pytest.mark.parametrize(
    'atm, word',
    [
        ({'clouds': {'coverage': 1.5}}, 'coverage'),
        ({'clouds': {'colour': 1}}, 'colour'),
        ({'haze': {'turbidity': 1.0}}, 'turbidity'),
        ({'skyline': {}}, 'skyline'),
        ({'fog': {}}, 'fog'),
        ({'clouds': {'wind_mps': [1]}}, 'wind_mps'),
    ],
)
def test_bad_atmosphere_is_a_one_line_scene_error(atm, word):
    with pytest.raises(SceneError, match=word):
        scene_from_dict({'atmosphere': atm})


def test_render_sky_refuses_an_atmosphere():
    r = Renderer(Scene(pixels=GRID, atmosphere={'haze': {'turbidity': 3}}))
    with pytest.raises(AtmosphereError):
        r.render_sky(np.array([0.0, 0.5, 0.8]), np.array([0.0, 0.0, 1.0]))


# ------------------------------------------------------------------------------------------ optics
SUN_IN_VIEW = SunDirection(200.0, 55.0)  # 35 deg from the zenith: inside a level fisheye's field


def render_optics(optics, camera=FISHEYE, pixels=None, sun=SUN_IN_VIEW, sensor=None, **kw):
    scene = Scene(
        pixels=pixels or PixelSelection.full(),
        camera=camera,
        optics=optics,
        sky={'model': 'rayleigh', 'dop_max': 0.8},
        sensor=sensor or {},
        **kw,
    )
    return Renderer(scene).render(attitude=cv.CameraAttitude(0, 0, 0), sun=sun)


def sun_image_point(frame, cam):
    """Equidistant projection r = f theta of the sun, from its camera-frame direction (float64)."""
    s = frame.sun_cam / np.linalg.norm(frame.sun_cam)
    theta = math.acos(s[2])
    phi = math.atan2(s[1], s[0])
    r_px = cam.focal_length_mm * theta / (cam.pixel_pitch_x_um * 1e-3)
    return cam.cx_px + r_px * math.cos(phi), cam.cy_px + r_px * math.sin(phi)


def test_undeclared_optics_cost_nothing():
    instrumentation.reset()
    f = render()
    assert not [k for k in instrumentation.counts() if k.startswith('optics')]
    assert f.meta['optics'] is None


def test_flare_ghosts_lie_on_the_line_through_the_sun_and_the_optical_centre():
    import cv2

    t = [-0.4, -0.7, -1.05]
    f = render_optics({'flare': {'positions': t, 'radius_px': 6, 'radiance': 0.5}})
    ghost = (f.intensity > 1.2).astype(np.uint8)  # clear sky has intensity 1, ghosts 1.5
    n, _, _, cent = cv2.connectedComponentsWithStats(ghost)
    assert n - 1 == 3
    cent = cent[1:] + 1.0  # 0-based pixel index -> 1-based coordinates
    sx, sy = sun_image_point(f, FISHEYE)
    cx, cy = FISHEYE.cx_px, FISHEYE.cy_px
    d = np.array([sx - cx, sy - cy])
    for gx, gy in cent:
        dist = abs(d[0] * (gy - cy) - d[1] * (gx - cx)) / np.linalg.norm(d)
        assert dist < 0.5, dist  # on the line (px)
    got_t = sorted(((cent - [cx, cy]) @ d) / (d @ d))
    np.testing.assert_allclose(got_t, sorted(t), atol=0.5 / np.linalg.norm(d))


def test_no_ghosts_when_the_sun_is_behind_a_pinhole():
    f = render_optics(
        {'flare': {}}, camera=CameraModel(), pixels=GRID, sun=SunDirection(0.0, -20.0)
    )
    assert np.all(f.intensity == 1.0)


def test_cos4_vignetting_of_a_pinhole_from_pixel_coordinates():
    cam = CameraModel()
    f = render_optics({'vignetting': {'law': 'cos4'}}, camera=cam, pixels=GRID)
    u = (f.x_px - cam.cx_px) * cam.pixel_pitch_x_um * 1e-3
    v = (f.y_px - cam.cy_px) * cam.pixel_pitch_y_um * 1e-3
    cos_t = cam.focal_length_mm / np.sqrt(cam.focal_length_mm**2 + u**2 + v**2)
    np.testing.assert_allclose(f.intensity, cos_t**4, rtol=2e-5)
    clear = render_optics(None, camera=cam, pixels=GRID)
    np.testing.assert_array_equal(f.dop, clear.dop)


def test_polynomial_vignetting_at_the_corner():
    cam = CameraModel(width_px=300, height_px=400)
    sel = PixelSelection.explicit(np.array([1, 150]), np.array([1, 200]))
    f = render_optics({'vignetting': {'k': [-0.3, 0.05, -0.01]}}, camera=cam, pixels=sel)
    r2 = ((1 - cam.cx_px) ** 2 + (1 - cam.cy_px) ** 2) / (0.25 * (300**2 + 400**2))
    np.testing.assert_allclose(
        f.intensity[0], 1 - 0.3 * r2 + 0.05 * r2**2 - 0.01 * r2**3, rtol=1e-6
    )
    r2c = ((150 - cam.cx_px) ** 2 + (200 - cam.cy_px) ** 2) / (0.25 * (300**2 + 400**2))
    np.testing.assert_allclose(
        f.intensity[1], 1 - 0.3 * r2c + 0.05 * r2c**2 - 0.01 * r2c**3, rtol=1e-6
    )
    assert f.intensity[0] < f.intensity[1] < 1.0


def test_sun_glare_is_unpolarized_light_falling_as_the_declared_power():
    g1, n = 40.0, 2.0
    f = render_optics({'sun': {'glare_at_1deg': g1, 'glare_exponent': n}})
    clear = render_optics(None)
    s = f.sun_cam / np.linalg.norm(f.sun_cam)
    gam = np.degrees(np.arccos(np.clip(s @ f.rays_cam.astype(float), -1, 1)))
    ok = clear.valid.reshape(-1) & (gam > 1.0)
    glare = g1 * gam[ok] ** -n
    np.testing.assert_allclose(f.intensity.reshape(-1)[ok], 1.0 + glare, rtol=2e-4)
    np.testing.assert_allclose(
        f.dop.reshape(-1)[ok], clear.dop.reshape(-1)[ok] / (1.0 + glare), rtol=2e-4, atol=1e-7
    )
    np.testing.assert_array_equal(f.aop_rad, clear.aop_rad)


def test_the_sun_in_the_field_saturates_the_sensor_and_those_pixels_are_invalid():
    sensor = {
        'mosaic': {},
        'exposure': {'full_well_e': 10500, 'fill': 0.45},
        'quantization': {'bits': 12},
        'demosaic': 'superpixel',
    }
    f = render_optics({'sun': {}}, sensor=sensor)
    sat = f.mosaic >= 4095
    assert 4 <= sat.sum() < 0.05 * sat.size
    ys, xs = np.nonzero(sat)
    sx, sy = sun_image_point(f, FISHEYE)
    assert np.hypot(xs + 1 - sx, ys + 1 - sy).max() < 40  # around the sun only
    blocks = sat.reshape(sat.shape[0] // 2, 2, sat.shape[1] // 2, 2).any(axis=(1, 3))
    assert not f.valid[blocks].any()


def test_a_full_frame_clouds_from_the_interpolated_grid_like_every_pixel_exactly():
    """
    A full frame's clouds from the interpolated grid match every pixel's.

    Contiguous blocks evaluate the layer on every 8th pixel and interpolate: against the per-pixel
    evaluation, the same cloud cover (1 %) and the same radiance except within a few pixels of
    cloud edges.
    """
    from polarization_compass.atmosphere import CloudLayer

    cam = CameraModel(width_px=480, height_px=400)
    f = render(None, camera=cam, pixels=PixelSelection.full())
    R = cv.R_enu_cam_from_attitude(0, 0, 0)
    layer = CloudLayer(coverage=0.5, scale_m=300.0, optical_thickness=3.0, seed=9)
    out = []
    for block in ((400, 480), None):
        aop, dop = f.aop_rad.reshape(-1).copy(), f.dop.reshape(-1).copy()
        inten, valid = np.ones(aop.size, np.float32), f.valid.reshape(-1).copy()
        layer.apply(R, f.rays_cam, aop, dop, inten, valid, 0.0, 0.0, block)
        out.append((inten, dop))
    (ig, dg), (ie, de) = out
    assert abs(float((ig > 1.1).mean()) - float((ie > 1.1).mean())) < 0.01  # edge ramps smeared
    d = np.abs(ig - ie)
    assert np.quantile(d, 0.90) < 0.01 and np.quantile(d, 0.95) < 0.05 and d.max() < 0.5
    assert abs(float(np.median(dg)) - float(np.median(de))) < 0.01
