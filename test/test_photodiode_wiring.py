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
Degenerate or miswired arrays never give ok headings (issue 24, item 4).

All units looking one way, the wrong angle sense, azimuths counted the other way, units recorded
one position out of order, duplicated channels: each simulated with the truth known, each must
end without an ``ok`` heading, and the right geometry must keep its ``ok`` headings.
"""

import numpy as np
from polarization_compass.cli import main
from polarization_compass.conventions import wrap_180_deg
from polarization_compass.estimators.base import Status
from polarization_compass.photodiode.geometry import geometry_from_dict, geometry_to_dict
from polarization_compass.photodiode.heading import (
    axes_spread_deg,
    estimate_recording,
    make_array_estimator,
)
from polarization_compass.photodiode.readings import save_array_recording_npz
from polarization_compass.photodiode.selfcheck import estimate_recording_checked
from polarization_compass.photodiode.simulate import simulate_readings
from polarization_compass.solar import sun_position
import pytest
import yaml

ORDER = (0, 90, 180, 270, 45, 135, 225, 315)  # the POL-OP recording order
SUN_AZ, SUN_ALT = 130.0, 40.0
BEARINGS = np.arange(0.0, 360.0, 10.0)  # 36 samples, as the probes


def geom(az=ORDER, sense='ccw', el=45.0):
    return geometry_from_dict(
        {
            'angle_zero': 'horizontal',
            'angle_sense': sense,
            'units': [
                {
                    'azimuth_deg': a,
                    'elevation_deg': el,
                    'channels_deg': [135, 45, 90, 0],
                    'acceptance_deg': 30.0,
                }
                for a in az
            ],
        }
    )


TRUTH = geom()


def _readings(noise=0.003, geometry=TRUTH):
    rng = np.random.default_rng(5)
    return simulate_readings(
        geometry, SUN_AZ, SUN_ALT, BEARINGS, noise_rel=noise, rng=rng, brightness=3000.0
    )


def _checked(geometry, x):
    est = make_array_estimator('tilt_aware', geometry)
    return estimate_recording_checked(est, x, SUN_AZ, SUN_ALT, 0.0, 0.0)


def test_axes_spread_by_hand():
    assert axes_spread_deg(np.tile([0.0, 0.6, 0.8], (5, 1))) == pytest.approx(0.0, abs=1e-6)
    assert axes_spread_deg([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]) == pytest.approx(45.0)
    assert axes_spread_deg(TRUTH.axes_body()) == pytest.approx(30.0)


def test_the_right_geometry_keeps_its_ok_headings():
    res = _checked(TRUTH, _readings())
    assert all(r.status == Status.OK for r in res), {r.reason for r in res}


def test_units_looking_one_way_are_degenerate_never_ok():
    same = geom(az=(0,) * 8)
    x = _readings(geometry=same)
    res = estimate_recording(make_array_estimator('tilt_aware', same), x, SUN_AZ, SUN_ALT, 0, 0)
    assert not any(r.ok for r in res), {r.reason for r in res}
    degenerate = [r for r in res if r.status == Status.DEGENERATE]
    assert len(degenerate) > len(res) // 2 and 'view axes spread' in degenerate[0].reason
    # nearly the same way (2 deg apart) too
    near = geom(az=(0, 2, 1, 0, 2, 1, 0, 1))
    res = estimate_recording(
        make_array_estimator('tilt_aware', near), _readings(geometry=near), SUN_AZ, SUN_ALT, 0, 0
    )
    assert not any(r.status == Status.OK for r in res)


@pytest.mark.parametrize(
    'mistake',
    ['angle_sense', 'azimuths_other_way', 'one_position_late', 'one_position_early'],
)
def test_miswired_geometry_gives_no_ok_heading(mistake):
    x = _readings()
    g = TRUTH
    if mistake == 'angle_sense':
        g = geom(sense='cw')
    elif mistake == 'azimuths_other_way':
        g = geom(az=tuple(-a for a in ORDER))
    elif mistake == 'one_position_late':
        x = np.roll(x, -1, axis=1)  # column u holds unit u + 1's readings
    else:
        x = np.roll(x, 1, axis=1)
    # without the check these give ok headings far off (the probes)
    plain = estimate_recording(make_array_estimator('tilt_aware', g), x, SUN_AZ, SUN_ALT, 0, 0)
    res = _checked(g, x)
    assert not any(r.status == Status.OK for r in res), [r.reason for r in res if r.ok][:2]
    assert any(r.status == Status.POOR_FIT and 'check-array' in r.reason for r in res)
    err = [abs(wrap_180_deg(r.bearing_deg - b)) for r, b in zip(plain, BEARINGS) if r.ok]
    assert err and max(err) > 20.0  # the mistake matters: ok headings far off without the check


def test_duplicated_channels_give_no_ok_heading():
    x = _readings()
    x[:, :, 3] = x[:, :, 2]  # the 0 deg channel wired to the 90 deg one
    res = _checked(TRUTH, x)
    assert not any(r.status == Status.OK for r in res)
    assert res[0].extras['units_unusable'] == {'duplicated_channels': 8}


def test_check_array_catches_units_out_of_order(tmp_path, capsys):
    (tmp_path / 'g.yaml').write_text(yaml.safe_dump(geometry_to_dict(TRUTH)))
    # check-array takes the ephemeris of a place and time: simulate that sun
    t = np.datetime64('2022-05-14T10:00:00')
    p = sun_position(t, 39.2586, 8.4402)
    x = np.roll(
        simulate_readings(TRUTH, float(p.azimuth_deg), float(p.altitude_deg), BEARINGS), -1, 1
    )
    save_array_recording_npz(tmp_path / 'rec.npz', x)
    code = main(
        [
            'check-array',
            str(tmp_path / 'rec.npz'),
            '--geometry',
            str(tmp_path / 'g.yaml'),
            '--lat',
            '39.2586',
            '--lon',
            '8.4402',
            '--time',
            '2022-05-14T10:00:00Z',
        ]
    )
    out = capsys.readouterr().out
    assert code == 1 and 'WIRING' in out and 'one position late' in out, out
