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
Real camera images in: a raw DoFP mosaic or Stokes planes, as camera SDKs and drivers save them.

Accepted files (what :func:`load_polarization_input` returns as ``kind``):

``mosaic``  the raw division-of-focal-plane image: a single-page PNG or TIFF (8- or 16-bit grey,
            read with OpenCV unchanged), or a 2-D ``.npy`` (integer or float). 10/12-bit data in a
            16-bit container: give ``bits`` (saturation at ``2**bits - 1``; values above it are an
            error, e.g. MSB-aligned data that needs ``bits=16``).
``stokes``  Stokes planes ``S0, S1, S2`` in the camera SDK's convention (polarizer labels of the
            sensor, S1 = I0 - I90, S2 = I45 - I135): an ``.npz`` with arrays ``s0``, ``s1``, ``s2``
            or a multi-page TIFF with three pages in that order. Full sensor resolution or half
            (one value per 2 x 2 superpixel).
``frame``   this package's own frame ``.npz`` (``polarization-compass render``): read with
            :mod:`frame_io`.

Files are bounded before decoding: a regular file of at most 1 GiB, and for PNG/PGM/TIFF the size,
channels and page count their headers declare (:mod:`~polarization_compass.image_header`; at most
:data:`MAX_PIXELS` per plane, one grey channel, 3 pages) -- OpenCV decodes a whole file, every
page, before anything can be checked. What the native decoders print (libpng, libtiff) is kept off
the terminal and folded into the error. Errors raise :class:`RealInputError` with a one-line
reason.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import os
from pathlib import Path
import sys

import numpy as np

from .errors import CompassError

__all__ = [
    'RealInputError',
    'PolarizationInput',
    'load_polarization_input',
    'load_mask',
    'MAX_PIXELS',
]

#: largest plane accepted (pixels): a 24 Mpixel sensor
MAX_PIXELS = 24_000_000
_MAX_FILE_BYTES = 1 << 30


class RealInputError(CompassError):
    """A real image that cannot be read or does not fit what was asked."""


@dataclass(frozen=True)
class PolarizationInput:
    """
    A real polarization input: a raw mosaic, Stokes planes or a frame.

    ``kind`` mosaic | stokes | frame; ``mosaic`` 2-D array; ``stokes`` (S0, S1, S2) float32 planes;
    ``saturation_level`` the raw value that counts as saturated (mosaic), ``path`` the file.
    """

    kind: str
    path: str
    mosaic: np.ndarray | None = None
    stokes: tuple | None = None
    saturation_level: float | None = None


def _check_size(p: Path) -> None:
    from .safe_load import regular_file

    regular_file(
        p, RealInputError, 'input', max_bytes=_MAX_FILE_BYTES
    )  # no FIFO or device, at most 1 GiB


def _check_plane(a: np.ndarray, what: str, p: Path) -> np.ndarray:
    if a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 2:
        raise RealInputError(
            f'{p}: {what} must be a 2-D image of at least 2 x 2, got shape {a.shape}'
        )
    if a.size > MAX_PIXELS:
        raise RealInputError(
            f'{p}: {what} has {a.size} pixels, more than the {MAX_PIXELS} accepted'
        )
    if a.dtype.kind not in 'iuf':  # not bool, timedelta64 (an integer subtype), ...
        raise RealInputError(f'{p}: {what} must hold integers or floats, got {a.dtype}')
    return a


def _saturation(m: np.ndarray, bits: int | None, p: Path) -> float | None:
    if bits is not None:
        if not (1 <= int(bits) <= 16):
            raise RealInputError(f'--bits must be in [1, 16], got {bits}')
        if not np.issubdtype(m.dtype, np.integer):
            raise RealInputError(f'{p}: --bits applies to integer images, this one is {m.dtype}')
        sat = float((1 << int(bits)) - 1)
        top = int(m.max())
        if top > sat:
            raise RealInputError(
                f'{p}: values up to {top} exceed {bits}-bit data (max {int(sat)}); '
                'MSB-aligned data needs --bits 16'
            )
        return sat
    if np.issubdtype(m.dtype, np.integer):
        return float(np.iinfo(m.dtype).max)
    return None


