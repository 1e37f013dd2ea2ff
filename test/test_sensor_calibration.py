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
DoFP calibration errors against independent computations.

DoFP calibration errors (sensor ``calibration``): per-pixel polarizer angle, extinction-ratio
spread, gain non-uniformity and crosstalk, each against an independent float64 computation or its
declared statistics; undeclared it neither runs nor is counted; the fixed pattern is seeded and
tied to the sensor's pixels.
"""

import numpy as np
from polarization_compass import instrumentation as instr
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.conventions import CameraAttitude
from polarization_compass.mosaic import IMX250MZR_POL45
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, SceneError
from polarization_compass.scene_load import scene_from_dict
from polarization_compass.sensor import parse_sensor_config, simulate_mosaic
from polarization_compass.sensor_calibration import calibration_maps
import pytest

N0 = 5250.0  # default fill 0.5 x full well 10 500 e-
NOMINAL_DEG = np.array([[90.0, 45.0], [135.0, 0.0]])


def mosaic(cal, aop, dop, s0=None, extra=None, origin=(0, 0)):
    cfg = parse_sensor_config({'calibration': cal, **(extra or {})})
    layout = cfg.layout.shifted(origin[0] % 2, origin[1] % 2)
    return (
        simulate_mosaic(aop, dop, s0, cfg, layout, np.random.default_rng(0), origin),
        cfg,
        layout,
    )


def field(shape=(64, 80), dop=1.0):
    rng = np.random.default_rng(3)
    aop = rng.uniform(-np.pi / 2, np.pi / 2, shape).astype(np.float32)
    return aop, np.full(shape, dop, np.float32)


def malus(aop, dop, phi, d=1.0, g=1.0, s0=1.0):
    """
    Return the electrons behind a polarizer at camera angle phi (float64).

    Electrons behind a polarizer at camera angle phi: N0 S0 g (1 + d DoP cos 2(phi - AoLP_x)),
    AoLP_x = pi/2 - AoP (physics notes 1), float64.
    """
    aolp_x = np.pi / 2 - aop.astype(float)
    return N0 * s0 * g * (1.0 + d * dop * np.cos(2.0 * (phi - aolp_x)))


def nominal_phi(shape):
    """
    Return the camera-frame angles of the default layout's polarizers.

    Camera-frame angles (from +x towards +y) of the default layout: the IMX250MZR as delivered has
    its 45 deg polarizer towards +x-y, so a label theta lies at -theta in the camera frame.
    """
    sign = 1.0 if IMX250MZR_POL45 == '+x+y' else -1.0
    return sign * np.radians(np.tile(NOMINAL_DEG, (shape[0] // 2, shape[1] // 2)))


def test_polarizer_angle_errors_follow_malus_with_each_pixels_own_angle():
    aop, dop = field()
    m, cfg, layout = mosaic({'angle_error_deg': 2.0, 'seed': 4}, aop, dop)
    phi, _, _ = calibration_maps(cfg, layout, aop.shape)
    err_deg = np.degrees(phi - nominal_phi(aop.shape))
    assert abs(err_deg.std() - 2.0) < 0.1 and abs(err_deg.mean()) < 0.1
    np.testing.assert_allclose(m, malus(aop, dop, phi.astype(float)), rtol=1e-5, atol=0.05)
    ideal = malus(aop, dop, nominal_phi(aop.shape))
    assert np.abs(m - ideal).max() > 100  # the error matters at DoP 1


def test_gain_non_uniformity_has_the_declared_rms():
    shape = (200, 200)
    m, _, _ = mosaic({'gain_rms': 0.02}, np.zeros(shape, np.float32), np.zeros(shape, np.float32))
    g = m / N0
    assert abs(g.std() - 0.02) < 0.001 and abs(g.mean() - 1.0) < 0.001


def test_extinction_ratio_spread_is_log_normal_around_the_declared_ratio():
    shape = (200, 200)
    aop, dop = field(shape)
    m, cfg, layout = mosaic(
        {'extinction_ratio_spread': 0.5}, aop, dop, extra={'extinction_ratio': {'value': 20}}
    )
    _, dmap, _ = calibration_maps(cfg, layout, shape)
    er = (1 + dmap.astype(float)) / (1 - dmap.astype(float))
    assert abs(np.log(er).std() - 0.5) < 0.02 and abs(np.median(er) - 20) < 1.0
    np.testing.assert_allclose(
        m, malus(aop, dop, nominal_phi(shape), d=dmap.astype(float)), rtol=1e-5, atol=0.05
    )
    with pytest.raises(Exception, match='extinction_ratio'):
        parse_sensor_config({'calibration': {'extinction_ratio_spread': 0.5}})


def test_crosstalk_shares_electrons_with_the_four_neighbours_and_conserves_them():
    shape = (9, 9)
    s0 = np.zeros(shape, np.float32)
    s0[4, 4] = 1.0
    m, _, _ = mosaic(
        {'crosstalk': 0.03}, np.zeros(shape, np.float32), np.zeros(shape, np.float32), s0=s0
    )
    assert m[4, 4] == pytest.approx(N0 * 0.88, rel=1e-6)
    for r, c in ((3, 4), (5, 4), (4, 3), (4, 5)):
        assert m[r, c] == pytest.approx(N0 * 0.03, rel=1e-6)
    assert m.sum() == pytest.approx(N0, rel=1e-6)
    assert np.count_nonzero(m) == 5


def test_the_pattern_belongs_to_the_sensor_pixels_and_is_seeded():
    """
    The calibration pattern belongs to the sensor pixels and is seeded.

    A region render reads the same pixels' errors as the full sensor; the seed fixes the pattern.
    """
    cal = {'angle_error_deg': 1.0, 'gain_rms': 0.01, 'seed': 7}
    aop, dop = field((40, 50))
    full, _, _ = mosaic(cal, aop, dop)
    part, _, _ = mosaic(cal, aop[11:31, 7:37].copy(), dop[11:31, 7:37].copy(), origin=(11, 7))
    np.testing.assert_allclose(part, full[11:31, 7:37], rtol=1e-6)
    again, _, _ = mosaic(cal, aop, dop)
    other, _, _ = mosaic({**cal, 'seed': 8}, aop, dop)
    np.testing.assert_array_equal(full, again)
    assert not np.array_equal(full, other)


def test_calibration_runs_and_is_counted_only_when_declared():
    base = Scene(pixels=PixelSelection.rect(1, 1, 32, 24), sensor={'mosaic': {}})
    att, sun = CameraAttitude(10, 0, 0), SunDirection(30, 40)
    instr.reset()
    Renderer(base).render(attitude=att, sun=sun)
    assert not [
        k for k in instr.counts() if 'calibration' in k or '_cal_' in k or 'crosstalk' in k
    ]
    instr.reset()
    f = Renderer(
        base.replace(sensor={'calibration': {'angle_error_deg': 1, 'crosstalk': 0.01}})
    ).render(attitude=att, sun=sun)
    c = instr.counts()
    assert c.get('sensor.calibration') == 2 and c.get('sensor.kernel._crosstalk_kernel') == 1
    assert f.meta['sensor']['calibration']['angle_error_deg'] == 1.0


def test_bad_calibration_is_a_scene_error():
    with pytest.raises(SceneError, match='angle_error_deg'):
        scene_from_dict({'sensor': {'calibration': {'angle_error_deg': -1}}})
