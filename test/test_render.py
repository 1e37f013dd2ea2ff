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
The renderer against the paper's own formulas, and its invariants.

The formulas: eq 18 in ENU, then eq 27/28.
"""

import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass import instrumentation
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.fastmath import axial_atan2_array
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
from polarization_compass.sky import rayleigh_reference
import pytest

GRID = PixelSelection.grid(48, 40)


def reference_aop_dop(frame, dop_max=1.0):
    """
    Return AoP and DoP by the paper's path, in float64 with numpy.

    The paper's path: rays to ENU (eq 22), azimuth/altitude (eqs 23-24), E from eq 18, back to the
    camera (eq 27), AoP by eq 28 -- computed in float64 with numpy, independent of the render
    kernel.
    """
    att = frame.attitude
    R = cv.R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg)
    rays_enu = (R @ frame.rays_cam.astype(float)).T
    az, alt = cv.azimuth_altitude_from_enu(rays_enu)
    E_enu, dop = rayleigh_reference(
        frame.sun.azimuth_deg, frame.sun.altitude_deg, az, alt, dop_max
    )
    E_cam = E_enu @ R
    aop = np.arctan2(E_cam[:, 0], E_cam[:, 1])
    return aop, dop


@given(
    st.floats(0, 360),
    st.floats(-30, 30),
    st.floats(-30, 30),
    st.floats(0, 360),
    st.floats(0, 85),
    st.floats(0.3, 1.0),
)
def test_render_matches_paper_formulas(bearing, pitch, roll, sun_az, sun_alt, dop_max):
    scene = Scene(pixels=GRID, sky={'model': 'rayleigh', 'dop_max': dop_max})
    f = Renderer(scene).render(
        attitude=cv.CameraAttitude(bearing, pitch, roll), sun=SunDirection(sun_az, sun_alt)
    )
    aop_ref, dop_ref = reference_aop_dop(f, dop_max)
    v = f.valid.reshape(-1)
    assert v.sum() > 0.5 * v.size
    d = cv.fold_axial_rad(aop_ref[v] - f.aop_rad.reshape(-1)[v].astype(float))
    assert np.degrees(np.abs(d)).max() < 2e-3  # float32 rays and kernel vs float64 reference
    np.testing.assert_allclose(f.dop.reshape(-1)[v], dop_ref[v], atol=2e-6)
    assert np.all(f.aop_rad >= -np.pi / 2) and np.all(f.aop_rad < np.pi / 2)
    assert np.all(np.isfinite(f.aop_rad)) and np.all(np.isfinite(f.dop))


@given(st.floats(0, 360), st.floats(-30, 30), st.floats(-30, 30), st.floats(5, 85))
def test_evector_is_perpendicular_to_sun_and_view(bearing, pitch, roll, sun_alt):
    f = Renderer(Scene(pixels=GRID)).render(
        attitude=cv.CameraAttitude(bearing, pitch, roll), sun=SunDirection(123.0, sun_alt)
    )
    v = f.valid.reshape(-1)
    e = cv.evector_cam_from_aop(
        f.aop_rad.reshape(-1)[v].astype(float), f.rays_cam[:, v].T.astype(float)
    )
    assert np.abs(e @ f.sun_cam).max() < 1e-4


def test_dop_is_dop_max_at_90_degrees_from_the_sun():
    scene = Scene(pixels=PixelSelection.full(), sky={'model': 'rayleigh', 'dop_max': 0.8})
    f = Renderer(scene).render(attitude=cv.CameraAttitude(0, 0, 0), sun=SunDirection(0, 30))
    cos_g = f.sun_cam @ f.rays_cam.astype(float)
    ring = np.abs(cos_g) < 2e-4
    assert ring.sum() > 100
    np.testing.assert_allclose(f.dop.reshape(-1)[ring], 0.8, atol=1e-6)
    assert f.dop.max() <= 0.8 + 1e-6


def test_aop_mirror_symmetry_about_the_solar_meridian():
    """
    The AoP is mirror-symmetric about the solar meridian.

    psi = 0, level: the solar meridian is the column through the principal point; mirroring x flips
    AoP.
    """
    cam = CameraModel()
    f = Renderer(Scene(pixels=PixelSelection.full())).render(
        attitude=cv.CameraAttitude(0, 0, 0), sun=SunDirection(0, 40)
    )
    a, ok = f.aop_rad, f.valid
    mirrored, ok_m = a[:, ::-1], ok[:, ::-1]  # x -> W + 1 - x, since cx = (W + 1) / 2
    assert f.x_px[0, 0] + f.x_px[0, -1] == 2 * cam.cx_px
    both = ok & ok_m
    d = cv.fold_axial_rad(a[both].astype(float) + mirrored[both].astype(float))
    assert np.degrees(np.abs(d)).max() < 1e-4


def test_subsets_equal_the_full_render_at_their_pixels():
    scene = Scene(sky={'model': 'rayleigh', 'dop_max': 1.0})
    att, sun = cv.CameraAttitude(33, -12, 7), SunDirection(200, 35)
    full = Renderer(scene).render(attitude=att, sun=sun)
    strided = Renderer(scene, pixels=PixelSelection.strided(16)).render(attitude=att, sun=sun)
    ys = (strided.y_px[:, 0] - 1).astype(int)
    xs = (strided.x_px[0] - 1).astype(int)
    np.testing.assert_array_equal(strided.aop_rad, full.aop_rad[np.ix_(ys, xs)])
    np.testing.assert_array_equal(strided.valid, full.valid[np.ix_(ys, xs)])
    px = [1, 2448, 700, 1500]
    py = [1, 2048, 1000, 20]
    lst = Renderer(scene, pixels=PixelSelection.explicit(px, py)).render(attitude=att, sun=sun)
    np.testing.assert_array_equal(lst.aop_rad, full.aop_rad[np.array(py) - 1, np.array(px) - 1])
    assert lst.aop_rad.shape == (4,)


def test_sparse_render_evaluates_only_the_requested_rays():
    """
    A sparse render evaluates only the requested rays.

    Cost proportional to the pixels requested: the kernel is handed exactly the selected rays.
    """
    r = Renderer(Scene(), pixels=PixelSelection.strided(8))
    assert r.pixels.rays_cam.shape == (3, 256 * 306)
    seen = []
    orig = r.sky.polarization
    r.sky.polarization = lambda s, z, rays, lim: (
        seen.append(rays.shape[1]),
        orig(s, z, rays, lim),
    )[1]
    r.render(sun=SunDirection(0, 30))
    assert seen == [256 * 306]


def test_validity_mask_sun_disk_horizon_and_dop():
    scene = Scene(
        pixels=PixelSelection.full(),
        validity=Scene().validity.__class__(
            sun_exclusion_deg=5.0, min_altitude_deg=2.0, min_dop=0.1
        ),
    )
    # camera pitched 50 deg so that the horizon and the sun are both in view
    f = Renderer(scene).render(attitude=cv.CameraAttitude(0, -50, 0), sun=SunDirection(0, 20))
    rays = f.rays_cam.astype(float)
    ang_sun = np.degrees(np.arccos(np.clip(f.sun_cam @ rays, -1, 1)))
    alt = np.degrees(np.arcsin(np.clip(f.zenith_cam @ rays, -1, 1)))
    dop = (1 - np.cos(np.radians(ang_sun)) ** 2) / (1 + np.cos(np.radians(ang_sun)) ** 2)
    expected = (ang_sun >= 5.0) & (alt >= 2.0) & (dop >= 0.1)
    margin = (
        (np.abs(ang_sun - 5.0) > 1e-3) & (np.abs(alt - 2.0) > 1e-3) & (np.abs(dop - 0.1) > 1e-5)
    )
    got = f.valid.reshape(-1)
    assert (~expected).sum() > 1000 and expected.sum() > 1000
    np.testing.assert_array_equal(got[margin], expected[margin])
    assert np.all(f.aop_rad[~f.valid] == 0) and np.all(f.dop[~f.valid] == 0)


def test_ideal_scene_runs_no_sensor_or_radiance_stage():
    instrumentation.reset()
    Renderer(Scene(pixels=GRID)).render(sun=SunDirection(10, 30))
    stages = instrumentation.counts()
    assert stages.get('sky.rayleigh') == 1 and stages.get('geometry') == 1
    assert not any(k.startswith(('sensor', 'radiance')) for k in stages), stages


def test_worked_example_tilted_camera_sun_direction():
    """
    Worked example: the sun direction for a tilted camera.

    Hand calculation (eq 21): psi = 90, pitch = -20, sun at azimuth 0, altitude 50. s_cam = Rx(20)
    Rz(90) (0, cos50, sin50) = (-cos50, -sin20 sin50, cos20 sin50).
    """
    f = Renderer(Scene(pixels=GRID)).render(
        attitude=cv.CameraAttitude(90, -20, 0), sun=SunDirection(0, 50)
    )
    c50, s50 = math.cos(math.radians(50)), math.sin(math.radians(50))
    np.testing.assert_allclose(
        f.sun_cam,
        [-c50, -math.sin(math.radians(20)) * s50, math.cos(math.radians(20)) * s50],
        atol=1e-12,
    )
    assert f.psi_deg == pytest.approx(90.0)


def test_fast_axial_atan2_against_numpy():
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.normal(size=200000), [0, 0, 1, -1, 0, 1e-30, -1e-30, 3, -3]]).astype(
        np.float32
    )
    y = np.concatenate([rng.normal(size=200000), [0, 1, 0, 0, -1, 1e-30, 1e-30, -3, 3]]).astype(
        np.float32
    )
    out = np.empty_like(x)
    axial_atan2_array(x, y, out)
    ref = cv.fold_aop_rad(np.arctan2(x.astype(float), y.astype(float)))
    d = cv.fold_axial_rad(out.astype(float) - ref)
    assert np.abs(d).max() < 3e-7
    assert np.all(out >= -np.pi / 2) and np.all(out < np.pi / 2)
    assert out[200000] == 0.0  # 0/0 (a ray at the sun) gives 0, not NaN


def test_sun_below_horizon_and_at_zenith_render_finite():
    r = Renderer(Scene(pixels=GRID))
    for sun in (SunDirection(0, -5), SunDirection(0, 90), SunDirection(0, 0)):
        f = r.render(attitude=cv.CameraAttitude(10, 0, 0), sun=sun)
        assert np.all(np.isfinite(f.aop_rad)) and np.all(np.isfinite(f.dop))


def test_sensor_noise_differs_between_frames_but_is_reproducible():
    from pathlib import Path

    from polarization_compass.scene_load import load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / 'config/scenes/imx250mzr_noisy.yaml')
    scene = scene.replace(camera=CameraModel(width_px=64, height_px=48))
    sun = SunDirection(0, 40)
    a, b = Renderer(scene), Renderer(scene)
    f1, f2 = a.render(sun=sun), a.render(sun=sun)
    g1 = b.render(sun=sun)
    assert not np.array_equal(f1.mosaic, f2.mosaic)  # fresh noise every frame
    np.testing.assert_array_equal(f1.mosaic, g1.mosaic)  # same scene seed, same frame index
    np.testing.assert_array_equal(
        a.render(sun=sun, seed=5).mosaic, b.render(sun=sun, seed=5).mosaic
    )
    assert f1.meta['sensor'] and f1.meta['effects']


def test_meta_records_how_the_sun_was_obtained():
    """A fixed sun claims no time; an ephemeris sun records the time it was computed for."""
    r = Renderer(Scene(pixels=GRID))
    m = r.render(time_utc='2019-11-15T11:30:00+08:00').meta
    assert m['sun_source'] == 'ephemeris' and m['sun_fixed'] is False and m['sun_model'] == 'spa'
    assert m['time_utc'] == '2019-11-15T03:30:00Z'
    m = r.render().meta  # the scene's time
    assert m['time_utc'] == '2019-11-15T06:00:00Z'
    m = r.render(sun=SunDirection(12.0, 34.0)).meta
    assert (m['sun_source'], m['sun_fixed'], m['sun_model'], m['time_utc']) == (
        'given',
        True,
        None,
        None,
    )
    assert (m['sun_azimuth_deg'], m['sun_altitude_deg']) == (12.0, 34.0)
    m = (
        Renderer(Scene(pixels=GRID, sun_fixed=(5.0, 60.0)))
        .render(time_utc='2020-01-01T00:00:00Z')
        .meta
    )
    assert (m['sun_source'], m['sun_fixed'], m['time_utc']) == ('scene', True, None)
    assert (m['sun_azimuth_deg'], m['sun_altitude_deg']) == (5.0, 60.0)
