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
sensor_msgs/Image -> raw polarizer mosaic: the one image decoder of the package.

:func:`decode_mosaic` is what the nodes (``nodes.msgs.decode_image``) and the offline replay
convert images with. It checks the message itself (encoding, even size, ``step``, data length),
then converts it through ``cv_bridge`` where that imports (a ROS install) and can convert the
message, else with numpy, and holds either result to the same contract: one function chooses
(:func:`image_decoder` says which it chose in this process). ``cv_bridge`` is the ROS package
(``imgmsg_to_cv2``, passthrough encoding); PyPI has no ROS 2 cv_bridge, so without a ROS install
(or with ``POLARIZATION_COMPASS_CV_BRIDGE=0``) the numpy conversion runs. The two are tested
bit-identical (``test/test_image_decoder.py``).
"""

from __future__ import annotations

import os
import sys

import numpy as np

from .errors import MessageError

__all__ = ['decode_mosaic', 'image_decoder', 'MOSAIC_ENCODINGS']

#: The image encodings of a raw polarizer mosaic and their pixel types.
MOSAIC_ENCODINGS = {
    'mono8': np.uint8,
    '8UC1': np.uint8,
    'mono16': np.uint16,
    '16UC1': np.uint16,
    '32FC1': np.float32,
}
_ENCODINGS = MOSAIC_ENCODINGS  # the name the package used before

_BRIDGE: list = []  # [CvBridge instance or None], filled on first use


def image_decoder() -> str:
    """
    Return which conversion :func:`decode_mosaic` uses in this process.

    Returns
    -------
    str
        ``"cv_bridge"`` where the ROS package ``cv_bridge`` imports and
        ``POLARIZATION_COMPASS_CV_BRIDGE`` is not ``0``, else ``"numpy"``. With ``"cv_bridge"``,
        the messages cv_bridge cannot convert (see :func:`decode_mosaic`) still go through numpy.

    """
    return 'cv_bridge' if _bridge() is not None else 'numpy'


def _bridge():
    """Return the process's ``CvBridge`` (created on first use), or None where there is none."""
    if not _BRIDGE:
        bridge = None
        if os.environ.get('POLARIZATION_COMPASS_CV_BRIDGE', '1').strip() != '0':
            try:
                from cv_bridge import CvBridge

                bridge = CvBridge()
            # missing, or broken (PyPI's ROS 1 cv-bridge on numpy 2)
            except Exception:  # noqa: BLE001
                bridge = None
        _BRIDGE.append(bridge)
    return _BRIDGE[0]


def decode_mosaic(msg) -> np.ndarray:
    """
    Return the raw mosaic of a sensor_msgs/Image as a (height, width) array, native byte order.

    uint8 (``mono8``/``8UC1``), uint16 (``mono16``/``16UC1``: drivers put 10/12-bit samples in
    these) or float32 (``32FC1``: the simulator's ideal polarizer intensities, finite and >= 0).

    The message is checked first (the same refusals whichever conversion runs), then converted
    through ``cv_bridge`` (:func:`image_decoder`) or numpy. cv_bridge is not given what its
    Python conversion gets wrong, and numpy converts those: a byte order other than the host's
    (``imgmsg_to_cv2`` then calls ``ndarray.newbyteorder``, which NumPy 2 removed) and a ``step``
    that is not a whole number of pixels (it reads rows of ``int(step / pixel size)`` pixels).

    Parameters
    ----------
    msg : sensor_msgs.msg.Image
        The message (rosbags class or rclpy message: duck-typed; ``encoding``, ``height``,
        ``width``, ``step``, ``is_bigendian``, ``data``).

    Returns
    -------
    numpy.ndarray
        The mosaic [counts, or intensity for ``32FC1``], shape (height, width); a view of the
        message's data when already native and unpadded.

    Raises
    ------
    MessageError
        ``bad_encoding`` (unsupported encoding), ``bad_size`` (odd or < 2 dimensions, step <
        width x bytes per pixel, data length != step x height), ``bad_image`` (cv_bridge failed
        or returned another shape or type), and for ``32FC1`` ``non_finite`` (NaN/inf) or
        ``bad_value`` (negative intensities).

    """
    enc, dtype, h, w, step, buf = _checked_layout(msg)
    bridge = _bridge()
    big = bool(msg.is_bigendian)
    if bridge is not None and big == (sys.byteorder == 'big') and step % dtype.itemsize == 0:
        img = _via_cv_bridge(bridge, msg, enc, dtype, h, w)
    else:
        img = _via_numpy(buf, dtype, h, w, step, big)
    if dtype.kind == 'f':
        if not np.isfinite(img).all():
            raise MessageError('non_finite', f'{enc} mosaic has NaN or inf pixels')
        if (img < 0).any():
            raise MessageError('bad_value', f'{enc} mosaic has negative intensities')
    return img


def _checked_layout(msg):
    """Return ``(encoding, dtype, height, width, step, bytes)`` of an image, or refuse it."""
    enc = str(msg.encoding)
    if enc not in MOSAIC_ENCODINGS:
        raise MessageError(
            'bad_encoding',
            f'image encoding {enc!r} is not a raw polarizer mosaic '
            f'(expected one of {", ".join(MOSAIC_ENCODINGS)})',
        )
    dtype = np.dtype(MOSAIC_ENCODINGS[enc])
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    buf = (
        np.frombuffer(msg.data, dtype=np.uint8)
        if not isinstance(msg.data, np.ndarray)
        else msg.data.view(np.uint8).reshape(-1)
    )
    if h < 2 or w < 2 or h % 2 or w % 2:
        raise MessageError('bad_size', f'mosaic {w}x{h} must have even width and height >= 2')
    if step < w * dtype.itemsize:
        raise MessageError('bad_size', f'step {step} < width {w} x {dtype.itemsize} bytes')
    if buf.size != step * h:
        raise MessageError('bad_size', f'data has {buf.size} bytes, step x height = {step * h}')
    return enc, dtype, h, w, step, buf


def _via_numpy(buf: np.ndarray, dtype: np.dtype, h: int, w: int, step: int, big: bool):
    """Return the checked image's pixels, converted with numpy (rows cut to ``width``)."""
    rows = buf.reshape(h, step)[:, : w * dtype.itemsize]
    img = rows.view(dtype.newbyteorder('>' if big else '<')) if dtype.itemsize > 1 else rows
    return np.ascontiguousarray(img, dtype=dtype)  # a view when already native and unpadded


def _via_cv_bridge(bridge, msg, enc: str, dtype: np.dtype, h: int, w: int) -> np.ndarray:
    """Return the checked image's pixels, converted by cv_bridge and held to the same contract."""
    try:
        img = bridge.imgmsg_to_cv2(msg, desired_encoding='passthrough')
    except Exception as exc:  # noqa: BLE001 - CvBridgeError, TypeError, ValueError, ...
        raise MessageError('bad_image', f'cv_bridge: {type(exc).__name__}: {exc}') from None
    img = np.asarray(img)
    if img.shape != (h, w) or img.dtype.kind != dtype.kind or img.dtype.itemsize != dtype.itemsize:
        raise MessageError(
            'bad_image', f'cv_bridge gave {img.dtype} {img.shape} for a {w}x{h} {enc} image'
        )
    return np.ascontiguousarray(img, dtype=dtype)
