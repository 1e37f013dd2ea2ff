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

"""Error maps of a photodiode array from the same sweep engine as the camera's."""

import json
from pathlib import Path

import numpy as np
from polarization_compass.cli import main
from polarization_compass.errormap_io import load_error_map
from polarization_compass.errors import CompassError
from polarization_compass.scene_load import scene_from_dict
from polarization_compass.sweep import run_sweep, SweepSpec
import pytest

GEOMETRY = str(Path(__file__).resolve().parents[1] / 'config' / 'arrays' / 'pol_op_8unit.yaml')
AXES = {
    'sun_altitude_deg': [35.0],
    'yaw_deg': np.arange(-180.0, 181.0, 60.0),
    'pitch_deg': [-20.0, 0.0],
    'roll_deg': [0.0, 10.0],
}


def test_array_map_equals_the_camera_map_under_rayleigh(tmp_path):
    """
    The array's error map equals the camera's under a Rayleigh sky.

    Both least-squares solutions recover the sun exactly in the tilted frame, so the level
    assumption costs the array (8 units) exactly what it costs the camera (a whole sky): an
    independent pixel path to compare.
    """
    scene = scene_from_dict({'photodiode_array': {'geometry': GEOMETRY, 'integrate': False}})
    arr = run_sweep(
        SweepSpec(
            ('least_squares', 'tilt_aware'), scene=scene, array=True, full_domain=True, **AXES
        ),
        out=tmp_path / 'a.npz',
        workers=1,
        progress=False,
    )
    cam = run_sweep(
        SweepSpec(('least_squares',), scene=scene, full_domain=True, **AXES),
        out=tmp_path / 'c.npz',
        workers=1,
        progress=False,
    )
    assert arr.valid.all() and cam.valid.all()
    assert arr.meta['sensor'] == 'photodiode_array'
    np.testing.assert_allclose(arr.error_deg[0], cam.error_deg[0], atol=2e-3)
    assert np.abs(arr.error_deg[0]).max() > 5.0  # the tilt costs the level method
    assert np.abs(arr.error_deg[1]).max() < 1e-9  # tilt_aware is exact


def test_array_sweep_refuses_image_methods_and_a_scene_without_array():
    scene = scene_from_dict({'photodiode_array': {'geometry': GEOMETRY}})
    with pytest.raises(CompassError, match='need an image'):
        SweepSpec(('zenith',), scene=scene, array=True, **AXES)
    with pytest.raises(CompassError, match='declares a photodiode_array'):
        SweepSpec(('least_squares',), array=True, **AXES)


def test_errormap_cli_for_an_array(tmp_path, capsys):
    out = tmp_path / 'm.npz'
    code = main(
        [
            'errormap',
            '--array-geometry',
            GEOMETRY,
            '--sun-altitude',
            '30',
            '--yaw=-180:180:90',
            '--pitch',
            '0',
            '--roll',
            '0',
            '--workers',
            '1',
            '--no-progress',
            '--out',
            str(out),
        ]
    )
    assert code == 0, capsys.readouterr().err
    summary = json.loads(capsys.readouterr().out)
    assert summary['methods'] == ['least_squares', 'tilt_aware']
    m = load_error_map(out)
    assert (
        np.abs(m.error_deg[m.valid]).max() < 1.0
    )  # level: only the acceptance cone's small shift
    code = main(
        [
            'errormap',
            '--array-geometry',
            GEOMETRY,
            '--methods',
            'symmetry',
            '--sun-altitude',
            '30',
            '--yaw',
            '0',
            '--pitch',
            '0',
            '--roll',
            '0',
            '--out',
            str(tmp_path / 'x.npz'),
        ]
    )
    assert code == 2 and 'need an image' in capsys.readouterr().err
