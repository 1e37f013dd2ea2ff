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
Hostile image files are refused from their headers, before OpenCV decodes them (issue 24).

The files are written by hand here (a PNG or TIFF header declaring more than its few bytes hold),
and OpenCV's decoders are replaced by ones that fail the test: a refusal must come before any
decoding, so no test allocates what the header declares.
"""

import struct
import zlib

import cv2
import numpy as np
from polarization_compass.cli import main
from polarization_compass.real_input import load_mask, load_polarization_input, RealInputError
import pytest


def _chunk(kind: bytes, data: bytes, crc=None) -> bytes:
    crc = zlib.crc32(kind + data) if crc is None else crc
    return struct.pack('>I', len(data)) + kind + data + struct.pack('>I', crc)


def png_bytes(w, h, depth=8, colour=0, rows=None, extra=b''):
    """Return a PNG declaring w x h; its data are ``rows`` (default: the whole image, zeros)."""
    ch = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    row = b'\x00' + bytes(w * ch * depth // 8)
    raw = row * (h if rows is None else rows)
    ihdr = struct.pack('>IIBBBBB', w, h, depth, colour, 0, 0, 0)
    return (
        b'\x89PNG\r\n\x1a\n'
        + _chunk(b'IHDR', ihdr)
        + extra
        + _chunk(b'IDAT', zlib.compress(raw))
        + _chunk(b'IEND', b'')
    )


def tiff_bytes(sizes, loop=False):
    """Return a little-endian TIFF whose pages declare ``sizes`` [(w, h)], 8-bit grey."""
    out = bytearray(b'II*\x00' + struct.pack('<I', 8))
    for i, (w, h) in enumerate(sizes):
        start = len(out)
        entries = [(256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, 8), (277, 3, 1, 1)]
        nxt = start + 2 + 12 * len(entries) + 4
        if i == len(sizes) - 1:
            nxt = 8 if loop else 0
        out += struct.pack('<H', len(entries))
        for tag, typ, count, value in entries:
            out += struct.pack('<HHII', tag, typ, count, value)
        out += struct.pack('<I', nxt)
    return bytes(out)


@pytest.fixture
def no_decoding(monkeypatch):
    """Make OpenCV's decoders fail the test: a hostile file is refused from its header."""

    def boom(*args, **kwargs):
        raise AssertionError('decoded before the header was checked')

    monkeypatch.setattr(cv2, 'imread', boom)
    monkeypatch.setattr(cv2, 'imreadmulti', boom)


@pytest.mark.parametrize(
    'name, data, words',
    [
        ('bomb.png', png_bytes(40000, 40000, rows=1), 'declares 40000 x 40000'),
        ('rgba16.png', png_bytes(4000, 4000, depth=16, colour=6, rows=1), 'has 4'),
        ('huge.tif', tiff_bytes([(100000, 100000)]), 'declares 100000 x 100000'),
        ('pages.tif', tiff_bytes([(64, 64)] * 400), 'more than 3 pages'),
        ('third.tif', tiff_bytes([(64, 64), (64, 64), (30000, 30000)]), 'page 2 declares'),
        ('loop.tif', tiff_bytes([(64, 64)] * 2, loop=True), 'loop'),
        ('cut.tif', tiff_bytes([(64, 64)])[:12], 'truncated'),
    ],
    ids=lambda v: v if isinstance(v, str) and v.endswith(('.png', '.tif')) else '',
)
def test_inputs_are_refused_from_their_header(tmp_path, no_decoding, name, data, words):
    p = tmp_path / name
    p.write_bytes(data)
    with pytest.raises(RealInputError, match=words):
        load_polarization_input(p)


@pytest.mark.parametrize(
    'name, data',
    [('bomb.png', png_bytes(40000, 40000, rows=1)), ('huge.tif', tiff_bytes([(10**5, 10**5)]))],
    ids=('bomb.png', 'huge.tif'),
)
def test_masks_are_refused_from_their_header(tmp_path, no_decoding, name, data):
    p = tmp_path / name
    p.write_bytes(data)
    with pytest.raises(RealInputError, match='refused before decoding'):
        load_mask(p, (64, 64))


def test_a_mask_reads_only_the_first_page_of_a_tiff(tmp_path):
    first = (np.arange(64 * 48).reshape(48, 64) % 3).astype(np.uint8)
    p = tmp_path / 'mask.tif'
    cv2.imwritemulti(str(p), [first] + [np.zeros((48, 64), np.uint8)] * 4)
    np.testing.assert_array_equal(load_mask(p, (48, 64)), first != 0)


@pytest.mark.parametrize('dtype', [np.float32, np.float64, np.uint16])
def test_stokes_tiffs_still_read_as_written(tmp_path, dtype):
    rng = np.random.default_rng(3)
    planes = [(rng.random((20, 30)) * 1000).astype(dtype) for _ in range(3)]
    p = tmp_path / 'stokes.tif'
    cv2.imwritemulti(str(p), planes)
    got = load_polarization_input(p)
    assert got.kind == 'stokes'
    for a, b in zip(got.stokes, planes):
        np.testing.assert_array_equal(a, b.astype(np.float32))


def test_timedelta_npy_is_a_user_error(tmp_path):
    p = tmp_path / 'td.npy'
    np.save(p, np.zeros((8, 8), dtype='timedelta64[s]'))
    with pytest.raises(RealInputError, match='integers or floats'):
        load_polarization_input(p)
    with pytest.raises(RealInputError, match='timedelta64'):
        load_mask(p, (8, 8))


def test_libpng_warnings_do_not_reach_the_terminal(tmp_path, capfd):
    p = tmp_path / 'warn.png'
    p.write_bytes(png_bytes(8, 8, extra=_chunk(b'tEXt', b'a\x00b', crc=1)))
    got = load_polarization_input(p)
    assert got.kind == 'mosaic' and got.mosaic.shape == (8, 8)
    assert 'libpng' not in capfd.readouterr().err


def test_estimate_on_a_huge_tiff_header_is_one_line_exit_2(tmp_path, capsys):
    p = tmp_path / 'huge.tif'
    p.write_bytes(tiff_bytes([(100000, 100000)]))
    code = main(['estimate', str(p), '--sun-azimuth', '100', '--sun-altitude', '40'])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count('\n') == 1 and 'refused before decoding' in err
