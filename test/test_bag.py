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
Tests of the bag package: topic mapping, message conversions, rosbag2 I/O and errors.

Message conversions are checked against hand-built bytes and closed forms, rosbag2 reading and
writing in both storage formats, and one-line errors for paths that are not bags.
"""

import math
from pathlib import Path
import struct

import numpy as np
from polarization_compass import bag as B
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import (
    body_quat_from_camera_attitude,
    camera_attitude_from_body_quat,
    CameraAttitude,
)
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------------------------
# topic mapping
# ------------------------------------------------------------------------------------------------
def test_shipped_config_is_the_builtin_default():
    shipped = yaml.safe_load((ROOT / 'config' / 'replay_topics.yaml').read_text())
    assert (
        B.load_topic_map(ROOT / 'config' / 'replay_topics.yaml').to_dict()
        == B.default_topic_map().to_dict()
    )
    assert shipped['topics'] == B.BUILTIN_TOPIC_MAP['topics']


def test_partial_mapping_keeps_defaults_and_accepts_quaternion_stamped(tmp_path):
    p = tmp_path / 'm.yaml'
    p.write_text(
        'topics:\n  reference: {topic: /dual_antenna/heading, type: '
        'geometry_msgs/msg/QuaternionStamped}\n'
        '  image: /cam/raw\n'
    )
    m = B.load_topic_map(p)
    assert m.spec('reference') == B.TopicSpec(
        '/dual_antenna/heading', 'geometry_msgs/msg/QuaternionStamped'
    )
    assert m.spec('image').topic == '/cam/raw' and m.spec('image').type == 'sensor_msgs/msg/Image'
    assert m.spec('imu') == B.default_topic_map().spec('imu')
    assert m.role_of_topic('/cam/raw') == 'image' and m.role_of_topic('/nope') is None


@pytest.mark.parametrize(
    'text, words',
    [
        ('topics:\n  lidar: /x\n', 'unknown role'),
        (
            'topics:\n  image: {topic: /a, type: sensor_msgs/msg/CompressedImage}\n',
            'not supported',
        ),
        ('topics:\n  image: relative\n', 'absolute'),
        ('topics:\n  image: /same\n  imu: /same\n', 'more than one role'),
        ('colour: red\n', 'unknown key'),
        ('max_gap_s: {imu: -1}\n', 'positive'),
        ('mounting: {R_body_cam: [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}\n', 'rotation'),
        ('site: {latitude_deg: 95, longitude_deg: 0}\n', 'latitude'),
        ('topics: [1, 2\n', 'not valid YAML'),
    ],
)
def test_bad_mapping_is_one_clear_error(tmp_path, text, words):
    p = tmp_path / 'm.yaml'
    p.write_text(text)
    with pytest.raises(B.BagError) as ei:
        B.load_topic_map(p)
    assert words in str(ei.value) and '\n' not in str(ei.value)


def test_missing_directory_binary_or_unsafe_mapping_file_is_one_line(tmp_path):
    with pytest.raises(B.BagError, match='does not exist'):
        B.load_topic_map('/nonexistent/m.yaml')
    with pytest.raises(B.BagError, match='is a directory'):
        B.load_topic_map(tmp_path)
    (tmp_path / 'bin.yaml').write_bytes(b'\x89PNG\r\n\x1a\n\xff\xfe')
    with pytest.raises(B.BagError, match='not UTF-8'):
        B.load_topic_map(tmp_path / 'bin.yaml')
    (tmp_path / 'evil.yaml').write_text(
        "topics: !!python/object/apply:os.system ['touch %s']\n" % (tmp_path / 'PWNED')
    )
    with pytest.raises(B.BagError, match='safe loader'):
        B.load_topic_map(tmp_path / 'evil.yaml')
    assert not (tmp_path / 'PWNED').exists()


# ------------------------------------------------------------------------------------------------
# images
# ------------------------------------------------------------------------------------------------
class _Img:
    """A duck-typed Image (as rclpy would give) built from raw bytes."""

    def __init__(self, h, w, enc, step, data, big=0):
        self.height, self.width, self.encoding, self.step, self.data, self.is_bigendian = (
            h,
            w,
            enc,
            step,
            data,
            big,
        )


def test_mono16_big_endian_and_padded_rows_from_hand_built_bytes():
    vals = [[1, 2, 3, 4], [0x0102, 0xFFFE, 4095, 0]]
    rows = b''.join(
        struct.pack('>4H', *r) + b'\xaa\xbb' for r in vals
    )  # 2 bytes of padding per row
    img = B.decode_mosaic(_Img(2, 4, 'mono16', 10, rows, big=1))
    assert img.dtype == np.uint16 and img.shape == (2, 4)
    assert img.tolist() == vals
    little = b''.join(struct.pack('<4H', *r) for r in vals)
    assert B.decode_mosaic(_Img(2, 4, '16UC1', 8, bytearray(little))).tolist() == vals


def test_float_mosaic_of_the_simulator_and_its_failures():
    vals = [[0.0, 1.5, 2.25, 1e-3], [3.0, 0.5, 7.0, 8.0]]
    img = B.decode_mosaic(
        _Img(2, 4, '32FC1', 16, b''.join(struct.pack('>4f', *r) for r in vals), big=1)
    )
    assert img.dtype == np.float32 and img.tolist() == np.float32(vals).tolist()
    for bad, reason in ((float('nan'), 'non_finite'), (-1.0, 'bad_value')):
        raw = struct.pack('<4f', 0, 1, 2, bad) * 2
        with pytest.raises(B.MessageError) as ei:
            B.decode_mosaic(_Img(2, 4, '32FC1', 16, raw))
        assert ei.value.reason == reason


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16])
def test_mosaic_cdr_round_trip(dtype):
    rng = np.random.default_rng(1)
    m = rng.integers(0, np.iinfo(dtype).max, size=(6, 8), dtype=dtype)
    msg = B.encode_mosaic(m, 1_573_797_600_123_456_789, 'cam')
    raw = B.typestore().serialize_cdr(msg, 'sensor_msgs/msg/Image')
    back = B.deserialize(raw, 'sensor_msgs/msg/Image')
    assert back.encoding == ('mono8' if dtype == np.uint8 else 'mono16')
    assert back.step == 8 * np.dtype(dtype).itemsize
    assert B.stamp_ns(back.header) == 1_573_797_600_123_456_789
    np.testing.assert_array_equal(B.decode_mosaic(back), m)


@pytest.mark.parametrize(
    'h, w, enc, step, nbytes, reason',
    [
        (2, 4, 'rgb8', 12, 24, 'bad_encoding'),
        (2, 4, 'mono16', 8, 15, 'bad_size'),  # truncated
        (2, 4, 'mono16', 6, 12, 'bad_size'),  # step shorter than a row
        (3, 4, 'mono8', 4, 12, 'bad_size'),  # odd height: not a 2x2 mosaic
        (2, 4, 'mono8', 4, 9, 'bad_size'),  # too long
    ],
)
def test_bad_images_raise_message_error_with_reason(h, w, enc, step, nbytes, reason):
    with pytest.raises(B.MessageError) as ei:
        B.decode_mosaic(_Img(h, w, enc, step, bytes(nbytes)))
    assert ei.value.reason == reason


def test_garbage_cdr_is_bad_cdr():
    with pytest.raises(B.MessageError) as ei:
        B.deserialize(b'\x00\x01\x00\x00' + b'\xff' * 40, 'sensor_msgs/msg/Image')
    assert ei.value.reason == 'bad_cdr'


# ------------------------------------------------------------------------------------------------
# camera_info
# ------------------------------------------------------------------------------------------------
def test_camera_info_of_the_paper_imager_has_the_closed_form_k():
    cam = CameraModel()  # 2448 x 2048, f 4 mm, 3.45 um
    msg = B.encode_camera_info(cam, 0, 'cam_optical')
    fx = 4.0e-3 / 3.45e-6  # 1159.42 px
    np.testing.assert_allclose(msg.k, [fx, 0, 1223.5, 0, fx, 1023.5, 0, 0, 1], rtol=1e-12)
    assert msg.distortion_model == 'plumb_bob' and not np.any(msg.d)
    back = B.decode_camera_info(
        B.deserialize(
            B.typestore().serialize_cdr(msg, 'sensor_msgs/msg/CameraInfo'),
            'sensor_msgs/msg/CameraInfo',
        ),
        3.45,
    )
    # the principal pixel (1-based centre) looks along the optical axis; a corner's angle is atan(r
    # / f)
    r, _ = back.rays_from_pixels([1224.5, 1.0], [1024.5, 1.0])
    np.testing.assert_allclose(r[:, 0], [0, 0, 1], atol=1e-12)
    corner_mm = math.hypot(1223.5, 1023.5) * 3.45e-3
    assert math.degrees(math.acos(r[2, 1])) == pytest.approx(
        math.degrees(math.atan2(corner_mm, 4.0)), abs=1e-9
    )


def test_camera_info_fisheye_and_pixel_pitch_independence():
    cam = CameraModel(
        model='fisheye_equidistant',
        width_px=64,
        height_px=48,
        focal_length_mm=0.1,
        pixel_pitch_x_um=5.0,
        pixel_pitch_y_um=5.0,
    )
    msg = B.encode_camera_info(cam, 0, 'c')
    assert msg.distortion_model == 'equidistant'
    # a wrong pixel pitch in the mapping scales f and the pitch together: rays do not change
    a = B.decode_camera_info(msg, 5.0)
    b = B.decode_camera_info(msg, 2.0)
    x, y = np.array([1.0, 10.0, 64.0]), np.array([1.0, 30.0, 48.0])
    np.testing.assert_allclose(
        a.rays_from_pixels(x, y)[0], b.rays_from_pixels(x, y)[0], atol=1e-12
    )
    # equidistant: angle from the axis = pixel radius * pitch / f
    theta = math.hypot(64 - 32.5, 48 - 24.5) * 5e-3 / 0.1
    assert math.acos(a.rays_from_pixels([64.0], [48.0])[0][2, 0]) == pytest.approx(theta, abs=1e-9)


def test_camera_info_distortion_is_kept_and_unknown_models_or_nan_are_refused():
    msg = B.encode_camera_info(CameraModel(width_px=8, height_px=6), 0, 'c')
    msg.d[0] = 0.1
    cam = B.decode_camera_info(msg, 3.45)
    assert cam.distortion_model == 'plumb_bob' and cam.distortion[0] == 0.1 and cam.distorted
    msg.distortion_model = 'kannala_brandt'
    with pytest.raises(B.MessageError) as ei:
        B.decode_camera_info(msg, 3.45)
    assert ei.value.reason == 'unsupported_camera'
    msg.distortion_model = 'plumb_bob'
    msg.d = [0.1, 0.2]
    with pytest.raises(B.MessageError) as ei:
        B.decode_camera_info(msg, 3.45)
    assert ei.value.reason == 'bad_camera_info'
    msg.d = [0.0] * 5
    msg.k[0] = float('nan')
    with pytest.raises(B.MessageError) as ei:
        B.decode_camera_info(msg, 3.45)
    assert ei.value.reason == 'non_finite'


# ------------------------------------------------------------------------------------------------
# orientation, fix
# ------------------------------------------------------------------------------------------------
def _zyx_yaw_deg(q):
    x, y, z, w = q
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


@pytest.mark.parametrize(
    'bearing, pitch, roll', [(0, 0, 0), (30, -20, 0), (200, -16.3, -9.9), (359, 10, 29.1)]
)
def test_body_quaternion_yaw_is_90_minus_camera_bearing_even_when_tilted(bearing, pitch, roll):
    q = body_quat_from_camera_attitude(CameraAttitude(bearing, pitch, roll))
    yaw = _zyx_yaw_deg(q)  # REP-103 yaw (ZYX Euler)
    assert math.remainder(yaw - (90 - bearing), 360) == pytest.approx(0, abs=1e-9)
    att = camera_attitude_from_body_quat(q)
    assert (att.pitch_deg, att.roll_deg) == pytest.approx((pitch, roll), abs=1e-9)
    assert math.remainder(att.bearing_deg - bearing, 360) == pytest.approx(0, abs=1e-9)


def test_level_body_pointing_north_has_camera_bearing_zero():
    # REP-103 yaw 90 deg (x forward to North): q = (0, 0, sin 45, cos 45); camera +y is forward
    q = [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    att = camera_attitude_from_body_quat(q)
    assert math.remainder(att.bearing_deg, 360) == pytest.approx(0, abs=1e-12)


def test_orientation_decoding_reasons():
    q = body_quat_from_camera_attitude(CameraAttitude(10, 5, 0))
    imu = B.encode_imu(q, 0, 'imu', (1e-4, 1e-4, 1.0))
    np.testing.assert_allclose(B.decode_orientation(imu), q, atol=1e-12)
    np.testing.assert_allclose(
        B.decode_orientation(B.encode_quaternion_stamped(q, 0, 'b')), q, atol=1e-12
    )
    imu.orientation_covariance[0] = -1
    with pytest.raises(B.MessageError) as ei:
        B.decode_orientation(imu)
    assert ei.value.reason == 'no_orientation'
    with pytest.raises(B.MessageError) as ei:
        B.decode_orientation(B.encode_quaternion_stamped([0, 0, float('nan'), 1], 0, 'b'))
    assert ei.value.reason == 'non_finite'
    with pytest.raises(B.MessageError) as ei:
        B.decode_orientation(B.encode_quaternion_stamped([0, 0, 0.5, 0.5], 0, 'b'))
    assert ei.value.reason == 'bad_quaternion'


def test_imu_message_follows_rep145_covariance_rules():
    imu = B.encode_imu([0, 0, 0, 1], 5, 'imu', (1e-4, 2e-4, 0.3))
    assert imu.angular_velocity_covariance[0] == -1 and imu.linear_acceleration_covariance[0] == -1
    assert list(np.diag(imu.orientation_covariance.reshape(3, 3))) == [1e-4, 2e-4, 0.3]


def test_navsatfix_decoding():
    f = B.encode_navsatfix(32.0, 118.8, float('nan'), 0, 'gps')
    assert B.decode_navsatfix(f) == (32.0, 118.8, 0.0)
    f.status.status = -1
    with pytest.raises(B.MessageError, match='no_fix'):
        B.decode_navsatfix(f)
    g = B.encode_navsatfix(float('nan'), 1.0, 0.0, 0, 'gps')
    with pytest.raises(B.MessageError, match='non_finite'):
        B.decode_navsatfix(g)


def test_stamps_and_utc():
    import datetime as dt

    t = dt.datetime(2019, 11, 15, 6, 0, 0, 250000, tzinfo=dt.timezone.utc)
    ns = B.ns_from_utc(t)
    assert ns == 1573797600_250000000  # date -u -d 2019-11-15T06:00:00Z +%s = 1573797600
    assert B.utc_from_ns(ns) == t
    assert B.stamp_ns(B.stamp_from_ns(ns)) == ns


# ------------------------------------------------------------------------------------------------
# bags
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_writer_reader_round_trip_in_log_time_order(tmp_path, storage):
    path = tmp_path / 'run'
    with B.BagWriter(path, storage=storage) as w:
        for k in (2, 0, 1):  # written out of order: the bag sorts by log time
            w.write(
                'navsatfix', B.encode_navsatfix(1.0 + k, 2.0, 3.0, k * 10**9, 'gps'), k * 10**9
            )
        w.write('imu', B.encode_imu([0, 0, 0, 1], 5, 'imu'), 5)
    with B.BagReader(path) as r:
        topics = r.topics()
        assert topics['/gps/fix'] == ('sensor_msgs/msg/NavSatFix', 3)
        assert topics['/imu/data'] == ('sensor_msgs/msg/Imu', 1)
        assert topics['/camera/image_raw'] == ('sensor_msgs/msg/Image', 0)
        got = [
            (t, lt, B.decode_navsatfix(B.deserialize(raw, mt))[0])
            for t, mt, lt, raw in r.messages(['/gps/fix'])
        ]
    assert got == [('/gps/fix', 0, 1.0), ('/gps/fix', 10**9, 2.0), ('/gps/fix', 2 * 10**9, 3.0)]
    assert (path / 'metadata.yaml').is_file()
    assert any(p.suffix == ('.mcap' if storage == 'mcap' else '.db3') for p in path.iterdir())


def test_writer_refuses_to_overwrite(tmp_path):
    with pytest.raises(B.BagError, match='already exists'):
        B.BagWriter(tmp_path)


@pytest.mark.parametrize(
    'make', ['missing', 'empty_dir', 'text_file', 'bad_metadata', 'bare_mcap', 'truncated']
)
def test_not_a_bag_is_one_line_bag_error(tmp_path, make):
    p = tmp_path / 'x'
    if make == 'empty_dir':
        p.mkdir()
    elif make == 'text_file':
        p.write_text('hello')
    elif make == 'bad_metadata':
        p.mkdir()
        (p / 'metadata.yaml').write_text(
            'rosbag2_bagfile_information: {version: 9, storage_identifier: mcap}\n'
        )
    elif make == 'bare_mcap':
        p = tmp_path / 'x.mcap'
        p.write_bytes(b'\x89MCAP0\r\n' + bytes(32))
    elif make == 'truncated':
        with B.BagWriter(p, storage='mcap') as w:
            for k in range(50):
                w.write('navsatfix', B.encode_navsatfix(1.0, 2.0, 3.0, k, 'gps'), k)
        f = next(p.glob('*.mcap'))
        f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    with pytest.raises(B.BagError) as ei:
        with B.BagReader(p) as r:
            list(r.messages(['/gps/fix']))
    assert '\n' not in str(ei.value)


def test_tally_balances_and_reports():
    t = B.Tally()
    t.read['/a'] += 3
    t.used['/a'] += 1
    t.skip('/a', 'bad_cdr', 'SerdeError: x')
    assert not t.balanced()
    t.skip('/a', 'bad_size')
    assert t.balanced()
    t.note('/a', 'out_of_order')
    d = t.to_dict()['/a']
    assert d == {
        'read': 3,
        'used': 1,
        'skipped': {'bad_cdr': 1, 'bad_size': 1},
        'notes': {'out_of_order': 1},
        'first_reason': {'bad_cdr': 'SerdeError: x'},
    }
    assert t.lines() == ['/a: read 3, used 1, skipped: bad_cdr 1, bad_size 1; out_of_order 1']
