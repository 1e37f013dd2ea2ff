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
What an image file declares (size, channels, pages), read from its header before any decoding.

OpenCV decodes a whole file (every page of a TIFF) before its size can be checked: a PNG of a few
MB can declare gigabytes of pixels. These readers look only at the header: TIFF image file
directories are walked (classic and BigTIFF, at most ``max_pages`` of them, loops refused), and
the PNG ``IHDR`` chunk and the binary PGM text header are read as their specifications lay them
out: a few dozen bytes, nothing decoded.
"""

from __future__ import annotations

from dataclasses import dataclass
import struct

__all__ = ['PageHeader', 'read_image_pages', 'ImageHeaderError']

_PNG_MAGIC = b'\x89PNG'
#: PNG colour type -> channels OpenCV decodes (a palette is expanded to BGR).
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}
_TIFF_MAGIC = (b'II*\x00', b'MM\x00*', b'II+\x00', b'MM\x00+')
#: TIFF tags: ImageWidth, ImageLength, BitsPerSample, SamplesPerPixel.
_WIDTH, _LENGTH, _BITS, _SAMPLES = 256, 257, 258, 277
#: TIFF field type -> (struct code, size in bytes) of the integer types a size tag may use.
_INT_TYPES = {1: ('B', 1), 3: ('H', 2), 4: ('I', 4), 16: ('Q', 8)}


class ImageHeaderError(ValueError):
    """A header that cannot be read (truncated, looping, not the format its magic says)."""


@dataclass(frozen=True)
class PageHeader:
    """
    One page as its header declares it.

    ``width_px`` and ``height_px`` [pixels], ``channels`` (samples per pixel) and
    ``bits_per_sample``; ``pixels`` is their product of width and height.
    """

    width_px: int
    height_px: int
    channels: int
    bits_per_sample: int

    @property
    def pixels(self) -> int:
        """Return width x height [pixels]."""
        return self.width_px * self.height_px


def read_image_pages(path, max_pages: int) -> tuple[list[PageHeader], bool]:
    """
    Read the declared size of the first pages of a PNG, binary PGM or TIFF without decoding them.

    Parameters
    ----------
    path : str or os.PathLike
        The image file (a regular file: the caller checks).
    max_pages : int
        Pages read at most; a file with more has ``more`` set.

    Returns
    -------
    pages : list of PageHeader
        The first ``max_pages`` pages (one for PNG and PGM).
    more : bool
        True when the file has more than ``max_pages`` pages.

    Raises
    ------
    ImageHeaderError
        The header is unreadable, truncated or loops, or the format is not PNG, PGM or TIFF.

    """
    with open(path, 'rb') as fh:
        magic = fh.read(4)
        if magic in _TIFF_MAGIC:
            return _tiff_pages(fh, magic, max_pages)
        if magic == _PNG_MAGIC:
            return [_png_page(fh)], False
        if magic[:2] in (b'P2', b'P3', b'P5', b'P6') and magic[2:3].isspace():
            return [_pnm_page(fh, magic)], False
    raise ImageHeaderError('not a PNG, binary PGM or TIFF file')


def _png_page(fh) -> PageHeader:
    """Read the IHDR chunk, which the PNG specification puts first."""
    _read(fh, 4)  # the rest of the 8-byte signature
    length, kind = struct.unpack('>I4s', _read(fh, 8))
    if kind != b'IHDR' or length != 13:
        raise ImageHeaderError('a PNG whose first chunk is not IHDR')
    w, h, depth, colour = struct.unpack('>IIBB', _read(fh, 10))
    if colour not in _PNG_CHANNELS:
        raise ImageHeaderError(f'a PNG of unknown colour type {colour}')
    return PageHeader(w, h, _PNG_CHANNELS[colour], depth)


def _pnm_page(fh, magic: bytes) -> PageHeader:
    """Read the text header of a PGM/PPM (binary or plain): magic, width, height, maximum."""
    head = magic + fh.read(252)
    fields = []
    for line in head.split(b'\n'):
        fields += line.split(b'#')[0].split()
        if len(fields) >= 4:
            break
    try:
        w, h, top = (int(x) for x in fields[1:4])
    except ValueError:
        raise ImageHeaderError('an unreadable PGM header') from None
    return PageHeader(w, h, 1 if magic[:2] in (b'P2', b'P5') else 3, 16 if top > 255 else 8)


def _tiff_pages(fh, magic: bytes, max_pages: int):
    order = '<' if magic[:2] == b'II' else '>'
    big = magic[2:] in (b'+\x00', b'\x00+')
    if big:
        _, _, offset = struct.unpack(order + 'HHQ', _read(fh, 12))
    else:
        (offset,) = struct.unpack(order + 'I', _read(fh, 4))
    pages, seen = [], set()
    while offset and len(pages) <= max_pages:
        if offset in seen:
            raise ImageHeaderError('TIFF image directories form a loop')
        seen.add(offset)
        fh.seek(offset)
        tags, offset = _tiff_ifd(fh, order, big)
        if _WIDTH not in tags or _LENGTH not in tags:
            raise ImageHeaderError('a TIFF page without width or height')
        pages.append(
            PageHeader(tags[_WIDTH], tags[_LENGTH], tags.get(_SAMPLES, 1), tags.get(_BITS, 1))
        )
    if not pages:
        raise ImageHeaderError('a TIFF without pages')
    return pages[:max_pages], len(pages) > max_pages


def _tiff_ifd(fh, order: str, big: bool):
    """Return ({tag: first integer value} of the size tags, next directory offset)."""
    count_fmt, entry_size, off_fmt = ('Q', 20, 'Q') if big else ('H', 12, 'I')
    (n,) = struct.unpack(order + count_fmt, _read(fh, struct.calcsize(count_fmt)))
    if n > 4096:
        raise ImageHeaderError(f'a TIFF directory with {n} entries')
    raw = _read(fh, n * entry_size)
    (next_offset,) = struct.unpack(order + off_fmt, _read(fh, struct.calcsize(off_fmt)))
    tags = {}
    for i in range(n):
        e = raw[i * entry_size : (i + 1) * entry_size]
        tag, typ = struct.unpack(order + 'HH', e[:4])
        (count,) = struct.unpack(order + ('Q' if big else 'I'), e[4:12] if big else e[4:8])
        value = e[12:] if big else e[8:]
        if tag in (_WIDTH, _LENGTH, _BITS, _SAMPLES) and typ in _INT_TYPES:
            code, size = _INT_TYPES[typ]
            if count * size <= len(value):  # else the field holds an offset (per-sample bits)
                tags[tag] = struct.unpack(order + code, value[:size])[0]
    return tags, next_offset


def _read(fh, n: int) -> bytes:
    data = fh.read(n)
    if len(data) != n:
        raise ImageHeaderError('truncated header')
    return data
