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

"""Photodiode-array sensor description, recordings and the per-unit Stokes fit."""

import math

import numpy as np
from polarization_compass.photodiode.geometry import (
    ArrayGeometryError,
    geometry_from_dict,
    geometry_to_dict,
    load_array_geometry,
)
from polarization_compass.photodiode.readings import (
    ArrayRecordingError,
    load_array_recording,
    save_array_recording_csv,
    save_array_recording_npz,
)
from polarization_compass.photodiode.stokes import fit_stokes
import pytest
import yaml

UNIT = {
    'azimuth_deg': 0,
    'elevation_deg': 45,
    'channels_deg': [135, 45, 90, 0],
    'acceptance_deg': 30,
}


def _geom(**over):
    d = {
        'angle_zero': 'horizontal',
        'angle_sense': 'ccw',
        'units': [dict(UNIT), dict(UNIT, azimuth_deg=120)],
    }
    d.update(over)
    return d


def test_shipped_geometry_loads():
    from pathlib import Path

    g = load_array_geometry(
        Path(__file__).resolve().parents[1] / 'config' / 'arrays' / 'pol_op_8unit.yaml'
    )
    assert g.n_units == 8 and g.angle_zero == 'horizontal' and g.angle_sense == 'ccw'
    assert [u.enabled for u in g.units] == [True] * 5 + [False, True, False]


def test_round_trip(tmp_path):
    d = _geom()
    d['units'][1]['gains'] = [1.1, 0.9, 1.0, 1.0]
    d['units'][1]['gains_sigma'] = [0.01, 0.02, 0.0, 0.0]
    d['units'][0]['enabled'] = False
    g = geometry_from_dict(d)
    p = tmp_path / 'g.yaml'
    p.write_text(yaml.safe_dump(geometry_to_dict(g)))
    assert load_array_geometry(p) == g
    assert g.units[0].gains == (1.0, 1.0, 1.0, 1.0) and g.units[1].gains[0] == 1.1


@pytest.mark.parametrize(
    'mutate,match',
    [
        (lambda d: d.pop('units'), 'missing units'),
        (lambda d: d.update(angle_zero='vertical'), 'angle_zero must be one of'),
        (lambda d: d.update(angle_sense=1), 'angle_sense must be one of'),
        (lambda d: d.update(units=[]), 'units must be a list of 1-64'),
        (lambda d: d.update(units=[dict(UNIT)] * 65), 'units must be a list of 1-64'),
        (lambda d: d['units'][0].pop('acceptance_deg'), r'units\[0\]: missing acceptance_deg'),
        (lambda d: d['units'][0].update(channels_deg=[0, 180, 90]), 'same angle'),
        (lambda d: d['units'][0].update(channels_deg=[0]), '2-4 polarizer angles'),
        (
            lambda d: d['units'][0].update(channels_deg=[0, 45, 90, 135, 30]),
            '2-4 polarizer angles',
        ),
        (
            lambda d: d['units'][1].update(elevation_deg=91),
            r'units\[1\].elevation_deg must be finite and in',
        ),
        (lambda d: d['units'][1].update(azimuth_deg=float('nan')), 'azimuth_deg must be finite'),
        (lambda d: d['units'][1].update(azimuth_deg='north'), 'must be a number'),
        (lambda d: d['units'][1].update(acceptance_deg=0), 'acceptance_deg must be finite and in'),
        (lambda d: d['units'][1].update(gains=[1, 1]), 'must have 4 entries'),
        (lambda d: d['units'][1].update(gains=[1, 1, 0, 1]), r'gains\[2\] must be finite and in'),
        (lambda d: d['units'][1].update(enabled='yes'), 'enabled must be true or false'),
        (lambda d: d['units'][1].update(colour='red'), 'unknown key'),
        (lambda d: d.update(extra=1), 'unknown key'),
    ],
)
def test_bad_geometry_one_line(mutate, match):
    d = _geom()
    mutate(d)
    with pytest.raises(ArrayGeometryError, match=match) as ei:
        geometry_from_dict(d)
    assert '\n' not in str(ei.value) and len(str(ei.value)) < 300


def test_bad_geometry_files(tmp_path):
    with pytest.raises(ArrayGeometryError, match='does not exist'):
        load_array_geometry(tmp_path / 'nope.yaml')
    p = tmp_path / 'bad.yaml'
    p.write_text('units: [\n')
    with pytest.raises(ArrayGeometryError, match='not valid YAML'):
        load_array_geometry(p)
    p.write_text('- 1\n- 2\n')
    with pytest.raises(ArrayGeometryError, match='expected a mapping'):
        load_array_geometry(p)
    p.write_text('!!python/object:os.system {}\n')
    with pytest.raises(ArrayGeometryError, match='not valid YAML'):
        load_array_geometry(p)


# --------------------------------------------------------------------------------------------
def test_recording_round_trips(tmp_path):
    rng = np.random.default_rng(3)
    x = rng.uniform(0, 5000, (7, 3, 4))
    t = np.arange(7) * 0.1
    save_array_recording_npz(tmp_path / 'r.npz', x, t)
    save_array_recording_csv(tmp_path / 'r.csv', x, t)
    for name in ('r.npz', 'r.csv'):
        r = load_array_recording(tmp_path / name)
        np.testing.assert_array_equal(r.intensities, x)
        np.testing.assert_array_equal(r.t_offset_s, t)
    save_array_recording_csv(tmp_path / 'n.csv', x)
    assert load_array_recording(tmp_path / 'n.csv').t_offset_s is None


