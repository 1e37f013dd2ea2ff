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
The DoFP redundancy (IFOV) check of the demosaic (``demosaic`` module docstring, "IFOV check").

Independent references: the redundancy ``(I0 + I90) - (I45 + I135)`` and Malus's law computed here
with numpy from the polarizer angles; the Gaussian false-alarm rate ``erfc(k / sqrt 2)``; the
heading error against the rendered truth.
"""

import math
from pathlib import Path

import numpy as np
from polarization_compass.demosaic import (
    check_ifov_k,
    IFOV_K_DEFAULT,
    polarization_from_mosaic,
    redundancy_noise,
    stokes_from_mosaic,
)
from polarization_compass.estimators.mosaic_input import MosaicInputError, observation_from_mosaic
from polarization_compass.mosaic import SensorError
from polarization_compass.sensor import parse_sensor_config
import pytest

LAYOUT = ((90, 45), (135, 0))  # IMX250MZR; with '+x+y' the camera angles are the physical ones
POL45 = '+x+y'
ROOT = Path(__file__).resolve().parents[1]


def _malus(s0, dop, aolp_x_rad, shape):
    """Noise-free mosaic of a sky patch: I = S0/2 (1 + DoP cos 2(phi - AoLP_x)), per pixel."""
    phi = np.radians(np.tile(np.array(LAYOUT, float), (shape[0] // 2, shape[1] // 2)))
    return 0.5 * s0 * (1.0 + dop * np.cos(2.0 * (phi - aolp_x_rad)))


def _redundancy(m):
    """(I0 + I90) - (I45 + I135) per 2 x 2 block, from the layout's angles (numpy)."""
    blocks = m.reshape(m.shape[0] // 2, 2, m.shape[1] // 2, 2)
    sign = {0: 1.0, 90: 1.0, 45: -1.0, 135: -1.0}
    return sum(sign[LAYOUT[r][c]] * blocks[:, r, :, c] for r in range(2) for c in range(2))


def test_a_sharp_diagonal_edge_is_flagged_exactly_where_the_redundancy_jumps():
    rng = np.random.default_rng(1)
    H = W = 128
    y, x = np.mgrid[0:H, 0:W]
    cloud = (x + y) >= 129  # a 45 deg edge: a cloud three times brighter, half the DoP
    s0 = np.where(cloud, 3000.0, 1000.0)
    dop = np.where(cloud, 0.2, 0.4)
    ideal = _malus(s0, dop, 0.3, (H, W))
    m = np.rint(ideal + rng.normal(0.0, np.sqrt(ideal))).astype(np.uint16)  # shot-like noise
    d_ideal = _redundancy(ideal)
    crosses = (cloud.reshape(H // 2, 2, W // 2, 2).any(axis=(1, 3))) & ~(
        cloud.reshape(H // 2, 2, W // 2, 2).all(axis=(1, 3))
    )
    assert crosses.sum() >= 60
    # the independent redundancy is large exactly on the edge blocks, 0 elsewhere
    assert np.all(np.abs(d_ideal[crosses]) > 900.0)
    assert np.all(np.abs(d_ideal[~crosses]) < 1e-9)
    _, _, ok_off = polarization_from_mosaic(m, LAYOUT, POL45, 'superpixel')
    _, _, ok_on = polarization_from_mosaic(m, LAYOUT, POL45, 'superpixel', ifov_k=4.0)
    assert ok_off.all()
    flagged = ok_off & ~ok_on
    assert np.array_equal(flagged & crosses, crosses)  # every edge block
    assert (flagged & ~crosses).sum() <= 2  # 4-sigma false alarms: 6e-5 x 4000 blocks expected
    # bilinear: every pixel whose 3 x 3 neighbourhood holds both sides of the edge at a point
    # where the redundancy does not cancel is flagged; far from the edge nothing is
    _, _, bl_on = polarization_from_mosaic(m, LAYOUT, POL45, 'bilinear', ifov_k=4.0)
    far = np.abs((x + y) - 128.5) > 3
    assert (~bl_on[far]).sum() <= 2
    near = np.abs((x + y) - 128.5) < 1
    assert (~bl_on[near]).mean() > 0.9


def test_an_axis_aligned_edge_shows_in_the_redundancy_only_through_its_polarization():
    """
    The limit of the check: with 0/90 on one diagonal of the block, r is a mixed 2nd difference.

    An edge between the block's columns gives r = DoP (b - a) / 2 (cos 2t - sin 2t) (t the
    AoLP_x; by hand from Malus's law), not the (b - a) / 2 it leaks into S1 and S2: an
    unpolarized edge is invisible to the check, a polarized one is scaled down by ~DoP.
    """
    H = W = 64
    x = np.mgrid[0:H, 0:W][1]
    a, b, t = 1000.0, 3000.0, 0.3
    s0 = np.where(x >= 33, b, a)  # the blocks of columns 32, 33 straddle the edge
    edge = np.zeros((H // 2, W // 2), bool)
    edge[:, 16] = True
    for dop in (0.0, 0.4):
        r = _redundancy(_malus(s0, dop, t, (H, W)))
        want = dop * (b - a) / 2.0 * (math.cos(2 * t) - math.sin(2 * t))
        assert np.allclose(r[edge], want, atol=1e-9)
        assert np.allclose(r[~edge], 0.0, atol=1e-9)
    ideal = _malus(s0, 0.0, t, (H, W)).astype(np.float32)
    _, _, off = polarization_from_mosaic(ideal, LAYOUT, POL45, 'superpixel')
    _, _, on = polarization_from_mosaic(ideal, LAYOUT, POL45, 'superpixel', ifov_k=4.0)
    assert off[edge].all()  # the leak makes an unpolarized edge look polarized ...
    assert on[edge].all()  # ... and the check cannot see it


@pytest.mark.parametrize(
    'method, sigma_z',
    [
        ('superpixel', math.sqrt(2.0)),  # var r = sum of the 4 samples = 2 S0 (Poisson, gain 1)
        ('bilinear', math.sqrt(2.25 / 2.0)),  # weights 1, 4 x 0.5, 4 x 0.25: sum w^2 = 2.25
    ],
)
def test_clear_sky_false_alarm_rate_is_the_gaussian_tail(method, sigma_z):
    rng = np.random.default_rng(7)
    H, W = 1024, 1024
    y, x = np.mgrid[0:H, 0:W]
    s0 = 800.0 + 0.4 * x + 0.2 * y  # a smooth brightness gradient (linear: r stays 0)
    ideal = _malus(s0, 0.5, 0.8, (H, W))
    m = rng.poisson(ideal).astype(np.uint16)
    noise = redundancy_noise(m, LAYOUT, POL45, method)
    assert noise.sigma == pytest.approx(sigma_z, rel=0.05)
    assert abs(noise.mu) < 2e-3
    k = 3.29  # two-sided Gaussian tail 1.0e-3
    expected = math.erfc(k / math.sqrt(2.0))
    _, _, off = polarization_from_mosaic(m, LAYOUT, POL45, method)
    _, _, on = polarization_from_mosaic(m, LAYOUT, POL45, method, ifov_k=k)
    rate = (off & ~on).sum() / off.sum()
    assert 0.6 * expected < rate < 1.6 * expected
    _, _, dflt = polarization_from_mosaic(m, LAYOUT, POL45, method, ifov_k=IFOV_K_DEFAULT)
    rate4 = (off & ~dflt).sum() / off.sum()
    assert rate4 < 3.0 * math.erfc(IFOV_K_DEFAULT / math.sqrt(2.0))  # 6.3e-5 expected


def test_the_stokes_path_rejects_the_same_pixels():
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:64, 0:64]
    disc = (x - 30) ** 2 + (y - 34) ** 2 < 200
    ideal = _malus(np.where(disc, 2500.0, 900.0), 0.3, 0.1, (64, 64))
    m = rng.poisson(ideal).astype(np.uint16)
    for method in ('superpixel', 'bilinear'):
        _, _, ok = polarization_from_mosaic(m, LAYOUT, POL45, method, ifov_k=3.0)
        s0, _, _ = stokes_from_mosaic(m, LAYOUT, POL45, method, ifov_k=3.0)
        assert (~ok).sum() > 0
        assert np.array_equal(ok, s0 > 0)


@pytest.mark.parametrize('bad', [-1.0, 0.5, math.nan, math.inf, True, '3', None])
def test_a_bad_threshold_is_refused(bad):
    with pytest.raises(SensorError):
        check_ifov_k(bad)
    m = np.full((8, 8), 100, np.uint16)
    with pytest.raises(SensorError):
        polarization_from_mosaic(m, ifov_k=bad)
    with pytest.raises(SensorError, match='ifov_check'):
        parse_sensor_config({'ifov_check': {'k_sigma': bad}})


def test_the_threshold_knobs():
    assert check_ifov_k(0) == 0.0 and check_ifov_k(3) == 3.0
    assert parse_sensor_config({}).ifov_check_k == IFOV_K_DEFAULT
    assert parse_sensor_config({'ifov_check': {'k_sigma': 0}}).ifov_check_k == 0.0
    with pytest.raises(SensorError):
        parse_sensor_config({'ifov_check': {'k': 3}})
    from polarization_compass.camera import CameraModel

    cam = CameraModel(width_px=20, height_px=20)
    with pytest.raises(MosaicInputError, match='ifov_check_k'):
        observation_from_mosaic(np.ones((20, 20), np.uint16), cam, 0.0, 30.0, ifov_k=-2)


def test_a_cloudy_sky_least_squares_sigma_is_honest_with_the_check():
    """
    Noise-free DoFP frames of a 160 px fisheye under 30 % clouds (budget_small without noise).

    Measured (60 frames, ``polarization-compass budget``): mean err^2 / sigma^2 13.8 without the
    check, 1.1 with it; here 6 level frames at random bearings against the rendered truth.
    """
    from polarization_compass.conventions import CameraAttitude, fold_axial_deg, wrap_180_deg
    from polarization_compass.estimators import registry
    from polarization_compass.estimators.base import Observation
    from polarization_compass.render import Renderer
    from polarization_compass.scene_load import load_scene

    base = load_scene(ROOT / 'config' / 'scenes' / 'budget_small.yaml')
    plain = {
        k: v
        for k, v in base.sensor.items()
        if k not in ('shot_noise', 'read_noise', 'calibration')
    }
    est = registry.make('least_squares')
    rng = np.random.default_rng(11)
    cal = {}
    for k in (0, IFOV_K_DEFAULT):
        ratios = []
        for i in range(6):
            scene = base.replace(sensor=dict(plain, ifov_check={'k_sigma': k}), seed=100 + i)
            att = CameraAttitude(float(rng.uniform(0, 360)), 0, 0)
            frame = Renderer(scene).render(attitude=att)
            out = est.estimate(Observation.from_frame(frame, camera=scene.camera))
            assert out.ok
            d = out.psi_deg - frame.psi_deg
            err = float(fold_axial_deg(d)) if out.axial else float(wrap_180_deg(d))
            ratios.append((err / out.sigma_deg) ** 2)
        rng = np.random.default_rng(11)  # the same bearings with the check on
        cal[k] = float(np.mean(ratios))
    # without the check these edges are what the jackknife checks of least squares have to catch
    # (13.8 before them, 2.9 here with them); the IFOV check removes the cause
    assert cal[0] > 2.0 * cal[IFOV_K_DEFAULT], cal
    assert 0.3 < cal[IFOV_K_DEFAULT] < 3.0, cal
