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
Hostile input to the ROS-free layer (issue 18).

Loaders bound what they read, implausible camera intrinsics are refused, and a heading
contradicting an independent IMU prior is not ``ok``.

Bombs are built small: a compressed ``.npz`` whose ``.npy`` header *declares* a huge shape is
refused from its header, before anything is decompressed or allocated (``tracemalloc`` checks the
peak).
"""

import io
import json
import math
import os
import tracemalloc
import zipfile

import numpy as np
from polarization_compass.camera import CameraError, CameraModel, check_intrinsics
from polarization_compass.errors import CompassError
import pytest


# --------------------------------------------------------------------------------------------
# zip bombs, built without allocating what they declare
# --------------------------------------------------------------------------------------------
def npy_bytes_declaring(shape, dtype='<f8', payload_bytes=1 << 20) -> bytes:
    """
    Return an .npy stream whose header declares ``shape`` but whose body is short.

    The body is ``payload_bytes`` of zeros: numpy would allocate the declared array before
    noticing.
    """
    header = {'descr': dtype, 'fortran_order': False, 'shape': tuple(shape)}
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    return buf.getvalue() + bytes(payload_bytes)


def write_npz(path, members: dict) -> None:
    """``members``: name -> bytes of an .npy stream (or an ndarray, saved normally), deflated."""
    with zipfile.ZipFile(path, 'w', compression=zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            if isinstance(data, np.ndarray):
                b = io.BytesIO()
                np.save(b, data, allow_pickle=False)
                data = b.getvalue()
            zf.writestr(name + '.npy', data)


def small_frame_members(shape=(4, 6)):
    return {
        'aop_rad': np.zeros(shape, np.float32),
        'dop': np.zeros(shape, np.float32),
        'valid': np.ones(shape, bool),
        'x_px': np.ones(shape),
        'y_px': np.ones(shape),
        'meta': np.array(json.dumps({'camera': {'width_px': shape[1], 'height_px': shape[0]}})),
    }


def test_the_header_helper_writes_what_numpy_reads(tmp_path):
    """The bomb builder is honest: numpy itself reads the declared shape from its header."""
    b = io.BytesIO(npy_bytes_declaring((10000, 20000), payload_bytes=0))
    version = np.lib.format.read_magic(b)
    shape, _, dtype = np.lib.format.read_array_header_1_0(b)
    assert version == (1, 0) and shape == (10000, 20000) and dtype == np.float64


def test_a_frame_declaring_10000_x_20000_is_refused_before_decompressing(tmp_path):
    """Issue 18's 4.8 MB npz that took `estimate` to 20 GB: here 1 MB of zeros declaring 1.6 GB."""
    from polarization_compass.frame_io import FrameFileError, load_frame_npz

    m = small_frame_members()
    m['aop_rad'] = npy_bytes_declaring((10000, 20000))
    p = tmp_path / 'bomb.npz'
    write_npz(p, m)
    assert p.stat().st_size < 100_000  # deflated: a small file
    tracemalloc.start()
    try:
        with pytest.raises(FrameFileError, match='declares shape'):
            load_frame_npz(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6, peak  # never near the 1.6 GB declared


def test_a_frame_whose_mosaic_or_side_array_declares_a_huge_shape_is_refused(tmp_path):
    from polarization_compass.frame_io import FrameFileError, load_frame_npz

    for key, shape, words in [
        ('mosaic', (100000, 100000), 'mosaic'),
        ('dop', (4000, 4000), 'shape'),
        ('meta', (), 'meta'),
    ]:
        m = small_frame_members()
        m[key] = npy_bytes_declaring(
            shape, '<U100000000' if key == 'meta' else '<f8', payload_bytes=1000
        )
        write_npz(tmp_path / f'{key}.npz', m)
        with pytest.raises(FrameFileError, match=words):
            load_frame_npz(tmp_path / f'{key}.npz')


def test_any_npz_declaring_more_than_the_total_budget_is_refused(tmp_path):
    from polarization_compass.safe_load import open_npz

    p = tmp_path / 'many.npz'
    write_npz(
        p, {f'a{i}': npy_bytes_declaring((20000, 20000), payload_bytes=10) for i in range(3)}
    )
    with pytest.raises(CompassError, match='declare'):
        with open_npz(p, CompassError, 'file') as z:
            z['a0']
    # and a normal archive still opens, with its arrays intact
    q = tmp_path / 'fine.npz'
    np.savez_compressed(q, a=np.arange(12.0).reshape(3, 4))
    with open_npz(q) as z:
        assert z['a'].sum() == 66.0


def test_a_frame_with_deeply_nested_meta_json_is_a_frame_file_error(tmp_path):
    from polarization_compass.frame_io import FrameFileError, load_frame_npz

    m = small_frame_members()
    m['meta'] = np.array('{"a":' * 100000 + '1' + '}' * 100000)
    write_npz(tmp_path / 'deep.npz', m)
    with pytest.raises(FrameFileError, match='nested'):
        load_frame_npz(tmp_path / 'deep.npz')


# --------------------------------------------------------------------------------------------
# special files and sizes
# --------------------------------------------------------------------------------------------
@pytest.fixture
def special_files(tmp_path):
    f = {
        'fifo': tmp_path / 'fifo.yaml',
        'dev_zero': tmp_path / 'zero.yaml',
        'huge': tmp_path / 'huge.yaml',
        'loop': tmp_path / 'loop.yaml',
    }
    os.mkfifo(f['fifo'])
    os.symlink('/dev/zero', f['dev_zero'])
    with open(f['huge'], 'wb') as fh:  # sparse: 2 MB of nothing on disk
        fh.truncate(2 << 20)
    os.symlink(f['loop'], f['loop'])
    return f


@pytest.mark.parametrize(
    'kind, words',
    [('fifo', 'FIFO'), ('dev_zero', 'device'), ('huge', 'MB'), ('loop', 'cannot be read')],
)
def test_scene_and_topic_map_loaders_refuse_special_and_huge_files(special_files, kind, words):
    """
    Scene and topic-map loaders refuse special and huge files.

    A FIFO would block, /dev/zero grow without bound (issue 18): refused from a stat, never opened.
    """
    from polarization_compass.bag import BagError, load_topic_map
    from polarization_compass.scene import SceneError
    from polarization_compass.scene_load import load_scene

    with pytest.raises(SceneError, match=words):
        load_scene(special_files[kind])
    with pytest.raises(BagError, match=words):
        load_topic_map(special_files[kind])


def test_npz_loaders_refuse_special_files(special_files):
    from polarization_compass.frame_io import FrameFileError, load_frame_npz

    with pytest.raises(FrameFileError, match='FIFO'):
        load_frame_npz(special_files['fifo'])
    with pytest.raises(FrameFileError, match='device'):
        load_frame_npz(special_files['dev_zero'])


@pytest.mark.parametrize(
    'text, words',
    [
        ('a: ' + '[' * 20000 + ']' * 20000 + '\n', 'nested'),
        ('time_utc: 2023-02-30\n', 'day is out of range'),  # a YAML date the constructor refuses
    ],
)
def test_yaml_recursion_and_bad_dates_are_scene_errors(tmp_path, text, words):
    from polarization_compass.scene import SceneError
    from polarization_compass.scene_load import load_scene

    p = tmp_path / 's.yaml'
    p.write_text(text)
    with pytest.raises(SceneError, match=words):
        load_scene(p)


def test_json_loader_refuses_nan_and_deep_nesting():
    from polarization_compass.safe_load import load_json

    assert load_json('{"a": [1, 2.5]}', 'x') == {'a': [1, 2.5]}
    for text in ('{"a": NaN}', '{"a": Infinity}', '[' * 100000 + ']' * 100000):
        with pytest.raises(CompassError):
            load_json(text, 'x')


@pytest.mark.parametrize(
    'field, value',
    [
        ('width_px', True),
        ('height_px', False),
        ('focal_length_mm', True),
        ('principal_x_px', float('nan')),
        ('principal_y_px', '3'),
    ],
)
def test_camera_fields_of_the_wrong_type_are_camera_errors(field, value):
    """`width_px: true` in a scene used to give a 1-pixel-wide camera (issue 18)."""
    with pytest.raises(CameraError, match=field):
        CameraModel(**{field: value})


# --------------------------------------------------------------------------------------------
# intrinsics
# --------------------------------------------------------------------------------------------
W, H = 612, 512
F_MM, PITCH = 0.9, 3.45  # fx = 0.9 mm / 3.45 um = 260.9 px


def info_camera(fx, fy, cx0, cy0):
    """Return the CameraModel a camera_info K gives (as bag.decode_camera_info documents)."""
    return CameraModel(
        'pinhole', W, H, fx * PITCH * 1e-3, PITCH, PITCH * fx / fy, cx0 + 1.0, cy0 + 1.0
    )


FX = F_MM / (PITCH * 1e-3)


@pytest.mark.parametrize(
    'fx, fy, cx, cy, words',
    [
        (FX, FX, 611.0, 511.0, 'from the centre'),  # issue 18: the last pixel
        (
            2 * FX,
            2 * FX,
            2 * 305.5,
            2 * 255.5,
            'from the centre',
        ),  # K scaled 2x (another resolution or binning)
        (FX, FX, 10000.0, -5000.0, 'outside'),  # issue 18
        (FX, 1.2 * FX, 305.5, 255.5, 'fx/fy'),
        # issue 24: a K calibrated 2x binned on full-resolution images (24.96 % off passed 25 %)
        (FX / 2, FX / 2, (W / 2 - 1) / 2, (H / 2 - 1) / 2, 'from the centre'),
        (FX, FX, 305.5 + 0.20 * W, 255.5, 'from the centre'),  # 20 %: ok 14 deg off before
        (FX, FX, 305.5, 255.5 - 0.11 * H, 'from the centre'),
    ],
)
def test_implausible_intrinsics_are_refused(fx, fy, cx, cy, words):
    with pytest.raises(CameraError, match=words):
        check_intrinsics(info_camera(fx, fy, cx, cy))


@pytest.mark.parametrize(
    'fx, fy, cx, cy',
    [
        (FX, FX, 305.5, 255.5),
        (FX, 1.01 * FX, 320.0, 240.0),
        (FX, FX, 305.5 + 0.09 * W, 255.5 - 0.09 * H),
    ],
)
def test_plausible_intrinsics_pass(fx, fy, cx, cy):
    cam = info_camera(fx, fy, cx, cy)
    assert check_intrinsics(cam) is cam
    assert check_intrinsics(cam, image_size=(W, H)) is cam
    with pytest.raises(CameraError, match='image is 306x256'):
        check_intrinsics(cam, image_size=(306, 256))


def test_decode_camera_info_refuses_the_issue_probes():
    from polarization_compass.bag import decode_camera_info, encode_camera_info, MessageError

    good = CameraModel('pinhole', W, H, F_MM, PITCH, PITCH)
    msg = encode_camera_info(good, 0, 'cam')
    back = decode_camera_info(msg, PITCH)
    assert back.focal_length_mm == pytest.approx(F_MM, rel=1e-12) and (back.cx_px, back.cy_px) == (
        306.5,
        256.5,
    )
    for k in (
        [FX, 0, 611.0, 0, FX, 511.0, 0, 0, 1],
        [2 * FX, 0, 611.0, 0, 2 * FX, 511.0, 0, 0, 1],
        [FX, 0, 10000.0, 0, FX, -5000.0, 0, 0, 1],
    ):
        m = encode_camera_info(good, 0, 'cam')
        m.k[:] = np.array(k, float)
        with pytest.raises(MessageError) as e:
            decode_camera_info(m, PITCH)
        assert e.value.reason == 'bad_camera_info'


def test_a_rejected_camera_info_withdraws_the_one_in_use():
    from polarization_compass.pipeline import CameraInfoState, PipelineError

    s = CameraInfoState()
    assert s.camera() is None and not s.received_any  # nothing yet: the caller's fallback
    cam = CameraModel('pinhole', W, H, F_MM, PITCH, PITCH)
    s.accept(cam)
    assert s.camera() is cam
    s.reject('bad_camera_info: principal point at the corner')
    with pytest.raises(PipelineError, match='corner'):
        s.camera()
    s.accept(cam)
    assert s.camera() is cam and (s.accepted, s.rejected) == (2, 1)


# --------------------------------------------------------------------------------------------
# heading vs. IMU prior
# --------------------------------------------------------------------------------------------
def _result(bearing, sigma, axial=False, sun_az=0.0):
    from polarization_compass.estimators.base import HeadingResult

    return HeadingResult.from_psi(
        'least_squares', bearing - sun_az, sun_az, sigma, 1000, 0.9, axial
    )


@pytest.mark.parametrize(
    'bearing, prior, sigma, axial, ok',
    [
        (40.0, 97.0, 0.3, False, False),  # issue 18: an IMU prior 57 deg away raised nothing
        (40.0, 80.0, 0.3, False, True),  # 40 deg: within 3 x sqrt(0.3^2 + 15^2) = 45.0
        (5.0, 350.0, 0.3, False, True),  # across North: 15 deg, not 345
        (5.0, 200.0, 0.3, True, True),  # axial: 15 deg modulo 180
        (5.0, 200.0, 0.3, False, False),  # resolved: 165 deg
        (40.0, 97.0, 10.0, False, False),  # 3 x sqrt(10^2 + 15^2) = 54.1 < 57
        (40.0, 97.0, 12.0, False, True),  # a wider sigma: 3 x sqrt(12^2 + 15^2) = 57.6 > 57
    ],
)
def test_a_heading_beyond_its_sigma_from_the_imu_prior_is_not_ok(bearing, prior, sigma, axial, ok):
    from polarization_compass.pipeline import check_prior_agreement

    r = _result(bearing, sigma, axial)
    limit = 3.0 * math.sqrt(sigma**2 + 15.0**2)
    d = (bearing - prior) % (180.0 if axial else 360.0)
    off = min(d, (180.0 if axial else 360.0) - d)  # the distance, computed here independently
    assert (off <= limit) == ok
    out = check_prior_agreement(r, prior, 15.0)
    if off <= limit:
        assert out is r
    else:
        assert not out.ok and out.status.value == 'prior_disagrees' and out.psi_deg is None
        assert f'{off:.1f} deg from the IMU prior' in out.reason
        assert out.extras['rejected_bearing_deg'] == pytest.approx(bearing)


def test_the_prior_check_is_off_without_a_prior_or_with_sigma_0_and_only_for_the_imu_source():
    from polarization_compass.pipeline import check_prior_agreement, FrameInputs, TiltAndPrior

    r = _result(40.0, 0.3)
    assert check_prior_agreement(r, None, 15.0) is r and check_prior_agreement(r, 97.0, 0.0) is r
    inp = FrameInputs(None, None, 97.0)
    assert not TiltAndPrior('least_squares', 'imu').checked(r, inp).ok
    assert TiltAndPrior('least_squares', 'last').checked(r, inp) is r


def test_image_loss_watch_counts_camera_info_without_its_image():
    """
    The image-loss watch counts a camera_info without its image.

    One camera_info per image (same stamp): a camera_info whose image never came, 1 s (stamp time)
    behind the newest camera_info, is one lost image; an image arriving before or after its
    camera_info is not.
    """
    from polarization_compass.pipeline import ImageLossWatch

    w = ImageLossWatch(after_ns=1_000_000_000)
    ms = 1_000_000
    lost = 0
    for k in range(40):  # 10 Hz for 4 s; images 5, 6 and 17 never arrive
        t = k * 100 * ms
        if k % 2:  # image first on odd frames, camera_info first on even
            if k not in (5, 17):
                w.image(t)
            lost += w.camera_info(t)
        else:
            lost += w.camera_info(t)
            if k != 6:
                w.image(t)
    assert lost == 3 == w.lost
    assert w.camera_info(39 * 100 * ms) == 0  # a repeated camera_info of a seen image: nothing


def test_bag_metadata_that_is_a_device_or_fifo_is_refused(tmp_path):
    """Rosbags would read a metadata.yaml that is /dev/zero without end: refused from a stat."""
    from polarization_compass.bag import BagError, BagReader

    for name, make in (('zero', lambda p: os.symlink('/dev/zero', p)), ('fifo', os.mkfifo)):
        d = tmp_path / name
        d.mkdir()
        make(d / 'metadata.yaml')
        with pytest.raises(BagError, match='device|FIFO'):
            BagReader(d)


def test_image_loss_watch_never_counts_streams_that_are_not_paired():
    """
    The image-loss watch never counts streams that are not paired.

    A driver stamping camera_info differently from its images: nothing is ever counted as lost.
    """
    from polarization_compass.pipeline import ImageLossWatch

    w = ImageLossWatch(after_ns=1_000_000_000)
    lost = 0
    for k in range(50):
        w.image(k * 100_000_000)
        lost += w.camera_info(k * 100_000_000 + 1234)
    assert lost == 0 and not w.paired