def test_csv_by_hand(tmp_path):
    p = tmp_path / 'h.csv'
    p.write_text('u1_c0,u0_c1,t_offset_s,u0_c0,u1_c1\n1,2,0.5,3,4\n5,6,1.5,7,\n')
    r = load_array_recording(p)
    np.testing.assert_array_equal(r.intensities[0], [[3, 2], [1, 4]])
    assert math.isnan(r.intensities[1, 1, 1])  # an empty cell is a missing reading, kept as NaN
    np.testing.assert_array_equal(r.t_offset_s, [0.5, 1.5])


@pytest.mark.parametrize(
    'content,match',
    [
        ('', 'empty CSV'),
        ('u0_c0,u0_c1,temp\n1,2,3\n', "unknown column 'temp'"),
        ('u0_c0,u0_c0\n1,2\n', 'appears twice'),
        ('u0_c0,u0_c1\n1,2,3\n', 'line 2 has 3 fields'),
        ('u0_c0,u0_c1\n1,x\n', 'line 2: not a number'),
        ('u0_c0,u0_c1\n', 'no samples'),
        ('u0_c0,u0_c1\n1,inf\n', 'inf'),
        ('u0_c0,u0_c1,u2_c0,u2_c1\n1,2,3,4\n', r'no columns for unit\(s\) \[1\]'),
        ('t_offset_s,u0_c0,u0_c1\n,1,2\n', 't_offset_s has empty'),
    ],
)
def test_bad_csv(tmp_path, content, match):
    p = tmp_path / 'b.csv'
    p.write_text(content)
    with pytest.raises(ArrayRecordingError, match=match) as ei:
        load_array_recording(p)
    assert '\n' not in str(ei.value)


def test_bad_npz(tmp_path):
    np.savez(tmp_path / 'a.npz', other=np.zeros(3))
    with pytest.raises(ArrayRecordingError, match="no 'intensities'"):
        load_array_recording(tmp_path / 'a.npz')
    np.savez(tmp_path / 'b.npz', intensities=np.zeros((3, 4)))
    with pytest.raises(ArrayRecordingError, match='samples, units, channels'):
        load_array_recording(tmp_path / 'b.npz')
    np.savez(tmp_path / 'c.npz', intensities=np.zeros((3, 2, 4)), t_offset_s=np.zeros(2))
    with pytest.raises(ArrayRecordingError, match='one per sample'):
        load_array_recording(tmp_path / 'c.npz')
    np.savez(tmp_path / 'd.npz', intensities=np.zeros((3, 2, 5)))
    with pytest.raises(ArrayRecordingError, match='2-4 channels'):
        load_array_recording(tmp_path / 'd.npz')
    (tmp_path / 'e.npz').write_bytes(b'not a zip')
    with pytest.raises(ArrayRecordingError, match='not a readable .npz'):
        load_array_recording(tmp_path / 'e.npz')
    np.savez(tmp_path / 'f.npz', intensities=np.zeros((3, 2, 4)))
    r = load_array_recording(tmp_path / 'f.npz')
    with pytest.raises(ArrayRecordingError, match='2 unit'):
        r.check_against(geometry_from_dict(_geom(units=[dict(UNIT)])))


# --------------------------------------------------------------------------------------------
def _malus(theta_deg, s0, dop, phi_rad, gain=1.0):
    """Intensity behind an ideal polarizer at theta: gain * s0/2 * (1 + P cos 2(theta - phi))."""
    return gain * s0 / 2 * (1 + dop * np.cos(2 * (np.radians(theta_deg) - phi_rad)))


@pytest.mark.parametrize('channels', [[135, 45, 90, 0], [0, 60, 120], [10, 50, 100, 170]])
def test_stokes_fit_recovers_angle_and_dop(channels):
    rng = np.random.default_rng(1)
    S = 50
    phi = rng.uniform(-1.5, 1.5, S)
    dop = rng.uniform(0.01, 0.95, S)
    s0 = rng.uniform(100, 1e4, S)
    gains = rng.uniform(0.5, 1.5, len(channels))
    x = np.stack([_malus(c, s0, dop, phi, g) for c, g in zip(channels, gains)], axis=-1)[
        :, None, :
    ]
    geo = geometry_from_dict(
        {
            'angle_zero': 'meridian',
            'angle_sense': 'cw',
            'units': [dict(UNIT, channels_deg=channels, gains=list(gains))],
        }
    )
    st = fit_stokes(x, geo)
    assert st.valid.all()
    np.testing.assert_allclose(
        np.degrees(np.angle(np.exp(2j * (st.aop_rad[:, 0] - phi)))) / 2, 0, atol=1e-9
    )
    np.testing.assert_allclose(st.dop[:, 0], dop, rtol=1e-9)
    np.testing.assert_allclose(st.s0[:, 0], s0, rtol=1e-9)
    np.testing.assert_allclose(st.misfit[:, 0], 0, atol=1e-9)
    assert np.all((st.aop_rad >= -math.pi / 2) & (st.aop_rad < math.pi / 2))


def test_stokes_invalid_cases():
    geo = geometry_from_dict(
        {
            'angle_zero': 'meridian',
            'angle_sense': 'cw',
            'units': [dict(UNIT), dict(UNIT, channels_deg=[0, 90]), dict(UNIT, enabled=False)],
        }
    )
    x = np.full((4, 3, 4), 100.0)
    x[1, 0, 2] = -5.0  # a negative reading
    x[2, 0, 0] = np.nan  # a missing one
    x[3, 0] = 0.0  # dark
    st = fit_stokes(x, geo)
    assert st.valid[:, 0].tolist() == [True, False, False, False]
    assert not st.valid[:, 1:].any()
    assert '3 or more' in st.reason[1] and 'disabled' in st.reason[2]
    assert np.all(np.isfinite(st.aop_rad)) and np.all(np.isfinite(st.dop))
