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
Loading files never executes their content, and corrupt files are one clear CompassError.

numpy files are read with ``allow_pickle=False`` (an object array or a pickle is refused with a
message, and the payload never runs); YAML is read with the safe loader (a ``!!python`` tag is
refused). Covered elsewhere and not repeated: test_scene.py::test_loading_never_executes_yaml_tags
(os.system tag in a scene), test_bag.py::test_not_a_bag_is_one_line_bag_error (missing, empty,
text, bad metadata, bare and truncated MCAP bags),
test_bag.py::test_bad_mapping_is_one_clear_error.

Every payload below would create a marker file if it ran; each test checks the marker is absent.
"""

import json
import pickle

from hard_cases_npz import assert_no_leaked_handle, assert_refused, npy_named_npz, truncate_half
import numpy as np
from polarization_compass import bag as B
from polarization_compass.errors import CompassError
from polarization_compass.frame_io import FrameFileError, load_frame_npz
from polarization_compass.scene import SceneError
from polarization_compass.scene_load import load_scene
import pytest


class _Payload:
    """Unpickling this calls open(marker, 'w'): proof that content was executed."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, 'w'))


def good_arrays(shape=(2, 3)):
    return {
        'aop_rad': np.zeros(shape, np.float32),
        'dop': np.zeros(shape, np.float32),
        'valid': np.ones(shape, bool),
        'x_px': np.ones(shape),
        'y_px': np.ones(shape),
        'meta': np.array(json.dumps({'camera': {'width_px': 3, 'height_px': 2}})),
    }


def write_npz(path, **over):
    arrays = good_arrays()
    arrays.update(over)
    np.savez(path, **{k: v for k, v in arrays.items() if v is not None})
    return path


# --------------------------------------------------------------------------------------------
# numpy: frame files
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('key', ['aop_rad', 'meta', 'valid', 'intensity'])
def test_frame_file_with_an_object_array_is_refused_and_never_unpickled(tmp_path, key):
    marker = tmp_path / 'EXECUTED'
    payload = np.empty((2, 3), dtype=object)
    payload[...] = _Payload(marker)
    p = write_npz(tmp_path / 'evil.npz', **{key: payload})
    with pytest.raises(FrameFileError, match='(?i)object arrays|pickle') as ei:
        load_frame_npz(p)
    assert '\n' not in str(ei.value)
    assert not marker.exists()


def test_a_pickle_named_npz_is_refused_and_never_unpickled(tmp_path):
    marker = tmp_path / 'EXECUTED'
    p = tmp_path / 'frame.npz'
    p.write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(FrameFileError, match='pickle'):
        load_frame_npz(p)
    assert not marker.exists()


@pytest.mark.parametrize('content', [b'', b'hello', b'PK\x03\x04' + bytes(40), b'\x93NUMPY'])
def test_garbage_frame_files_are_frame_file_errors(tmp_path, content):
    p = tmp_path / 'f.npz'
    p.write_bytes(content)
    with pytest.raises(FrameFileError) as ei:
        load_frame_npz(p)
    assert '\n' not in str(ei.value)


def truncated_npz(tmp_path):
    return truncate_half(write_npz(tmp_path / 'f.npz'))


def test_truncated_frame_file(tmp_path):
    assert_refused(load_frame_npz, truncated_npz(tmp_path), FrameFileError, match='not a readable')


def test_corrupt_frame_file_does_not_leak_a_file_handle(tmp_path):
    assert_no_leaked_handle(load_frame_npz, truncated_npz(tmp_path), FrameFileError)


def test_a_npy_file_named_npz_is_a_frame_file_error(tmp_path):
    with pytest.raises(FrameFileError):
        load_frame_npz(npy_named_npz(tmp_path / 'f.npz'))


@pytest.mark.parametrize(
    'over, words',
    [
        ({'aop_rad': None}, 'missing'),
        ({'meta': np.array('[1, 2]')}, 'JSON object'),
        ({'meta': np.array('{not json')}, 'JSON'),
        ({'valid': np.ones((2, 3), np.uint8)}, 'bool'),
        ({'aop_rad': np.zeros((2, 3), np.complex64)}, 'floating'),
        ({'dop': np.zeros((3, 2), np.float32)}, 'shape'),
        ({'aop_rad': np.full((2, 3), np.nan, np.float32)}, 'non-finite'),
        ({'dop': np.full((2, 3), np.inf, np.float32)}, 'non-finite'),
    ],
)
def test_inconsistent_frame_files_name_the_problem(tmp_path, over, words):
    with pytest.raises(FrameFileError, match=words):
        load_frame_npz(write_npz(tmp_path / 'f.npz', **over))


