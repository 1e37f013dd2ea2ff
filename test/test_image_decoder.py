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
The one image decoder (``bag.image.decode_mosaic``, the nodes' ``decode_image``) and cv_bridge.

The tests marked ``real cv_bridge`` run against the ROS 2 cv_bridge itself (issue 26): from a ROS
install, or ``../shared/ros-cpp/install.sh .venv --with-cv-bridge`` then ``source
.venv/opt/ros-cpp/setup.bash``. Where it is not importable and usable they skip and say so. They
check that the decoder really converts through cv_bridge where cv_bridge can, bit-identical to the
numpy conversion and to the array that was encoded (mono8, mono16, 32FC1; both byte orders; padded
``step``), that it refuses the same bad images for the same reasons with and without cv_bridge,
and which messages cv_bridge cannot convert (those go through numpy).
"""

from __future__ import annotations

import sys

import numpy as np
from polarization_compass import bag as B
from polarization_compass.bag import image
from polarization_compass.bag.errors import MessageError
import pytest

_INSTALL = (
    'cv_bridge (ROS 2) is not importable or not usable here: install it from a ROS distribution, '
    'or run ../shared/ros-cpp/install.sh .venv --with-cv-bridge and '
    '`source .venv/opt/ros-cpp/setup.bash` before pytest'
)


def _real_bridge():
    """Return a working real CvBridge, or skip the test saying what to install."""
    try:
        from cv_bridge import CvBridge
        from sensor_msgs.msg import Image

        bridge = CvBridge()
        probe = Image(height=2, width=2, encoding='mono8', step=2, data=bytes([1, 2, 3, 4]))
        out = bridge.imgmsg_to_cv2(probe, desired_encoding='passthrough')
        assert np.array_equal(out, [[1, 2], [3, 4]])
    except Exception as exc:  # noqa: BLE001 - missing, broken or unusable: all mean skip
        pytest.skip(f'{_INSTALL} ({type(exc).__name__}: {exc})')
    return bridge


class _Counting:
    """The real bridge, counting its conversions (to prove which conversion ran)."""

    def __init__(self, bridge):
        self.bridge = bridge
        self.calls = 0

    def imgmsg_to_cv2(self, msg, desired_encoding='passthrough'):
        self.calls += 1
        return self.bridge.imgmsg_to_cv2(msg, desired_encoding=desired_encoding)


@pytest.fixture
def real_bridge(monkeypatch):
    """Set the decoder to the real cv_bridge (skip where there is none); yield the counter."""
    counting = _Counting(_real_bridge())
    monkeypatch.delenv('POLARIZATION_COMPASS_CV_BRIDGE', raising=False)
    monkeypatch.setattr(image, '_BRIDGE', [])
    assert image.image_decoder() == 'cv_bridge'  # selected by the decoder itself
    monkeypatch.setattr(image, '_BRIDGE', [counting])
    yield counting
    image._BRIDGE.clear()


@pytest.fixture
def without_bridge(monkeypatch):
    monkeypatch.setitem(sys.modules, 'cv_bridge', None)  # import fails
    monkeypatch.setattr(image, '_BRIDGE', [])
    yield
    image._BRIDGE.clear()


def _numpy_decode(msg, monkeypatch):
    """Decode with cv_bridge switched off (the environment switch), then restore the bridge."""
    saved = list(image._BRIDGE)
    with monkeypatch.context() as m:
        m.setenv('POLARIZATION_COMPASS_CV_BRIDGE', '0')
        m.setattr(image, '_BRIDGE', [])
        assert image.image_decoder() == 'numpy'
        out = image.decode_mosaic(msg)
    image._BRIDGE[:] = saved
    return out


def _rclpy_image(a: np.ndarray, big: bool, pad: int):
    """Return an rclpy Image of ``a``, rows padded by ``pad`` bytes of 0xEE, packed by hand."""
    from sensor_msgs.msg import Image

    enc = {np.dtype(np.uint8): 'mono8', np.dtype(np.uint16): 'mono16'}.get(a.dtype, '32FC1')
    row = a.shape[1] * a.itemsize
    raw = a.astype(a.dtype.newbyteorder('>' if big else '<')).tobytes()
    data = b''.join(raw[r * row : (r + 1) * row] + b'\xee' * pad for r in range(a.shape[0]))
    return Image(
        height=a.shape[0],
        width=a.shape[1],
        encoding=enc,
        is_bigendian=int(big),
        step=row + pad,
        data=data,
    )


def _mosaic(dtype, shape=(6, 8), seed=3):
    rng = np.random.default_rng(seed)
    top = {np.uint8: 255, np.uint16: 4095}.get(dtype, 4000.0)
    a = rng.uniform(0, top, shape)
    return a.astype(dtype) if dtype is np.float32 else np.round(a).astype(dtype)


_NATIVE_BIG = sys.byteorder == 'big'


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize('big', [False, True])
@pytest.mark.parametrize('pad', [0, 4, 5])
def test_real_cv_bridge_and_numpy_give_the_same_mosaic(real_bridge, monkeypatch, dtype, big, pad):
    a = _mosaic(dtype)
    m = _rclpy_image(a, big, pad)
    out = image.decode_mosaic(m)
    assert out.dtype == a.dtype and out.flags.c_contiguous and out.dtype.isnative
    np.testing.assert_array_equal(out, a)  # the encoded array, bit for bit
    np.testing.assert_array_equal(out, _numpy_decode(m, monkeypatch))
    # cv_bridge converted it where it can: host byte order and a step of whole pixels
    whole = (a.shape[1] * a.itemsize + pad) % a.itemsize == 0
    assert real_bridge.calls == (1 if big == _NATIVE_BIG and whole else 0)


def test_real_cv_bridge_converts_what_it_is_given_bit_identically(real_bridge):
    """cv_bridge's own output (no decoder around it) equals the encoded arrays."""
    for dtype in (np.uint8, np.uint16, np.float32):
        a = _mosaic(dtype, seed=7)
        for pad in (0, 8):
            m = _rclpy_image(a, _NATIVE_BIG, pad)
            got = np.asarray(real_bridge.bridge.imgmsg_to_cv2(m, desired_encoding='passthrough'))
            assert got.shape == a.shape and got.dtype.kind == a.dtype.kind
            np.testing.assert_array_equal(got.astype(a.dtype), a)


def test_what_real_cv_bridge_cannot_convert_goes_through_numpy(real_bridge):
    """
    The two messages the decoder keeps from cv_bridge, and why.

    If this fails because cv_bridge now converts them right, the routing in
    ``bag.image.decode_mosaic`` can be dropped.
    """
    a = _mosaic(np.uint16, seed=11)
    foreign = _rclpy_image(a, not _NATIVE_BIG, 0)  # NumPy 2 removed ndarray.newbyteorder
    with pytest.raises(AttributeError, match='newbyteorder'):
        real_bridge.bridge.imgmsg_to_cv2(foreign, desired_encoding='passthrough')
    odd_step = _rclpy_image(a, _NATIVE_BIG, 5)  # rows of int(step / 2) pixels: misread
    got = real_bridge.bridge.imgmsg_to_cv2(odd_step, desired_encoding='passthrough')
    assert not np.array_equal(got, a)
    # the decoder gets both right, without cv_bridge
    np.testing.assert_array_equal(image.decode_mosaic(foreign), a)
    np.testing.assert_array_equal(image.decode_mosaic(odd_step), a)
    assert real_bridge.calls == 0


def test_real_cv_bridge_decodes_the_replays_rosbags_messages(real_bridge, monkeypatch):
    """The offline replay's messages (rosbags classes, read-only data views) go through it too."""
    for dtype in (np.uint8, np.uint16):
        a = _mosaic(dtype, shape=(8, 12), seed=5)
        raw = B.typestore().serialize_cdr(B.encode_mosaic(a, 1, 'cam'), 'sensor_msgs/msg/Image')
        msg = B.deserialize(raw, 'sensor_msgs/msg/Image')
        out = B.decode_mosaic(msg)
        np.testing.assert_array_equal(out, a)
        np.testing.assert_array_equal(out, _numpy_decode(msg, monkeypatch))
    assert real_bridge.calls == 2


def test_the_nodes_decode_with_the_one_decoder():
    msgs = pytest.importorskip('polarization_compass.nodes.msgs', reason='rclpy messages needed')
    assert msgs.decode_image is image.decode_mosaic is B.decode_mosaic


def test_without_cv_bridge_numpy_runs(without_bridge):
    assert image.image_decoder() == 'numpy'
    a = np.arange(24, dtype=np.uint16).reshape(4, 6) * 100
    m = B.encode_mosaic(a, 1, 'cam')
    np.testing.assert_array_equal(image.decode_mosaic(m), a)


def test_environment_switch_selects_numpy(monkeypatch):
    monkeypatch.setenv('POLARIZATION_COMPASS_CV_BRIDGE', '0')
    monkeypatch.setattr(image, '_BRIDGE', [])
    assert image.image_decoder() == 'numpy'
    image._BRIDGE.clear()


def _bad(case: str):
    a = np.full((4, 6), 7.0, dtype=np.float32)
    if case == 'nan':
        a[1, 2] = np.nan
    if case == 'negative':
        a[3, 5] = -1.0
    if case in ('rgb8', 'odd', 'short', 'long', 'narrow_step'):
        a = np.full((4, 6), 7, dtype=np.uint16)
    m = _rclpy_image(a, _NATIVE_BIG, 0)
    if case == 'rgb8':
        m.encoding = 'rgb8'
    if case == 'odd':
        m.height, m.data = 3, bytes(m.data)[: 3 * m.step]
    if case == 'short':
        m.data = bytes(m.data)[:-4]
    if case == 'long':
        m.data = bytes(m.data) + b'\0' * m.step
    if case == 'narrow_step':
        m.step = 10  # < 6 px x 2 bytes
        m.data = bytes(m.data)[: 10 * 4]
    return m


_BAD = [
    ('rgb8', 'bad_encoding'),
    ('odd', 'bad_size'),
    ('short', 'bad_size'),
    ('long', 'bad_size'),
    ('narrow_step', 'bad_size'),
    ('nan', 'non_finite'),
    ('negative', 'bad_value'),
]


@pytest.mark.parametrize('case, reason', _BAD)
def test_real_cv_bridge_refuses_the_same_bad_images(real_bridge, monkeypatch, case, reason):
    m = _bad(case)
    with pytest.raises(MessageError) as err:
        image.decode_mosaic(m)
    assert err.value.reason == reason
    with pytest.raises(MessageError) as err2:
        _numpy_decode(m, monkeypatch)
    assert err2.value.reason == reason
    # bad layouts are refused before cv_bridge; bad 32FC1 values after its conversion
    assert real_bridge.calls == (1 if case in ('nan', 'negative') else 0)