def _check_header(p: Path, max_pages: int, first_only: bool = False) -> int:
    """
    Check the pages a PNG/PGM/TIFF declares before anything is decoded; return their count.

    At most ``max_pages`` pages (``first_only``: only the first is looked at and read) of one grey
    channel and :data:`MAX_PIXELS` each (a file of a few MB can declare gigabytes, and OpenCV
    decodes every page before returning).
    """
    from .image_header import ImageHeaderError, read_image_pages

    try:
        pages, more = read_image_pages(p, max_pages)
    except (ImageHeaderError, OSError) as exc:
        raise RealInputError(f'{p}: not a readable PNG/PGM/TIFF image ({exc})') from None
    if first_only:
        pages = pages[:1]
    elif more:
        raise RealInputError(
            f'{p}: more than {max_pages} pages; a raw mosaic has 1, Stokes planes have 3 '
            '(S0, S1, S2) (refused before decoding)'
        )
    for i, page in enumerate(pages):
        if page.pixels > MAX_PIXELS:
            raise RealInputError(
                f'{p}: page {i} declares {page.width_px} x {page.height_px} pixels, more than the '
                f'{MAX_PIXELS} accepted (refused before decoding)'
            )
        if page.channels != 1:
            raise RealInputError(
                f'{p}: a raw mosaic or Stokes plane is one grey channel, this image has '
                f'{page.channels} (save the raw mono8/mono16 data, not a colour rendering)'
            )
    return len(pages)


@contextmanager
def _native_stderr_folded(p: Path):
    """
    Keep what the native decoders print (libpng, libtiff warnings) off the terminal.

    File descriptor 2 is redirected to a temporary file while OpenCV decodes; on a failed decode
    its first line is folded into the one-line error (:class:`RealInputError`).
    """
    import tempfile

    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        except RealInputError as exc:
            os.dup2(saved, 2)
            sink.seek(0)
            said = sink.read(400).decode('utf-8', 'replace').strip().splitlines()
            raise RealInputError(f'{exc}: {said[0]}' if said else str(exc)) from None
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def _read_images(p: Path, first_only: bool = False) -> list:
    import cv2

    n = _check_header(p, 3, first_only)
    with _native_stderr_folded(p):
        try:
            if n > 1:
                ok, pages = cv2.imreadmulti(str(p), flags=cv2.IMREAD_UNCHANGED)
            else:
                img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
                ok, pages = img is not None, [img]
        except cv2.error as exc:
            raise RealInputError(f'{p}: OpenCV cannot decode this image ({_first(exc)})') from None
        if not ok or not pages or any(img is None for img in pages):
            raise RealInputError(f'{p}: OpenCV cannot decode this image')
    out = []
    for img in pages:
        if img.ndim == 3:
            raise RealInputError(
                f'{p}: a raw mosaic or Stokes plane is one grey channel, this image has '
                f'{img.shape[2]} (save the raw mono8/mono16 data, not a colour rendering)'
            )
        out.append(img)
    return out


def _first(exc: Exception) -> str:
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    return lines[-1][:160] if lines else type(exc).__name__


