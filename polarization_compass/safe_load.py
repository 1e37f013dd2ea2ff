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
Loading files without executing them, with bounded memory, and with one-line errors.

Everything the package reads from disk goes through here: ``.npz`` archives (numpy, never pickle),
YAML (``yaml.safe_load`` only), JSON and text (UTF-8). Each function takes the error class of its
caller (a :class:`~polarization_compass.errors.CompassError`), so a bad file is a user error with a
short message, never a traceback, a leaked file handle or an ``internal error``.

Bounds (hostile or broken files must not take the machine's memory): only regular files are read (a
FIFO, a device such as a symlink to ``/dev/zero``, a socket or a directory is refused before it is
opened); text files are read up to ``max_bytes`` (:data:`MAX_TEXT_BYTES` by default); an ``.npz``
archive is refused when its file is larger than ``max_file_bytes`` or when the shapes its ``.npy``
headers *declare* exceed ``max_total_bytes`` or the caller's context check -- all before any array
is decompressed (a zip of a few MB can declare tens of GB of zeros). Nesting deep enough to exhaust
Python's recursion (YAML or JSON) and a ``MemoryError`` while parsing are user errors too.
"""

from __future__ import annotations

from contextlib import contextmanager
import json
import math
import os
from pathlib import Path
import stat
import zipfile

import numpy as np
import yaml

from .errors import CompassError

__all__ = [
    'open_npz',
    'read_text',
    'load_yaml',
    'load_json',
    'yaml_problem',
    'npz_headers',
    'NpyHeader',
    'MAX_TEXT_BYTES',
    'MAX_NPZ_FILE_BYTES',
    'MAX_NPZ_TOTAL_BYTES',
    'regular_file',
]

#: Largest text file read (scenes, topic maps): 1 MiB, about a thousand times a real scene.
MAX_TEXT_BYTES = 1 << 20
#: Largest ``.npz`` file opened (on disk): 1 GiB.
MAX_NPZ_FILE_BYTES = 1 << 30
#: Largest total size the arrays of one ``.npz`` may declare (decompressed): 2 GiB.
MAX_NPZ_TOTAL_BYTES = 2 << 30


def _size_text(n: int) -> str:
    for unit, k in (('GB', 1e9), ('MB', 1e6), ('kB', 1e3)):
        if n >= k:
            return f'{n / k:.3g} {unit}'
    return f'{n} bytes'


def regular_file(path, error=CompassError, what='file', max_bytes: int | None = None) -> Path:
    """
    Return ``path`` as a Path when it is a regular file (symlinks followed) of bounded size.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    error : type, default CompassError
        Exception class raised on failure.
    what : str, default "file"
        What the file is, for the message.
    max_bytes : int, optional
        Largest size [bytes]; None: any.

    Returns
    -------
    pathlib.Path
        The path.

    Raises
    ------
    error
        It does not exist, is a directory, is a special file (FIFO, character or block device such
        as ``/dev/zero``, socket: reading one could block or never end) or is too large.

    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise error(f'{what} {str(p)!r} does not exist') from None
    except (OSError, ValueError) as exc:  # a loop of symlinks, a name too long, a NUL byte ...
        raise error(
            f'{what} {str(p)!r} cannot be read: {getattr(exc, "strerror", None) or exc}'
        ) from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f'{what} {str(p)!r} is a directory')
    if not stat.S_ISREG(st.st_mode):
        kind = (
            'a FIFO'
            if stat.S_ISFIFO(st.st_mode)
            else 'a device'
            if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
            else 'a socket'
            if stat.S_ISSOCK(st.st_mode)
            else 'a special file'
        )
        raise error(f'{what} {str(p)!r} is {kind}, not a regular file; refused')
    if max_bytes is not None and st.st_size > max_bytes:
        raise error(
            f'{what} {str(p)!r} is {_size_text(st.st_size)}, more than the '
            f'{_size_text(max_bytes)} '
            f'a {what} may have; is it the right file?'
        )
    return p


