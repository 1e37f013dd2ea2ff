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
The error budget and the IMU/mounting error model.

The error budget (budget.py, `polarization-compass budget`) and the IMU/mounting error model
(motion.MountingErrors): exact readings for a level camera, structural facts of the breakdown (a
method that does not read the IMU gets nothing from it; the only declared source explains all of
the error), seeds.
"""

import json
import math

import numpy as np
from polarization_compass.budget import run_budget
from polarization_compass.budget_config import (
    BudgetConfig,
    BudgetError,
    declared_sources,
    parse_imu,
)
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.cli import main
from polarization_compass.conventions import CameraAttitude
from polarization_compass.motion import MountingErrors
from polarization_compass.scene import Scene
import pytest

Z3 = np.zeros(3)


@pytest.mark.parametrize('bearing', [0.0, 75.0, 250.0])
def test_level_camera_reads_the_bias_and_minus_the_boresight(bearing):
    level = CameraAttitude(bearing, 0.0, 0.0)
    m = MountingErrors(pitch_bias_deg=1.5).measured_attitude(level, Z3)
    assert m.pitch_deg == pytest.approx(1.5, abs=1e-9) and m.roll_deg == pytest.approx(
        0.0, abs=1e-9
    )
    m = MountingErrors(roll_bias_deg=-0.7).measured_attitude(level, Z3)
    assert m.roll_deg == pytest.approx(-0.7, abs=1e-9) and m.pitch_deg == pytest.approx(
        0.0, abs=1e-9
    )
    m = MountingErrors(boresight_pitch_deg=2.0).measured_attitude(level, Z3)
    assert m.pitch_deg == pytest.approx(-2.0, abs=1e-9) and m.bearing_deg == pytest.approx(
        bearing, abs=1e-9
    )
    m = MountingErrors(boresight_yaw_deg=3.0).measured_attitude(level, Z3)
    assert abs(m.pitch_deg) < 1e-9 and abs(m.roll_deg) < 1e-9  # yaw misalignment: no tilt error
    assert MountingErrors().measured_attitude(
        CameraAttitude(bearing, 7.0, -4.0), Z3
    ).pitch_deg == pytest.approx(7.0, abs=1e-9)


def test_time_offset_tilts_by_rate_times_offset_in_the_drawn_direction():
    me = MountingErrors(time_offset_s=0.05, tilt_rate_deg_s=20.0)  # 1 deg
    for z in (-1.0, 0.0, 0.4, 2.0):
        m = me.measured_attitude(CameraAttitude(10.0, 0.0, 0.0), np.array([0.0, 0.0, z]))
        assert math.hypot(m.pitch_deg, m.roll_deg) == pytest.approx(1.0, rel=1e-4)
        direction = math.pi * (1 + math.erf(z / math.sqrt(2)))
        assert m.pitch_deg == pytest.approx(math.cos(direction), abs=1e-4)


def test_noise_has_the_declared_sigma():
    me = MountingErrors(noise_deg=0.3)
    rng = np.random.default_rng(0)
    p = [
        me.measured_attitude(CameraAttitude(0, 0, 0), rng.standard_normal(3)).pitch_deg
        for _ in range(4000)
    ]
    assert abs(np.std(p) - 0.3) < 0.015 and abs(np.mean(p)) < 0.015


def test_parse_imu_and_its_errors():
    m = parse_imu(
        'noise_deg=0.5,bias_deg=0.2,boresight_deg=1,time_offset_s=0.01,tilt_rate_deg_s=30'
    )
    assert (m.pitch_bias_deg, m.roll_bias_deg, m.boresight_roll_deg, m.boresight_pitch_deg) == (
        0.2,
        0.2,
        1,
        1,
    )
    assert m.has_imu and m.has_boresight
    for bad in ('noise_deg', 'foo=1', 'noise_deg=x', 'noise_deg=1e9'):
        with pytest.raises(BudgetError):
            parse_imu(bad)


SMALL = Scene(
    camera=CameraModel(width_px=96, height_px=80),
    pixels=PixelSelection.full(),
    sun_fixed=(120.0, 40.0),
    sky={'model': 'rayleigh', 'dop_max': 0.75},
    seed=3,
)


def test_budget_breakdown_structure_and_reproducibility():
    cfg = BudgetConfig(
        SMALL,
        samples=6,
        tilt_max_deg=0.0,
        imu=MountingErrors(boresight_pitch_deg=2.0),
        methods=('zenith', 'tilt_aware'),
        correction='none',
    )
    assert declared_sources(cfg) == ['boresight']
    r = run_budget(cfg)
    assert r['sources'] == ['boresight'] and r['correction']['methods'] == []
    # uncorrected zenith does not read the IMU: the boresight cannot cost it anything (identical
    # errors with and without)
    assert r['breakdown']['zenith']['boresight']['contribution_deg'] == 0.0
    assert r['conditions']['all']['zenith'] == r['conditions']['without boresight']['zenith']
    # tilt_aware on an ideal level sky: the boresight is the only error source, so it explains
    # nearly all of it
    ta = r['conditions']['all']['tilt_aware']
    assert ta['rms_deg'] > 0.05
    assert r['conditions']['without boresight']['tilt_aware']['rms_deg'] < 0.1 * ta['rms_deg']
    assert r['breakdown']['tilt_aware']['boresight']['contribution_deg'] == pytest.approx(
        ta['rms_deg'], rel=0.01
    )
    assert json.dumps(r, sort_keys=True) == json.dumps(run_budget(cfg), sort_keys=True)
    for st in r['conditions']['all'].values():
        assert st['count'] == 6 and 0.0 <= st['share_not_ok'] <= 1.0


def test_budget_declares_each_scene_source():
    sc = SMALL.replace(
        sensor={'mosaic': {}, 'shot_noise': {}, 'calibration': {'gain_rms': 0.01}},
        atmosphere={'clouds': {'coverage': 0.3}, 'haze': {'turbidity': 3}},
        optics={'vignetting': {'law': 'cos4'}},
        sky={'model': 'berry_dennis_lee', 'dop_max': 0.7},
    )
    cfg = BudgetConfig(sc, 2, 5.0, MountingErrors(noise_deg=0.1))
    assert declared_sources(cfg) == [
        'noise',
        'calibration',
        'clouds',
        'haze',
        'optics',
        'sky_model',
        'tilt',
        'imu',
    ]


def test_cli_budget_writes_json_and_png_and_refuses_bad_input(tmp_path, capsys):
    scene = tmp_path / 's.yaml'
    scene.write_text(
        'name: small\ncamera: {width_px: 64, height_px: 48}\nsun: {azimuth_deg: 90, altitude_deg: '
        '30}\n'
        'atmosphere: {clouds: {coverage: 0.5, optical_thickness: 2}}\nseed: 2\n'
    )
    out = tmp_path / 'out'
    rc = main(
        [
            'budget',
            '--scene',
            str(scene),
            '--samples',
            '3',
            '--methods',
            'zenith',
            '--out',
            str(out),
        ]
    )
    assert rc == 0
    r = json.loads((out / 'budget.json').read_text())
    assert r['sources'] == ['clouds'] and (out / 'budget.png').stat().st_size > 1000
    assert main(['budget', '--scene', str(scene), '--imu', 'bogus=1', '--out', str(out)]) == 2
    assert main(['budget', '--scene', str(scene), '--samples', '0', '--out', str(out)]) == 2
    assert main(['budget', '--scene', str(scene), '--sigma-floor', '-1', '--out', str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert all(
        line.startswith('polarization-compass budget: error:') for line in err if 'error' in line
    )


def test_sigma_calibration_uses_the_published_floor_and_keeps_the_raw_figure():
    """
    The calibration counts max(sigma, floor), what the node publishes; the raw one is kept.

    Hand-computed: errors 0.002 and 0.03 deg with sigmas 1e-4 and 0.02 deg give a raw
    mean((e/s)^2) = (20^2 + 1.5^2) / 2 and, with the 0.01 deg floor, (0.2^2 + 1.5^2) / 2.
    """
    from polarization_compass.budget import _stats
    from polarization_compass.budget_config import BudgetConfig, published_sigma_floor_deg
    from polarization_compass.specs.params import defaults, ESTIMATOR

    assert published_sigma_floor_deg() == defaults(ESTIMATOR)['sigma_floor_deg'] == 0.01
    assert BudgetConfig(Scene()).sigma_floor_deg == 0.01
    d = _stats([0.002, -0.03], [True, True, False], [1e-4, 0.02], floor_deg=0.01)
    assert d['sigma_calibration_raw'] == pytest.approx((20.0**2 + 1.5**2) / 2)
    assert d['sigma_calibration'] == pytest.approx((0.2**2 + 1.5**2) / 2)
    assert d['sigma_band'] == 'honest' and d['share_not_ok'] == pytest.approx(1 / 3)
    raw = _stats([0.002, -0.03], [True, True], [1e-4, 0.02])
    assert raw['sigma_calibration'] == raw['sigma_calibration_raw'] and raw['sigma_band'] == (
        'overconfident'
    )


@pytest.fixture
def no_computation(monkeypatch):
    """Make the budget's computation fail the test: refusals must come before it."""
    from polarization_compass import budget

    def boom(*args, **kwargs):
        raise AssertionError('computed before the input was checked')

    monkeypatch.setattr(budget, '_samples', boom)


@pytest.mark.parametrize(
    'camera, extra, words',
    [
        ('{width_px: 20000, height_px: 20000}', [], '20000 x 20000 pixels'),
        ('{width_px: 64, height_px: 48}', ['--imu', 'noise_deg=-0.5'], 'noise_deg is a 1-sigma'),
        ('{width_px: 64, height_px: 48}', ['--out', '{file}'], 'is not a directory'),
        ('{width_px: 64, height_px: 48}', ['--out', '{file}/sub'], 'cannot be created'),
    ],
    ids=['huge-camera', 'negative-imu-noise', 'out-is-a-file', 'out-under-a-file'],
)
def test_cli_budget_refuses_before_computing(
    tmp_path, capsys, no_computation, camera, extra, words
):
    scene = tmp_path / 's.yaml'
    scene.write_text(f'camera: {camera}\nsun: {{azimuth_deg: 90, altitude_deg: 30}}\n')
    (tmp_path / 'file').write_text('x')
    extra = [a.replace('{file}', str(tmp_path / 'file')) for a in extra]
    if '--out' not in extra:
        extra += ['--out', str(tmp_path / 'out')]
    code = main(['budget', '--scene', str(scene), '--samples', '2', *extra])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count('\n') == 1 and words in err