def load_polarization_input(path, bits: int | None = None) -> PolarizationInput:
    """
    Read a raw mosaic, Stokes planes or a frame file.

    The kind is decided by the suffix and content (module docstring): ``.npz`` with ``s0``, ``s1``,
    ``s2`` (Stokes) or ``aop_rad`` and ``meta`` (this package's frame file, read later with
    :mod:`frame_io`); ``.npy`` (mosaic); ``.png``/``.tif``/``.tiff``/``.pgm`` with one page
    (mosaic) or three (Stokes, read with OpenCV unchanged). The file's size and, for images, the
    pixels, channels and pages its header declares are checked before it is decoded.

    Parameters
    ----------
    path : str or os.PathLike
        The input file.
    bits : int, optional
        Significant bits of an integer mosaic in [1, 16]; saturation at ``2**bits - 1``. Default:
        the maximum of the integer type (no saturation level for float data).

    Returns
    -------
    PolarizationInput
        ``kind`` ``"mosaic"`` (the 2-D raw array and its saturation level in counts), ``"stokes"``
        (float32 planes S0, S1, S2 in the camera SDK's convention) or ``"frame"`` (path only).

    Raises
    ------
    RealInputError
        When the file is missing, not a regular file, too large, undecodable, of an unknown type, a
        colour image, not a 2-D integer/float plane of at least 2 x 2 and at most
        :data:`MAX_PIXELS`, has Stokes planes of different shapes or with NaN/inf, has a page count
        other than 1 or 3, or has values above ``2**bits - 1`` (or ``bits`` is out of range or
        given for float data).

    """
    p = Path(path)
    _check_size(p)
    suf = p.suffix.lower()
    if suf == '.npz':
        from .safe_load import open_npz

        with open_npz(p, RealInputError, 'input') as z:
            names = set(z.files)
            if {'aop_rad', 'meta'} <= names:
                return PolarizationInput('frame', str(p))
            if not {'s0', 's1', 's2'} <= names:
                raise RealInputError(
                    f'{p}: an .npz input holds s0, s1, s2 (Stokes planes) or is a frame file '
                    f"from 'render'; found {sorted(names)[:6]}"
                )
            planes = [_check_plane(np.asarray(z[k]), k, p) for k in ('s0', 's1', 's2')]
        return _stokes(planes, p)
    if suf == '.npy':
        try:
            a = np.load(p, allow_pickle=False, mmap_mode='r')
        except (ValueError, OSError, EOFError) as exc:
            raise RealInputError(
                f'{p}: not a readable .npy array ({str(exc).splitlines()[0]})'
            ) from None
        m = np.ascontiguousarray(_check_plane(a, 'the mosaic', p))
        return PolarizationInput(
            'mosaic', str(p), mosaic=m, saturation_level=_saturation(m, bits, p)
        )
    if suf in ('.png', '.tif', '.tiff', '.pgm'):
        pages = _read_images(p)
        if len(pages) == 3:
            return _stokes([_check_plane(a, f'page {i}', p) for i, a in enumerate(pages)], p)
        if len(pages) != 1:
            raise RealInputError(
                f'{p}: {len(pages)} pages; a raw mosaic has 1, Stokes planes have 3 (S0, S1, S2)'
            )
        m = _check_plane(pages[0], 'the mosaic', p)
        return PolarizationInput(
            'mosaic', str(p), mosaic=m, saturation_level=_saturation(m, bits, p)
        )
    raise RealInputError(
        f'{p}: unknown input type {suf or "(no suffix)"!r}; use .png/.tif (raw mosaic or 3-page '
        'Stokes), .npy (raw mosaic), .npz (s0/s1/s2 or a frame file)'
    )


def _stokes(planes, p: Path) -> PolarizationInput:
    if not (planes[0].shape == planes[1].shape == planes[2].shape):
        raise RealInputError(f'{p}: S0, S1, S2 differ in shape: {[a.shape for a in planes]}')
    out = []
    for a in planes:
        f = a.astype(np.float32)
        if not np.all(np.isfinite(f)):
            raise RealInputError(f'{p}: Stokes planes hold NaN or inf')
        out.append(f)
    return PolarizationInput('stokes', str(p), stokes=tuple(out))


def load_mask(path, shape, sensor_shape=None) -> np.ndarray:
    """
    Read a static obstruction mask: True (use) where non-zero.

    A grey PNG/TIFF (first page, read with OpenCV unchanged) or a 2-D ``.npy``; zero marks
    obstructed pixels (mast, antenna, the robot), as in OpenCV's mask convention.

    Parameters
    ----------
    path : str or os.PathLike
        The mask file.
    shape : tuple of int
        ``(rows, cols)`` of the input image the mask applies to [pixels].
    sensor_shape : tuple of int, optional
        ``(rows, cols)`` of the full sensor, also accepted for half-resolution Stokes planes.

    Returns
    -------
    numpy.ndarray of bool
        True where the sky is usable, of the mask file's own shape (``shape`` or
        ``sensor_shape``).

    Raises
    ------
    RealInputError
        When the file cannot be read or decoded, is a colour image, or matches neither ``shape``
        nor ``sensor_shape``.

    """
    p = Path(path)
    _check_size(p)
    if p.suffix.lower() == '.npy':
        try:
            a = np.load(p, allow_pickle=False, mmap_mode='r')  # shape known, nothing read
        except (ValueError, OSError, EOFError) as exc:
            raise RealInputError(
                f'{p}: not a readable .npy mask ({str(exc).splitlines()[0]})'
            ) from None
        if a.dtype.kind not in 'biuf':
            raise RealInputError(f'{p}: a mask holds bool, integer or float values, not {a.dtype}')
    else:
        a = _read_images(p, first_only=True)[0]
    a = np.asarray(a)
    if a.shape != tuple(shape) and (sensor_shape is None or a.shape != tuple(sensor_shape)):
        raise RealInputError(
            f'--mask {p.name}: shape {a.shape} does not match the input image {tuple(shape)}'
        )
    return a != 0