def read_text(path, error=CompassError, what='file', max_bytes: int = MAX_TEXT_BYTES) -> str:
    """
    Return the UTF-8 text of ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        File to read.
    error : type, default CompassError
        Exception class raised on failure (the caller's :class:`CompassError` subclass).
    what : str, default "file"
        What the file is, for the message (e.g. ``"scene file"``).
    max_bytes : int, default MAX_TEXT_BYTES
        Largest size read [bytes].

    Returns
    -------
    str
        The decoded text.

    Raises
    ------
    error
        The file is missing, a directory, a special file (FIFO, device), larger than ``max_bytes``,
        unreadable, or not UTF-8 text (one-line message).

    """
    p = regular_file(path, error, what, max_bytes)
    try:
        with open(p, 'rb') as fh:
            data = fh.read(max_bytes + 1)  # the file may have grown since the stat
    except OSError as exc:
        raise error(f'{what} {str(p)!r} cannot be read: {exc.strerror}') from None
    if len(data) > max_bytes:
        raise error(
            f'{what} {str(p)!r} is more than {_size_text(max_bytes)}; is it the right file?'
        )
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise error(
            f'{what} {str(p)!r} is not UTF-8 text (byte {exc.start}); is it the right file?'
        ) from None


def yaml_problem(exc: yaml.YAMLError) -> str:
    """
    Return one line from a YAML error: the problem and where it is, without the source excerpt.

    Parameters
    ----------
    exc : yaml.YAMLError
        The parser's error.

    Returns
    -------
    str
        E.g. ``"found unexpected end of stream at line 3, column 1"`` (line and column 1-based,
        when the error has a mark).

    """
    problem = getattr(exc, 'problem', None) or str(exc).splitlines()[0]
    mark = getattr(exc, 'problem_mark', None)
    where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark is not None else ''
    return f'{" ".join(str(problem).split())}{where}'


def load_yaml(text: str, where: str, error=CompassError):
    """
    Parse YAML text with ``yaml.safe_load``; tags such as ``!!python/object`` are refused.

    Parameters
    ----------
    text : str
        The YAML document.
    where : str
        Where it came from (a path or a parameter name), the prefix of the error message.
    error : type, default CompassError
        Exception class raised on failure.

    Returns
    -------
    object
        The parsed document (dict, list, scalar or None); nothing is executed.

    Raises
    ------
    error
        The text is not valid YAML for the safe loader (message with line and column), a value
        the safe constructors refuse (``2023-02-30`` read as a date), nesting too deep for Python's
        recursion limit, or a MemoryError while parsing.

    """
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise error(f'{where}: not valid YAML (safe loader): {yaml_problem(exc)}') from None
    except RecursionError:
        raise error(f'{where}: YAML nested too deeply to read') from None
    except MemoryError:
        raise error(f'{where}: YAML too large to read') from None
    except (ValueError, TypeError, OverflowError) as exc:  # e.g. datetime.date(2023, 2, 30)
        raise error(f'{where}: not valid YAML (safe loader): {_short(exc)}') from None


def load_json(text: str, where: str, error=CompassError):
    """
    Parse JSON text with every failure as a one-line user error.

    NaN/Infinity literals are refused too (no NaN reaches an output).

    Parameters
    ----------
    text : str
        The JSON document.
    where : str
        Where it came from, the prefix of the message.
    error : type, default CompassError
        Exception class raised on failure.

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    error
        Invalid JSON, nesting too deep for the recursion limit, or a MemoryError while parsing.

    """

    def _no_constant(name):
        raise ValueError(f'{name} is not a JSON number')

    try:
        return json.loads(text, parse_constant=_no_constant)
    except RecursionError:
        raise error(f'{where}: JSON nested too deeply to read') from None
    except MemoryError:
        raise error(f'{where}: JSON too large to read') from None
    except (ValueError, TypeError) as exc:
        raise error(f'{where}: not valid JSON ({_short(exc)})') from None


class NpyHeader:
    """
    What an ``.npy`` member of an archive declares, read from its header before its data.

    Attributes: ``shape``, ``dtype`` and ``nbytes`` (Python int, no overflow).
    """

    __slots__ = ('shape', 'dtype', 'nbytes')

    def __init__(self, shape, dtype):
        self.shape = tuple(int(n) for n in shape)
        self.dtype = dtype
        self.nbytes = math.prod(self.shape) * int(dtype.itemsize)

    def __repr__(self):
        return f'NpyHeader({self.shape}, {self.dtype})'


