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
The photodiode-array subcommands on simulated recordings.

estimate-array, calibrate-array and check-array on simulated recordings (in-process main([...])).
"""

import csv
import io

import numpy as np
from polarization_compass.cli import main
from polarization_compass.conventions import wrap_180_deg
from polarization_compass.photodiode.geometry import (
    geometry_from_dict,
    geometry_to_dict,
    load_array_geometry,
)
from polarization_compass.photodiode.readings import (
    save_array_recording_csv,
    save_array_recording_npz,
)
from polarization_compass.photodiode.simulate import simulate_readings
from polarization_compass.solar import sun_position
import pytest
from test_photodiode_heading import geom
import yaml

SITE = ['--lat', '39.26', '--lon', '8.44', '--time', '2022-05-14T08:00:00Z']


def _sun(t_offset_s):
    times = np.datetime64('2022-05-14T08:00:00', 'us') + (np.asarray(t_offset_s) * 1e6).astype(
        'timedelta64[us]'
    )
    p = sun_position(times, 39.26, 8.44)
    return np.asarray(p.azimuth_deg), np.asarray(p.altitude_deg)


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp('arr')
    rng = np.random.default_rng(4)
    gains = rng.uniform(0.8, 1.2, (8, 4))
    gains /= gains.mean(axis=1, keepdims=True)
    truth = geom(gains=gains)
    t = np.arange(0.0, 1200.0, 50.0)  # the sun moves over 20 minutes: per-sample ephemeris
    bearings = (t * 0.6) % 360.0
    az, alt = _sun(t)
    x = np.concatenate([simulate_readings(truth, a, h, [b]) for a, h, b in zip(az, alt, bearings)])
    save_array_recording_npz(d / 'rec.npz', x, t)
    save_array_recording_csv(d / 'rec.csv', x, t)
    (d / 'truth.yaml').write_text(yaml.safe_dump(geometry_to_dict(truth)))
    (d / 'raw.yaml').write_text(yaml.safe_dump(geometry_to_dict(geom())))
    (d / 'wrong.yaml').write_text(
        yaml.safe_dump(geometry_to_dict(geom('meridian', 'cw', gains=gains)))
    )
    turns = []
    for k in range(3):
        xt = simulate_readings(truth, az[0], alt[0], np.linspace(0, 360, 60) + 5 * k)
        save_array_recording_npz(d / f'turn{k}.npz', xt)
        turns.append(str(d / f'turn{k}.npz'))
    return d, bearings, gains, turns


def _rows(text):
    return list(csv.DictReader(io.StringIO(text)))


@pytest.mark.parametrize('name', ['rec.npz', 'rec.csv'])
def test_estimate_array(capsys, files, name):
    d, bearings, _, _ = files
    out = d / f'{name}.out.csv'
    code = main(
        [
            'estimate-array',
            str(d / name),
            '--geometry',
            str(d / 'truth.yaml'),
            *SITE,
            '--method',
            'tilt_aware',
            '--pitch',
            '0',
            '--roll',
            '0',
            '--out',
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert code == 0, err
    rows = _rows(out.read_text())
    assert len(rows) == len(bearings)
    assert list(rows[0]) == [
        'sample',
        't_offset_s',
        'bearing_deg',
        'yaw_enu_deg',
        'sigma_deg',
        'status',
        'units_used',
        'misfit_rms_deg',
        'reason',
        'side_by',
        'units_unusable',
    ]
    for r, b in zip(rows, bearings):
        assert r['status'] == 'ok', r['reason']
        assert abs(wrap_180_deg(float(r['bearing_deg']) - b)) < 1e-3
        assert float(r['yaw_enu_deg']) == pytest.approx(
            float(wrap_180_deg(90 - float(r['bearing_deg']))), abs=2e-4
        )
        assert float(r['sigma_deg']) > 0


def test_estimate_array_to_stdout_and_failed_rows(capsys, files):
    d, _, _, _ = files
    code = main(
        [
            'estimate-array',
            str(d / 'rec.npz'),
            '--geometry',
            str(d / 'truth.yaml'),
            '--lat',
            '39.26',
            '--lon',
            '8.44',
            '--time',
            '2022-05-14T02:00:00Z',
            '--out',
            '-',
        ]
    )  # before sunrise
    out = capsys.readouterr().out
    assert code == 0
    rows = _rows(out)
    assert all(
        r['status'] == 'sun_below_horizon' and r['bearing_deg'] == '' and r['sigma_deg'] == ''
        for r in rows
    )


@pytest.mark.parametrize(
    'extra,match',
    [
        (['--method', 'zenith'], 'needs an image'),
        (['--method', 'tilt_aware', '--pitch', '3'], '--pitch and --roll go together'),
        (['--knob', 'min_units=1'], 'min_units'),
        (['--knob', 'stride=2'], 'unknown array knob'),
        (['--lat', '95'], '--lat must be'),
    ],
)
def test_estimate_array_bad_input_exits_2(capsys, files, extra, match):
    d, _, _, _ = files
    argv = [
        'estimate-array',
        str(d / 'rec.npz'),
        '--geometry',
        str(d / 'truth.yaml'),
        *SITE,
        '--out',
        str(d / 'x.csv'),
        *extra,
    ]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and match in err and err.count('\n') == 1


def test_estimate_array_bad_files_exit_2(capsys, files, tmp_path):
    d, _, _, _ = files
    bad = tmp_path / 'g.yaml'
    bad.write_text('angle_zero: meridian\nangle_sense: cw\nunits: []\n')
    assert (
        main(['estimate-array', str(d / 'rec.npz'), '--geometry', str(bad), *SITE, '--out', '-'])
        == 2
    )
    assert 'units must be a list' in capsys.readouterr().err
    small = tmp_path / 's.yaml'
    small.write_text(yaml.safe_dump(geometry_to_dict(geom(az=(0, 90, 180)))))
    assert (
        main(['estimate-array', str(d / 'rec.npz'), '--geometry', str(small), *SITE, '--out', '-'])
        == 2
    )
    assert '8 unit(s), the geometry 3' in capsys.readouterr().err
    assert (
        main(
            [
                'estimate-array',
                str(tmp_path / 'none.npz'),
                '--geometry',
                str(small),
                *SITE,
                '--out',
                '-',
            ]
        )
        == 2
    )
    assert 'does not exist' in capsys.readouterr().err


def test_calibrate_array(capsys, files, tmp_path):
    d, _, gains, turns = files
    out = tmp_path / 'cal.yaml'
    code = main(['calibrate-array', *turns, '--geometry', str(d / 'raw.yaml'), '--out', str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    g = load_array_geometry(out)
    np.testing.assert_allclose([u.gains for u in g.units], gains, atol=1e-6)
    assert all(u.gains_sigma is not None for u in g.units)
    lines = [ln for ln in err.splitlines() if ln.startswith('unit ')]
    assert len(lines) == 8 and all('angle change' in ln for ln in lines)
    assert 'keep the old geometry' in err  # when not to use them, in the output


def test_calibrate_array_names_only_enabled_units_and_repeats_count_once(capsys, files, tmp_path):
    d, _, gains, _ = files
    gd = geometry_to_dict(geom(gains=gains))
    gd['units'][3]['enabled'] = False
    truth = geometry_from_dict(gd)
    rng = np.random.default_rng(7)
    x = simulate_readings(truth, 120.0, 40.0, np.linspace(0, 360, 200), noise_rel=0.003, rng=rng)
    save_array_recording_npz(tmp_path / 'noisy.npz', x)
    raw = dict(gd)
    raw['units'] = [{k: v for k, v in u.items() if k != 'gains'} for u in gd['units']]
    (tmp_path / 'raw.yaml').write_text(yaml.safe_dump(raw))
    out = tmp_path / 'cal.yaml'
    rec = str(tmp_path / 'noisy.npz')
    geo = str(tmp_path / 'raw.yaml')
    code = main(['calibrate-array', rec, rec, rec, '--geometry', geo, '--out', str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    named = [int(ln.split()[1].rstrip(':')) for ln in err.splitlines() if ln.startswith('unit ')]
    assert named == [0, 1, 2, 4, 5, 6, 7]
    assert 'recording 1 repeats recording 0' in err and 'recording 2 repeats recording 0' in err
    g = load_array_geometry(out)
    assert g.units[3].gains_sigma is None and g.units[3].gains == (1.0,) * 4
    for u in (0, 1, 2, 4, 5, 6, 7):
        sig = np.array(g.units[u].gains_sigma)
        assert np.all(sig > 1e-5), sig  # one recording's 8 blocks, not three identical groups
        # and the gains are within a few sigma of the truth
        assert np.all(np.abs(np.array(g.units[u].gains) - gains[u]) < 5 * sig + 1e-3)


def test_check_array(capsys, files):
    d, _, _, _ = files
    assert (
        main(['check-array', str(d / 'rec.npz'), '--geometry', str(d / 'truth.yaml'), *SITE]) == 0
    )
    out = capsys.readouterr().out
    assert 'clear: angle_zero horizontal, angle_sense ccw' in out
    assert (
        main(['check-array', str(d / 'rec.npz'), '--geometry', str(d / 'wrong.yaml'), *SITE]) == 1
    )
    assert 'the geometry says angle_zero meridian' in capsys.readouterr().err
