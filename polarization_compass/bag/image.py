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

"""sensor_msgs/Image -> raw polarizer mosaic: the one image decoder of the package."""

from __future__ import annotations

import numpy as np

from .errors import MessageError

__all__ = ['decode_mosaic']

_ENCODINGS = {
    'mono8': np.uint8,
    '8UC1': np.uint8,
    'mono16': np.uint16,
    '16UC1': np.uint16,
    '32FC1': np.float32,
}


def decode_mosaic(msg) -> np.ndarray:
    """
    Return the raw mosaic of a sensor_msgs/Image as a (height, width) array, native byte order.

    uint8 (``mono8``/``8UC1``), uint16 (``mono16``/``16UC1``: drivers put 10/12-bit samples in
    these) or float32 (``32FC1``: the simulator's ideal polarizer intensities, finite and >= 0).

    Parameters
    ----------
    msg : sensor_msgs.msg.Image
        The message (rosbags class or rclpy message: duck-typed).

    Returns
    -------
    numpy.ndarray
        The mosaic [counts, or intensity for ``32FC1``], shape (height, width); a view of the
        message's data when already native and unpadded.

    Raises
    ------
    MessageError
        ``bad_encoding`` (unsupported encoding), ``bad_size`` (odd or < 2 dimensions, step <
        width x bytes per pixel, data length != step x height), and for ``32FC1``
        ``non_finite`` (NaN/inf) or ``bad_value`` (negative intensities).

    """
    enc = str(msg.encoding)
    if enc not in _ENCODINGS:
        raise MessageError(
            'bad_encoding',
            f'image encoding {enc!r} is not a raw polarizer mosaic '
            f'(expected one of {", ".join(_ENCODINGS)})',
        )
    dtype = np.dtype(_ENCODINGS[enc])
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
    rows = buf.reshape(h, step)[:, : w * dtype.itemsize]
    img = (
        rows.view(dtype.newbyteorder('>' if msg.is_bigendian else '<'))
        if dtype.itemsize > 1
        else rows
    )
    img = np.ascontiguousarray(img, dtype=dtype)  # a view when already native and unpadded
    if dtype.kind == 'f':
        if not np.isfinite(img).all():
            raise MessageError('non_finite', f'{enc} mosaic has NaN or inf pixels')
        if (img < 0).any():
            raise MessageError('bad_value', f'{enc} mosaic has negative intensities')
    return img