def npz_headers(z, error=CompassError, name: str = 'archive') -> dict:
    """
    Read the ``.npy`` headers of an open archive's members (a few hundred bytes each).

    numpy's ``max_header_size`` applies; object dtypes are refused here (they would need pickle).

    Parameters
    ----------
    z : numpy.lib.npyio.NpzFile
        The open archive.
    error : type, default CompassError
        Exception class raised on failure.
    name : str, default "archive"
        The archive's name, for the message.

    Returns
    -------
    dict
        ``{array name: NpyHeader}``.

    Raises
    ------
    error
        A member that is not a readable ``.npy`` header, or an object array.

    """
    fmt = np.lib.format
    out = {}
    for info in z.zip.infolist():
        if not info.filename.endswith('.npy'):
            continue
        key = info.filename[:-4]
        try:
            with z.zip.open(info) as f:
                version = fmt.read_magic(f)
                if version == (1, 0):
                    shape, _, dtype = fmt.read_array_header_1_0(f)
                elif version == (2, 0):
                    shape, _, dtype = fmt.read_array_header_2_0(f)
                else:
                    raise ValueError(f'.npy format version {version} is not supported')
        except (
            ValueError,
            OSError,
            EOFError,
            zipfile.BadZipFile,
            RecursionError,
            MemoryError,
        ) as exc:
            raise error(
                f'{name}: corrupt .npz: member {key!r} is not a readable .npy array '
                f'({_short(exc)})'
            ) from None
        if dtype.hasobject:
            raise error(
                f'{name}: contains object arrays ({key!r}); refused (loading never unpickles)'
            )
        out[key] = NpyHeader(shape, dtype)
    return out


@contextmanager
def open_npz(
    path,
    error=CompassError,
    what='file',
    check=None,
    max_file_bytes: int = MAX_NPZ_FILE_BYTES,
    max_total_bytes: int = MAX_NPZ_TOTAL_BYTES,
):
    """
    Open a ``.npz`` archive with ``allow_pickle=False``; close it on every path.

    A missing file, a directory, a ``.npy`` saved under an ``.npz`` name, a corrupt or truncated
    zip: all raise ``error`` with the reason. Object arrays raise when read (pickle disabled),
    reported the same way, as do corrupt members read inside the ``with`` body. Bounded: a special
    file or one over ``max_file_bytes`` is refused, and before the archive is yielded the ``.npy``
    headers of its members are read (:func:`npz_headers`): arrays declaring more than
    ``max_total_bytes`` in all, or object arrays, are refused, and ``check(headers)`` (the caller's
    context: which shapes the file may hold) may raise ``error`` too -- nothing is decompressed
    before.

    Parameters
    ----------
    path : str or os.PathLike
        The archive.
    error : type, default CompassError
        Exception class raised on failure.
    what : str, default "file"
        What the archive is, for the message (e.g. ``"error map"``).
    check : callable, optional
        ``check(headers)`` with ``{name: NpyHeader}``; raises ``error`` for shapes the context
        refuses.
    max_file_bytes : int, default MAX_NPZ_FILE_BYTES
        Largest file size [bytes].
    max_total_bytes : int, default MAX_NPZ_TOTAL_BYTES
        Largest total size [bytes] the arrays may declare (decompressed).

    Yields
    ------
    numpy.lib.npyio.NpzFile
        The open archive (arrays are read lazily by key).

    Raises
    ------
    error
        The file is missing, a directory, unreadable, not an ``.npz`` archive, corrupt, or holds
        object arrays.

    """
    p = regular_file(path, error, what, max_file_bytes)
    try:
        fh = open(p, 'rb')
    except OSError as exc:
        raise error(f'{what} {str(p)!r} cannot be read: {exc.strerror}') from None
    with fh:
        try:
            z = np.load(fh, allow_pickle=False)
        except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
            raise error(
                f'{p.name}: corrupt or not a readable .npz {what} ({_short(exc)})'
            ) from None
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise error(f'{p.name}: not an .npz archive (a single .npy array?); expected a {what}')
        with z:
            headers = npz_headers(z, error, p.name)
            total = sum(h.nbytes for h in headers.values())
            if total > max_total_bytes:
                big = max(headers, key=lambda k: headers[k].nbytes)
                raise error(
                    f'{p.name}: its arrays declare {_size_text(total)} (the largest, {big!r}, '
                    'shape '
                    f'{headers[big].shape}), more than the {_size_text(max_total_bytes)} a {what} '
                    'may '
                    'hold; refused before decompressing'
                )
            if check is not None:
                check(headers)
            try:
                yield z
            except (zipfile.BadZipFile, EOFError, OSError) as exc:
                raise error(f'{p.name}: corrupt .npz {what} ({_short(exc)})') from None
            except ValueError as exc:
                if 'pickle' in str(exc):
                    raise error(
                        f'{p.name}: contains object arrays; refused (loading never unpickles)'
                    ) from None
                raise error(f'{p.name}: unreadable array in the {what} ({_short(exc)})') from None


def _short(exc: Exception) -> str:
    s = ' '.join(str(exc).split())
    return s if len(s) <= 160 else s[:157] + '...'
