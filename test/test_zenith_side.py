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
The zenith method's 180 deg side comes from the whole sky or a prior.

It never comes from the method's small window.

On the real ``sunny`` frame the 32 px zenith window is brighter on the side away from the sun
(lens-flare ghosts): a side taken from the window's brightness gradient was 177 deg wrong with
status ``ok``. Here the estimator alone (no whole-sky check layer) must give the visible sun's
side; a simulated frame with bright ghosts planted opposite the sun must too; and with neither a
usable sky nor a prior the result is axial (``ambiguous``) with a reason. References: the sun's
pixel (real frame) and the render's truth (simulated).
"""

import json
import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel
from polarization_compass.cli import main
from polarization_compass.estimators import make_estimator, Observation, Status
from polarization_compass.estimators.zenith import zenith_window
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
import pytest
import real_sky as R


def test_real_sunny_frame_side_from_the_whole_sky_not_the_flared_window(tmp_path, capsys):
    i, q, u = R.read_quadrants('sunny')
    # the premise: the zenith window is brighter AWAY from the visible sun (flare ghosts)
    cx, cy = R.CENTRE_PX
    (sx, sy), ref_sigma = R.FRAMES['sunny']
    ys, xs = np.mgrid[0 : i.shape[0], 0 : i.shape[1]]
    win = (np.abs(xs - cx) <= 16) & (np.abs(ys - cy) <= 16)
    toward = (xs - cx) * (sx - cx) + (ys - cy) * (sy - cy) > 0
    assert i[win & ~toward].mean() > i[win & toward].mean() + 0.01
    np.savez(tmp_path / 'sunny.npz', s0=i, s1=q, s2=u)
    (tmp_path / 'cam.yaml').write_text(R.camera_yaml_text('+x-y'))
    capsys.readouterr()
    assert (
        main(
            [
                'estimate',
                str(tmp_path / 'sunny.npz'),
                '--camera',
                str(tmp_path / 'cam.yaml'),
                '--sun-azimuth',
                '0',
                '--sun-altitude',
                f'{R.sun_altitude_deg("sunny"):.3f}',
                '--method',
                'zenith',
                '--no-sky-check',
            ]
        )
        == 0
    )
    (d,) = json.loads(capsys.readouterr().out)
    assert d['status'] == 'ok' and d['extras']['ambiguity_resolved_by'] == 'whole_sky', d['reason']
    err = float(cv.wrap_180_deg(d['psi_deg'] - R.expected_psi_deg('sunny')))
    assert abs(err) <= ref_sigma + 3 * max(d['sigma_deg'], 0.5), (err, d['sigma_deg'])


SMALL = Scene(radiance={'model': 'cie_clear'}).replace(
    camera=CameraModel(width_px=256, height_px=200, focal_length_mm=0.5)
)


def _ghosted(est, bearing, sun_alt, scene=SMALL, full=False):
    """
    Return a frame with a brighter anti-sun half and two bright ghosts.

    A frame with the window's half away from the sun 4x brighter and two bright ghosts in the
    anti-sun sky.
    """
    r = Renderer(scene) if full else Renderer(scene, pixels=est.pixels_needed(scene.camera))
    f = r.render(attitude=cv.CameraAttitude(bearing, 0.0, 0.0), sun=SunDirection(0.0, sun_alt))
    obs = Observation.from_frame(f, pitch_deg=0.0, roll_deg=0.0, camera=scene.camera)
    rays = np.asarray(obs.rays_cam).reshape(3, -1)
    psi = math.radians(f.psi_deg)
    sun_xy = np.array([-math.sin(psi), math.cos(psi)])  # psi = -atan2(s_x, s_y)
    away = rays[0] * sun_xy[0] + rays[1] * sun_xy[1] < 0
    (x_lo, x_hi, y_lo, y_hi), _ = zenith_window(scene.camera, est.knobs['window_px'])
    x = np.asarray(obs.x_px).reshape(-1)
    y = np.asarray(obs.y_px).reshape(-1)
    in_win = (x >= x_lo) & (x <= x_hi) & (y >= y_lo) & (y <= y_hi)
    inten = np.asarray(obs.intensity, dtype=np.float64).reshape(-1).copy()
    inten[in_win & away] *= 4.0
    for turn in (150.0, 210.0):  # two ghosts 60 deg off-axis, opposite-ish
        a = psi + math.radians(turn)
        g = np.array(
            [
                -math.sin(a) * math.sin(math.radians(60)),
                math.cos(a) * math.sin(math.radians(60)),
                math.cos(math.radians(60)),
            ]
        )
        inten[(g @ rays) > math.cos(math.radians(6.0))] *= 4.0
    obs = Observation(
        obs.aop_rad,
        obs.dop,
        obs.valid,
        obs.rays_cam,
        obs.x_px,
        obs.y_px,
        obs.camera,
        obs.sun_azimuth_deg,
        obs.sun_altitude_deg,
        inten.reshape(np.shape(obs.aop_rad)),
        0.0,
        0.0,
    )
    return f, obs, in_win, away


@pytest.mark.parametrize('bearing,sun_alt', [(25.0, 20.0), (205.0, 45.0), (290.0, 65.0)])
def test_planted_ghosts_opposite_the_sun_do_not_flip_the_side(bearing, sun_alt):
    est = make_estimator('zenith')
    f, obs, in_win, away = _ghosted(est, bearing, sun_alt)
    inten = np.asarray(obs.intensity).reshape(-1)
    assert (
        inten[in_win & away].mean() > 2.0 * inten[in_win & ~away].mean()
    )  # the window points the wrong way
    r = est.estimate(obs)
    assert r.status is Status.OK and r.extras['ambiguity_resolved_by'] == 'whole_sky', r.reason
    assert abs(cv.wrap_180_deg(r.psi_deg - f.psi_deg)) < 0.05


def test_full_frame_and_the_rendered_selection_decide_alike():
    est = make_estimator('zenith')
    f1, obs1, _, _ = _ghosted(est, 115.0, 35.0)
    f2, obs2, _, _ = _ghosted(est, 115.0, 35.0, full=True)
    assert np.ndim(obs2.aop_rad) == 2 and np.ndim(obs1.aop_rad) == 1
    r1, r2 = est.estimate(obs1), est.estimate(obs2)
    assert r1.extras['side_votes'] == r2.extras['side_votes']
    assert r1.status is r2.status is Status.OK
    assert abs(cv.wrap_180_deg(r1.psi_deg - f1.psi_deg)) < 0.05
    assert abs(cv.wrap_180_deg(r2.psi_deg - f2.psi_deg)) < 0.05


def test_neither_the_sky_nor_a_prior_decides_ambiguous():
    est = make_estimator('zenith', side_grid=0)
    f, obs, in_win, _ = _ghosted(est, 25.0, 30.0)
    r = est.estimate(obs)
    assert r.status is Status.AMBIGUOUS and r.axial and 'side_grid 0' in r.reason
    assert abs(cv.fold_axial_deg(r.psi_deg - f.psi_deg)) < 0.05
    # the grid read, but no usable sky outside the window
    est = make_estimator('zenith')
    f, obs, in_win, _ = _ghosted(est, 25.0, 30.0)
    valid = np.asarray(obs.valid).reshape(-1) & in_win
    obs = Observation(
        obs.aop_rad,
        obs.dop,
        valid.reshape(np.shape(obs.aop_rad)),
        obs.rays_cam,
        obs.x_px,
        obs.y_px,
        obs.camera,
        obs.sun_azimuth_deg,
        obs.sun_altitude_deg,
        obs.intensity,
    )
    r = est.estimate(obs)
    assert r.status is Status.AMBIGUOUS and r.axial and 'too little usable sky' in r.reason
    # a prior then decides
    obs = Observation(
        obs.aop_rad,
        obs.dop,
        obs.valid,
        obs.rays_cam,
        obs.x_px,
        obs.y_px,
        obs.camera,
        obs.sun_azimuth_deg,
        obs.sun_altitude_deg,
        obs.intensity,
        prior_bearing_deg=25.0 + 20.0,
    )
    r = est.estimate(obs)
    assert r.status is Status.OK and r.extras['ambiguity_resolved_by'] == 'prior'
    assert abs(cv.wrap_180_deg(r.bearing_deg - 25.0)) < 0.05