def test_non_finite_values_at_invalid_pixels_are_tolerated(tmp_path):
    """
    Non-finite values at invalid pixels are tolerated.

    Invalid pixels carry no data: NaN there is not an error (the renderer writes 0, others may
    not).
    """
    f = load_frame_npz(
        write_npz(
            tmp_path / 'f.npz',
            dop=np.full((2, 3), np.nan, np.float32),
            valid=np.zeros((2, 3), bool),
        )
    )
    assert not f.valid.any()


@pytest.mark.parametrize(
    'over',
    [
        {'x_px': np.full((2, 3), np.nan)},
        {'y_px': np.full((2, 3), np.inf)},
        {'dop': np.full((2, 3), 1.5, np.float32)},
        {'dop': np.full((2, 3), -0.5, np.float32)},
    ],
)
def test_frame_files_outside_the_documented_ranges_are_refused(tmp_path, over):
    with pytest.raises(FrameFileError):
        f = load_frame_npz(write_npz(tmp_path / 'f.npz', **over))
        assert np.all(np.isfinite(f.rays_cam()))


def test_frame_file_with_an_unusable_camera_is_a_frame_file_error(tmp_path):
    for cam in ({'width_px': 'abc'}, {'no_such_field': 1}, {'model': 'orthographic'}):
        f = load_frame_npz(
            write_npz(tmp_path / 'f.npz', meta=np.array(json.dumps({'camera': cam})))
        )
        with pytest.raises(FrameFileError, match='camera'):
            f.rays_cam()


# --------------------------------------------------------------------------------------------
# YAML: scenes and topic maps
# --------------------------------------------------------------------------------------------
TAGS = [
    "!!python/object/apply:builtins.open ['{m}', 'w']",
    "!!python/object/new:builtins.open ['{m}', 'w']",
    '!!python/name:os.system',
    '!!python/module:os',
]


@pytest.mark.parametrize('tag', TAGS)
def test_scene_yaml_python_tags_are_refused(tmp_path, tag):
    marker = tmp_path / 'EXECUTED'
    p = tmp_path / 's.yaml'
    p.write_text('name: ' + tag.format(m=marker) + '\n')
    with pytest.raises(SceneError, match='YAML'):
        load_scene(p)
    assert not marker.exists()


@pytest.mark.parametrize('tag', TAGS)
def test_topic_map_yaml_python_tags_are_refused(tmp_path, tag):
    marker = tmp_path / 'EXECUTED'
    p = tmp_path / 'm.yaml'
    p.write_text('topics:\n  image: ' + tag.format(m=marker) + '\n')
    with pytest.raises(B.BagError, match='YAML') as ei:
        B.load_topic_map(p)
    assert '\n' not in str(ei.value)
    assert not marker.exists()


def test_bag_metadata_with_a_python_tag_is_refused(tmp_path):
    marker = tmp_path / 'EXECUTED'
    d = tmp_path / 'bag'
    d.mkdir()
    (d / 'metadata.yaml').write_text(
        "rosbag2_bagfile_information: !!python/object/apply:builtins.open ['%s', 'w']\n" % marker
    )
    with pytest.raises(B.BagError) as ei:
        with B.BagReader(d) as r:
            list(r.messages(['/x']))
    assert '\n' not in str(ei.value)
    assert not marker.exists()


def test_non_utf8_scene_is_a_scene_error(tmp_path):
    p = tmp_path / 's.yaml'
    p.write_bytes(b'name: \xff\xfe\x00\x80\n')
    with pytest.raises(SceneError):
        load_scene(p)


def test_non_utf8_topic_map_is_a_bag_error(tmp_path):
    p = tmp_path / 'm.yaml'
    p.write_bytes(b'topics: \xff\xfe\x00\x80\n')
    with pytest.raises(B.BagError):
        B.load_topic_map(p)


def test_yaml_anchor_bomb_in_a_scene_is_a_clean_error(tmp_path):
    """
    A YAML anchor bomb in a scene is a clean error.

    'Billion laughs' with aliases: safe_load builds shared references (no blow-up), and the scene
    validator refuses the unknown key; nothing hangs.
    """
    lines = ['a: &a [x, x, x, x, x, x, x, x, x]']
    for i, (k, prev) in enumerate(zip('bcdefgh', 'abcdefg')):
        lines.append(
            f'{k}: &{k} [*{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, *{prev}, '
            f'*{prev}]'
        )
    p = tmp_path / 'bomb.yaml'
    p.write_text('\n'.join(lines) + '\n')
    with pytest.raises(SceneError, match='unknown key'):
        load_scene(p)


def test_every_loader_error_is_a_compass_error():
    """
    Every loader error is a CompassError.

    The CLI prints CompassError subclasses as one line with exit 2; the loaders' errors must be
    ones.
    """
    from polarization_compass.bag import BagError, MessageError

    for cls in (FrameFileError, SceneError, BagError, MessageError):
        assert issubclass(cls, CompassError)
