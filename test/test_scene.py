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

"""Scene files: defaults, validation, safe loading."""

from pathlib import Path

from polarization_compass.scene import parse_time_utc, SceneError
from polarization_compass.scene_load import default_scene, load_scene, scene_from_dict
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_default_is_the_papers_setup():
    s = default_scene()
    # 32 deg 01' 36.4" N, 118 deg 51' 11.9" E (paper section 4)
    assert s.site.latitude_deg == pytest.approx(32 + 1 / 60 + 36.4 / 3600, abs=1e-5)
    assert s.site.longitude_deg == pytest.approx(118 + 51 / 60 + 11.9 / 3600, abs=1e-5)
    assert (s.time_utc.year, s.time_utc.month, s.time_utc.day) == (2019, 11, 15)
    c = s.camera
    assert (c.width_px, c.height_px, c.focal_length_mm, c.pixel_pitch_x_um) == (
        2448,
        2048,
        4.0,
        3.45,
    )
    assert s.sky == {'model': 'rayleigh', 'dop_max': 1.0}
    assert s.sensor == {} and s.radiance is None and s.effects == []


def test_shipped_paper_scene_equals_the_embedded_default():
    assert (
        load_scene(ROOT / 'config/scenes/paper_nanjing.yaml').to_dict()
        == default_scene().to_dict()
    )


@pytest.mark.parametrize(
    'path', sorted((ROOT / 'config/scenes').glob('*.yaml')), ids=lambda p: p.name
)
def test_every_shipped_scene_loads(path):
    s = load_scene(path)
    assert s.name


@pytest.mark.parametrize(
    'bad,match',
    [
        ({'site': {'latitude_deg': 95}}, 'latitude_deg'),
        ({'site': {'lattitude_deg': 10}}, 'unknown key'),
        ({'time_utc': '15/11/2019'}, 'ISO 8601'),
        ({'sun': {'azimuth_deg': 10}}, 'both'),
        ({'sun': {'model': 'vsop87'}}, 'spa'),
        ({'camera': {'width_px': -3}}, 'width_px'),
        ({'pixels': {'mode': 'random'}}, 'pixels.mode'),
        ({'sky': {'model': 'mie'}}, 'unknown sky model'),
        ({'sky': {'model': 'rayleigh', 'dop_max': 1.5}}, 'dop_max'),
        ({'attitude': {'pitch_deg': float('nan')}}, 'pitch_deg'),
        ({'validity': {'min_dop': 2}}, 'min_dop'),
        ({'sensor': {'shot_noise': {}}, 'pixels': {'mode': 'stride', 'stride': 4}}, 'contiguous'),
        (
            {
                'sensor': {'mosaic': {}},
                'pixels': {
                    'mode': 'region',
                    'x0': 1,
                    'y0': 1,
                    'width': 8,
                    'height': 8,
                    'stride': 2,
                },
            },
            'contiguous',
        ),
        (
            {'sensor': {'read_noise': {}}, 'pixels': {'mode': 'grid', 'nx': 4, 'ny': 4}},
            'contiguous',
        ),
    ],
)
def test_bad_scenes_name_the_problem(bad, match):
    with pytest.raises(SceneError, match=match):
        scene_from_dict(bad)


def test_loading_never_executes_yaml_tags(tmp_path):
    p = tmp_path / 'evil.yaml'
    p.write_text(
        "name: !!python/object/apply:os.system ['echo pwned > %s']\n" % (tmp_path / 'pwned')
    )
    with pytest.raises(SceneError, match='not valid YAML'):
        load_scene(p)
    assert not (tmp_path / 'pwned').exists()


def test_missing_and_garbage_files(tmp_path):
    with pytest.raises(SceneError, match='does not exist'):
        load_scene(tmp_path / 'nope.yaml')
    p = tmp_path / 'list.yaml'
    p.write_text(yaml.safe_dump([1, 2, 3]))
    with pytest.raises(SceneError, match='mapping'):
        load_scene(p)


def test_time_parsing_is_utc():
    assert parse_time_utc('2019-11-15T14:00:00+08:00') == parse_time_utc('2019-11-15T06:00:00Z')
    assert parse_time_utc('2019-11-15T06:00:00').tzinfo is not None


def test_sensor_effects_on_contiguous_pixels_are_accepted():
    for pixels in (
        {'mode': 'full'},
        {'mode': 'region', 'x0': 3, 'y0': 5, 'width': 8, 'height': 6},
    ):
        assert scene_from_dict({'sensor': {'shot_noise': {}}, 'pixels': pixels}).effects == [
            'shot_noise'
        ]
    # an ideal sensor (no effects; a demosaic choice alone is not an effect) may use any pixels
    assert scene_from_dict(
        {'sensor': {'demosaic': 'superpixel'}, 'pixels': {'mode': 'stride', 'stride': 4}}
    )
