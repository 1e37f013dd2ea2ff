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
nodes.msgs.decode_image: the one function the nodes convert images with (issue 15).

cv_bridge (ROS 2) is not installable here (no registry carries it; PyPI's 1.13 is the ROS 1 package
and breaks on numpy 2), so the cv_bridge branch is exercised with a stand-in ``cv_bridge`` module
whose ``imgmsg_to_cv2`` follows cv_bridge's documented passthrough behaviour, written independently
of the project's decoder (per-row struct unpacking). What is tested is the selection and the
contract the node relies on after the bridge (encodings, sizes, dtype, finite non-negative 32FC1),
not cv_bridge itself; on a ROS install the same tests run against the real one if it is importable
(then the stand-in is not used).
"""

from __future__ import annotations

import struct
import sys
import types

import numpy as np
from polarization_compass.bag import decode_mosaic, MessageError
from polarization_compass.nodes import msgs
import pytest

_FMT = {'mono8': 'B', '8UC1': 'B', 'mono16': 'H', '16UC1': 'H', '32FC1': 'f'}


class _StandInBridge:
    """
    A cv_bridge stand-in: passthrough imgmsg_to_cv2 honouring step and byte order.

    passthrough imgmsg_to_cv2: height x width of the encoding's type, honouring step and
    is_bigendian.
    """

    calls = 0

    def imgmsg_to_cv2(self, msg, desired_encoding='passthrough'):
        assert desired_encoding == 'passthrough'
        type(self).calls += 1
        code = _FMT.get(msg.encoding)
        if code is None:
            raise RuntimeError(f'unsupported encoding {msg.encoding}')  # CvBridgeError stand-in
        size = struct.calcsize(code)
        data = bytes(msg.data)
        if len(data) < msg.step * msg.height:
            raise TypeError(
                'buffer is too small for requested array'
            )  # numpy's message in cv_bridge
        order = '>' if msg.is_bigendian else '<'
        rows = [
            struct.unpack(
                f'{order}{msg.width}{code}', data[r * msg.step:r * msg.step + msg.width * size]
            )
            for r in range(msg.height)
        ]
        return np.array(rows, dtype={'B': np.uint8, 'H': np.uint16, 'f': np.float32}[code])


@pytest.fixture
def with_bridge(monkeypatch):
    try:
        import cv_bridge  # noqa: F401 - a real one (ROS install): use it
    except ImportError:
        monkeypatch.setitem(
            sys.modules, 'cv_bridge', types.SimpleNamespace(CvBridge=_StandInBridge)
        )
    monkeypatch.delenv('POLARIZATION_COMPASS_CV_BRIDGE', raising=False)
    monkeypatch.setattr(msgs, '_BRIDGE', [])
    yield
    msgs._BRIDGE.clear()


@pytest.fixture
def without_bridge(monkeypatch):
    monkeypatch.setitem(sys.modules, 'cv_bridge', None)  # import fails
    monkeypatch.setattr(msgs, '_BRIDGE', [])
    yield
    msgs._BRIDGE.clear()


def _padded(a: np.ndarray, big: bool, pad: int = 6):
    m = msgs.image_msg(a, 1, 'cam')
    row = a.shape[1] * a.itemsize
    raw = a.astype(a.dtype.newbyteorder('>' if big else '<')).tobytes()
    m.step = row + pad
    m.data = b''.join(raw[r * row:(r + 1) * row] + b'\xee' * pad for r in range(a.shape[0]))
    m.is_bigendian = int(big)
    return m


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize('big', [False, True])
def test_cv_bridge_and_project_decoder_give_the_same_mosaic(with_bridge, dtype, big):
    assert msgs.image_decoder() == 'cv_bridge'
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 4000 if dtype != np.uint8 else 250, (4, 6)).astype(dtype)
    m = _padded(a, big)
    via_bridge = msgs.decode_image(m)
    assert via_bridge.dtype == a.dtype and via_bridge.flags.c_contiguous
    np.testing.assert_array_equal(via_bridge, a)
    np.testing.assert_array_equal(via_bridge, decode_mosaic(m))


def test_without_cv_bridge_the_project_decoder_runs(without_bridge):
    assert msgs.image_decoder() == 'decode_mosaic'
    a = np.arange(24, dtype=np.uint16).reshape(4, 6) * 100
    np.testing.assert_array_equal(msgs.decode_image(_padded(a, True)), a)


def test_environment_switch_selects_the_project_decoder(with_bridge, monkeypatch):
    monkeypatch.setenv('POLARIZATION_COMPASS_CV_BRIDGE', '0')
    msgs._BRIDGE.clear()
    assert msgs.image_decoder() == 'decode_mosaic'


@pytest.mark.parametrize(
    'case, reason',
    [
        ('rgb8', 'bad_encoding'),
        ('odd', 'bad_size'),
        ('short', 'bad_size'),
        ('nan', 'non_finite'),
        ('negative', 'bad_value'),
    ],
)
def test_cv_bridge_branch_keeps_the_decoder_contract(with_bridge, case, reason):
    a = np.full((4, 6), 7.0, dtype=np.float32)
    if case == 'nan':
        a[1, 2] = np.nan
    if case == 'negative':
        a[3, 5] = -1.0
    m = msgs.image_msg(a, 1, 'cam')
    if case == 'rgb8':
        m.encoding = 'rgb8'
    if case == 'odd':
        m.height, m.data = 3, bytes(m.data)[: 3 * m.step]
    if case == 'short':
        m.data = bytes(m.data)[:-4]
    with pytest.raises(MessageError) as err:
        msgs.decode_image(m)
    assert err.value.reason == reason
    # the project's decoder refuses the same message for the same reason
    with pytest.raises(MessageError) as err2:
        decode_mosaic(m)
    assert err2.value.reason == reason
