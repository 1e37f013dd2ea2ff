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
A photodiode array declared in a scene.

It is rendered only when declared, with the scene's attitude and sun.
"""

import numpy as np
from polarization_compass.conventions import CameraAttitude, wrap_180_deg
from polarization_compass.estimators.base import Status
from polarization_compass.photodiode.geometry import geometry_from_dict
from polarization_compass.photodiode.heading import estimate_recording, make_array_estimator
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import SceneError
from polarization_compass.scene_load import load_scene, scene_from_dict
import pytest

GEOM = {
    'angle_zero': 'horizontal',
    'angle_sense': 'ccw',
    'units': [
        {
            'azimuth_deg': a,
            'elevation_deg': 45,
            'channels_deg': [135, 45, 90, 0],
            'acceptance_deg': 40,
        }
        for a in (0, 90, 180, 270, 45, 135, 225, 315)
    ],
}


def _scene(**array):
    return scene_from_dict(
        {
            'pixels': {'mode': 'grid', 'nx': 8, 'ny': 6},
            'sky': {'model': 'rayleigh', 'dop_max': 0.7},
            'photodiode_array': {'geometry': GEOM, **array},
        }
    )


def test_not_rendered_unless_declared():
    f = Renderer(scene_from_dict({'pixels': {'mode': 'grid', 'nx': 8, 'ny': 6}})).render()
    assert f.array_intensities is None and f.meta['photodiode_array'] is None


@pytest.mark.parametrize('bearing,pitch,roll', [(40.0, 0.0, 0.0), (250.0, 8.0, -5.0)])
def test_rendered_array_gives_the_scenes_heading(bearing, pitch, roll):
    r = Renderer(_scene())
    f = r.render(attitude=CameraAttitude(bearing, pitch, roll), sun=SunDirection(120.0, 35.0))
    assert f.array_intensities.shape == (8, 4) and f.meta['photodiode_array']['units'] == 8
    est = make_array_estimator('tilt_aware', geometry_from_dict(GEOM))
    res = estimate_recording(est, f.array_intensities[None], 120.0, 35.0, pitch, roll)[0]
    assert (
        res.status == Status.OK and abs(wrap_180_deg(res.bearing_deg - bearing)) < 0.5
    )  # cone integration


def test_noise_is_seeded_and_per_frame():
    r = Renderer(_scene(noise_rel=0.01))
    a = r.render(sun=SunDirection(120.0, 35.0)).array_intensities
    b = r.render(sun=SunDirection(120.0, 35.0)).array_intensities
    assert not np.array_equal(a, b)
    a2 = Renderer(_scene(noise_rel=0.01)).render(sun=SunDirection(120.0, 35.0)).array_intensities
    np.testing.assert_array_equal(a, a2)


def test_scene_file_round_trip(tmp_path):
    import yaml

    s = _scene(brightness=500.0)
    p = tmp_path / 's.yaml'
    p.write_text(yaml.safe_dump(s.to_dict()))
    assert load_scene(p).photodiode_array == s.photodiode_array


@pytest.mark.parametrize(
    'cfg,match',
    [
        ({'geometry': {'units': []}}, 'missing angle_zero'),
        ({}, 'missing geometry'),
        ({'geometry': GEOM, 'gain': 2}, 'unknown key'),
        ({'geometry': GEOM, 'noise_rel': -1}, 'noise_rel must be'),
        ({'geometry': '/nonexistent/g.yaml'}, 'does not exist'),
        ([1], 'must be a mapping'),
    ],
)
def test_bad_array_declaration(cfg, match):
    with pytest.raises(SceneError, match=match):
        scene_from_dict({'photodiode_array': cfg})
