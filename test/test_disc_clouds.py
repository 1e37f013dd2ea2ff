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
sm_asm and symmetry under broken clouds: right within their sigma, or a non-ok status.

The cloud model keeps the clear-sky AoP beneath the clouds (Pomozi et al. 2001) and only lowers
the DoP and raises the radiance, so the solar meridian is still the AOPLM map's mirror axis; but
the DoP field is no longer mirror-symmetric about it. Weighting each pixel by its own DoP^2 moved
both axes by degrees with a sigma that did not see it (before the fix, on the scenes below at
stride 32: sm_asm -6.9, -0.76, -10.4 deg at 22, 17, 6.7 sigma; symmetry -6.2, -2.3, +0.30 deg at
16, 29, 18 sigma; all status ok). References here are independent of the estimators: the true psi
of each render, the closed-form reflection of a sensor offset about an axis.
"""

import math

import numpy as np
from polarization_compass.conventions import CameraAttitude, fold_axial_deg
from polarization_compass.estimators import make_estimator, Observation
from polarization_compass.estimators._mirror import _pair_weights, mirror_map
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene_load import default_scene
import pytest

METHODS = ['sm_asm', 'symmetry']


def _cloudy(coverage, seed):
    return (
        default_scene()
        .replace(
            sky={'model': 'rayleigh', 'dop_max': 0.7},
            radiance={'model': 'cie_clear'},
            atmosphere={'clouds': {'coverage': coverage, 'optical_thickness': 3.0}},
        )
        .replace(seed=seed)
    )


def _run(est, scene, bearing_deg, sun=SunDirection(160.0, 35.0)):
    f = Renderer(scene, pixels=est.pixels_needed(scene.camera)).render(
        attitude=CameraAttitude(bearing_deg, 0.0, 0.0), sun=sun
    )
    return f, est.estimate(Observation.from_frame(f, camera=scene.camera))


@pytest.mark.parametrize('name', METHODS)
def test_broken_clouds_heading_within_sigma_or_refused(name):
    """
    Broken clouds: within 3 sigma of the truth, or not ok with a reason.

    30 and 70 % cover, noise-free. Most of them must still give a heading (a method that refuses
    every cloudy sky would pass the first half trivially).
    """
    est = make_estimator(name, stride=32)
    n_ok = 0
    cases = 0
    for coverage in (0.3, 0.7):
        for seed in range(3):
            f, res = _run(est, _cloudy(coverage, seed), 30.0 + 40.0 * seed)
            cases += 1
            if res.ok:
                n_ok += 1
                err = abs(float(fold_axial_deg(res.psi_deg - f.psi_deg)))
                assert err <= 3.0 * res.sigma_deg, (coverage, seed, err, res.sigma_deg, res.extras)
                assert err < 1.0, (coverage, seed, err)  # it was 0.76-10 deg
            else:
                assert res.reason and res.psi_deg is None and res.sigma_deg is None
    assert n_ok >= cases - 1, n_ok


@pytest.mark.parametrize('name', METHODS)
@pytest.mark.parametrize('sun_alt', [20.0, 55.0])
def test_clear_sky_still_exact(name, sun_alt):
    """
    A clear Rayleigh sky, level camera, noise-free: the heading is the closed-form truth.

    The truth is the render's psi (eq 21 from the bearing and the sun's azimuth); the pair-weight
    fixed point is as exact as the plain fit was (measured 1e-5 to 8e-5 deg at stride 16), and the
    sigma is small and covers the error.
    """
    scene = default_scene().replace(sky={'model': 'rayleigh', 'dop_max': 1.0})
    est = make_estimator(name, stride=16)
    for bearing in (12.0, 200.0):
        f, res = _run(est, scene, bearing, SunDirection(75.0, sun_alt))
        assert res.psi_deg is not None and res.status.value in ('ok', 'ambiguous'), res.reason
        want = float(fold_axial_deg(bearing - 75.0))  # psi = bearing - sun azimuth (eq 21)
        err = abs(float(fold_axial_deg(res.psi_deg - want)))
        assert err < 5e-4, (bearing, err)
        assert res.sigma_deg < 0.01 and err <= max(5.0 * res.sigma_deg, 1e-5), (
            err,
            res.sigma_deg,
        )


def test_pair_weights_are_mirror_symmetric():
    """
    The weight of a pixel equals the weight of its mirror image about the trial axis.

    Mirror images from the closed-form reflection of the sensor offset (mm) about the axis
    direction (sin theta, cos theta); the weights Q(p) Q(p') come from one DoP map, so a point and
    its image get the same weight even under broken clouds.
    """
    scene = _cloudy(0.7, 1)
    est = make_estimator('sm_asm', stride=16)
    f = Renderer(scene, pixels=est.pixels_needed(scene.camera)).render(
        attitude=CameraAttitude(70.0, 0.0, 0.0), sun=SunDirection(160.0, 35.0)
    )
    from polarization_compass.estimators._common import select_view

    obs = Observation.from_frame(f, camera=scene.camera)
    view = select_view(obs, est.knobs)
    cam = scene.camera
    mm = mirror_map(view, cam, 0.9 * math.hypot(cam.cx_px, cam.cy_px), est.knobs['min_dop'])
    assert 0.1 < (mm.weight > 0).mean() < 0.9  # clouds: part of the map has no weight
    rng = np.random.default_rng(3)
    px, py = cam.pixel_pitch_x_um * 1e-3, cam.pixel_pitch_y_um * 1e-3
    r = 0.4 * min(cam.cx_px * px, cam.cy_px * py)
    for theta in (0.3, 1.9):
        mg, mq, mp = mm.at(theta)
        u = rng.uniform(-r, r, 200)
        v = rng.uniform(-r, r, 200)
        a = np.array([math.sin(theta), math.cos(theta)])
        d = 2.0 * (u * a[0] + v * a[1])
        u2, v2 = d * a[0] - u, d * a[1] - v
        x, y = cam.cx_px + u / px, cam.cy_px + v / py
        x2, y2 = cam.cx_px + u2 / px, cam.cy_px + v2 / py
        w = _pair_weights(mg, mq, mp, x, y)
        w2 = _pair_weights(mg, mq, mp, x2, y2)
        assert (w > 0).any() and (w == 0).any()
        np.testing.assert_allclose(w, w2, rtol=1e-9, atol=1e-12)
