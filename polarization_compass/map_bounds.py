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
Bounds and integrity of the labelled-array map formats, checked before their data are read.

A Zarr sweep store is a directory of many files: every entry must be a regular file or a directory
(no symlink to ``/dev/zero``, no FIFO that would block a reader), and the shapes its metadata
declare must be those of its axes and within the ``.npz`` map's bounds
(:data:`~polarization_compass.errormap.MAX_MAP_CELLS`, ...) before a chunk is decoded. A NetCDF map
carries the digest of its content (:func:`map_digest`), as an ``.npz`` map carries the CRC32 of its
zip members, so a changed value is refused rather than used.
"""

from __future__ import annotations

import hashlib
import math
import os
from pathlib import Path
import stat

import numpy as np

from .errormap import (
    AXES,
    ErrorMapError,
    MAX_AXIS_NODES,
    MAX_MAP_CELLS,
    MAX_MAP_META_CHARS,
    MAX_MAP_METHODS,
)

__all__ = ['check_store_files', 'check_store_shapes', 'map_digest', 'MAX_STORE_BYTES']

#: Largest sum of file sizes in a sweep store (compressed chunks): 2 GiB.
MAX_STORE_BYTES = 2 << 30
#: Most entries (files and directories) in a sweep store.
MAX_STORE_ENTRIES = 1_000_000


def check_store_files(path) -> None:
    """
    Refuse a store that holds anything but regular files and directories, or too much.

    Symlinks are not followed but refused (one to ``/dev/zero`` reads without end), as are FIFOs
    (opening one blocks), devices and sockets; so are more than :data:`MAX_STORE_ENTRIES` entries
    or :data:`MAX_STORE_BYTES` in all.

    Parameters
    ----------
    path : str or os.PathLike
        The store's directory.

    Raises
    ------
    ErrorMapError
        Naming the first offending entry.

    """
    p = Path(path)
    entries, total = 0, 0
    for root, dirs, files in os.walk(p, followlinks=False, onerror=_walk_error(p)):
        for name in dirs + files:
            entry = Path(root) / name
            st = os.lstat(entry)
            entries += 1
            if stat.S_ISREG(st.st_mode):
                total += st.st_size
            elif not stat.S_ISDIR(st.st_mode):
                raise ErrorMapError(
                    f'{p}: {entry.relative_to(p)} is {_kind(st.st_mode)}, not a regular file; '
                    'a sweep store holds only regular files (refused before reading)'
                )
        if entries > MAX_STORE_ENTRIES or total > MAX_STORE_BYTES:
            raise ErrorMapError(
                f'{p}: more than {MAX_STORE_ENTRIES} files or {MAX_STORE_BYTES >> 30} GiB; '
                'not a sweep store of this package (refused before reading)'
            )


def _walk_error(p: Path):
    def raise_it(exc: OSError):
        raise ErrorMapError(f'{p}: cannot list the store ({exc.strerror or exc})')

    return raise_it


def _kind(mode: int) -> str:
    if stat.S_ISLNK(mode):
        return 'a symlink'
    if stat.S_ISFIFO(mode):
        return 'a FIFO'
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return 'a device'
    return 'a socket' if stat.S_ISSOCK(mode) else 'a special file'


def check_store_shapes(group, path, dims) -> None:
    """
    Check the shapes a store's metadata declare against its axes, before any chunk is read.

    The method and axis coordinates must be 1-D of at most :data:`MAX_MAP_METHODS` /
    :data:`MAX_AXIS_NODES` entries; ``error_deg`` and ``status`` exactly (methods, altitudes, yaws,
    pitches, rolls) with at most :data:`MAX_MAP_CELLS` cells, ``chunk_checksum`` (altitudes,
    pitches); no chunk larger than its array; ``meta_json`` at most :data:`MAX_MAP_META_CHARS`.

    Parameters
    ----------
    group : zarr.Group
        The open store (metadata only is read here).
    path : str or os.PathLike
        The store, for messages.
    dims : sequence of str
        The coordinate names: ``method`` then the four axes.

    Raises
    ------
    ErrorMapError
        Naming the array and the shape it declares.

    """
    lengths = []
    for name, limit in zip(dims, (MAX_MAP_METHODS,) + (MAX_AXIS_NODES,) * len(AXES)):
        shape = _declared(group, name, path)
        if len(shape) != 1 or shape[0] > limit:
            raise ErrorMapError(
                f'{path}: {name} must be 1-D with at most {limit} entries, declares {shape}'
            )
        lengths.append(shape[0])
    want = {'error_deg': tuple(lengths), 'status': tuple(lengths)}
    want['chunk_checksum'] = (lengths[1], lengths[3])
    for name, shape in want.items():
        got = _declared(group, name, path)
        if got != shape:
            raise ErrorMapError(
                f'{path}: {name} declares {got}, the axes and methods make {shape}'
            )
    cells = math.prod(lengths)
    if cells > MAX_MAP_CELLS:
        raise ErrorMapError(
            f'{path}: the map declares {cells} cells, more than {MAX_MAP_CELLS} (refused before '
            'reading)'
        )
    if len(str(group.attrs.get('meta_json', ''))) > MAX_MAP_META_CHARS:
        raise ErrorMapError(f'{path}: meta_json is longer than {MAX_MAP_META_CHARS} characters')


def _declared(group, name: str, path) -> tuple:
    """Return an array's declared shape; refuse a chunk larger than the array."""
    try:
        arr = group[name]
        shape, chunks = tuple(int(n) for n in arr.shape), tuple(int(n) for n in arr.chunks)
    except Exception as exc:  # noqa: BLE001 - zarr's errors for missing/bad metadata vary
        raise ErrorMapError(
            f'{path}: corrupt sweep store (array {name!r}: {type(exc).__name__}: {exc})'
        ) from None
    if len(chunks) != len(shape) or any(c > max(n, 1) for c, n in zip(chunks, shape)):
        raise ErrorMapError(f'{path}: {name} declares chunks {chunks} larger than its shape')
    return shape


def map_digest(err, status, methods, axes, meta_json: str) -> str:
    """
    Return the hex blake2b-128 digest of a map's content, as stored in a NetCDF map.

    Over the little-endian float64 errors, the int8 statuses, the method names, the four axes
    (float64) and the meta JSON text, each with its length, so no value can change unseen.

    Parameters
    ----------
    err : numpy.ndarray
        Errors [deg].
    status : numpy.ndarray
        Status codes.
    methods : sequence of str
        Method names.
    axes : sequence of numpy.ndarray
        Sun altitude, yaw, pitch and roll nodes [deg].
    meta_json : str
        The meta JSON text as stored.

    Returns
    -------
    str
        32 hex digits.

    """
    h = hashlib.blake2b(digest_size=16)
    parts = [
        np.ascontiguousarray(err, dtype='<f8').tobytes(),
        np.ascontiguousarray(status, dtype='i1').tobytes(),
        '\n'.join(methods).encode('utf-8'),
        *(np.ascontiguousarray(a, dtype='<f8').tobytes() for a in axes),
        meta_json.encode('utf-8'),
    ]
    for part in parts:
        h.update(len(part).to_bytes(8, 'little'))
        h.update(part)
    return h.hexdigest()
