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
The Zarr store a sweep writes into, chunk by checksummed chunk, and its reader.

A sweep writes into a :class:`SweepStore`, a Zarr (format 3) directory holding that Dataset plus
the bookkeeping variable ``chunk_checksum`` (sun_altitude, pitch), uint64. The Zarr chunks of
``error_deg`` and ``status`` are exactly the sweep's chunks (one sun altitude x one pitch, every
method, yaw and roll), so each finished chunk writes its own region, then its checksum (blake2b of
the region's bytes); 0 means "not written". Reopening the store with the same sweep (same
:meth:`SweepSpec.digest`) resumes: a chunk counts as done only when its stored bytes hash to its
checksum; a chunk that does not (a kill between the two writes, a damaged file) is named on stderr
and recomputed, never used. A directory that is not such a store (another program's Zarr, another
sweep, unreadable metadata) is refused with :class:`ErrorMapError`.

Reading a store is bounded (:mod:`~polarization_compass.map_bounds`): regular files only, shapes
declared by the metadata checked against the axes before any chunk is decoded. The Dataset is
:mod:`polarization_compass.errormap_dataset`'s; the NetCDF export
:mod:`polarization_compass.errormap_netcdf`.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
import shutil
import sys

import numpy as np

from .errormap import AXES, ErrorMap, ErrorMapError
from .errormap_dataset import _attrs_from_meta, _AXIS_DIM, _coords, DIMS, require_sweep_extra
from .map_bounds import check_store_files, check_store_shapes
from .safe_load import load_json

__all__ = [
    'SweepStore',
    'read_store_map',
    'chunk_checksum',
    'STORE_KIND',
    'STORE_FORMAT_VERSION',
]

STORE_KIND = 'polarization_compass.errormap.sweep'
STORE_FORMAT_VERSION = 1


def chunk_checksum(err: np.ndarray, status: np.ndarray) -> int:
    """
    Return the uint64 checksum of one chunk's errors and statuses.

    blake2b with an 8-byte digest over the little-endian float64 errors then the int8 statuses, in
    C order; a digest of 0 is replaced by 1, so 0 can mean "not written".

    Parameters
    ----------
    err : numpy.ndarray
        The chunk's errors [deg] (converted to float64).
    status : numpy.ndarray
        The chunk's status codes (converted to int8).

    Returns
    -------
    int
        The checksum, in [1, 2**64 - 1].

    """
    h = hashlib.blake2b(digest_size=8)
    h.update(np.ascontiguousarray(err, dtype='<f8').tobytes())
    h.update(np.ascontiguousarray(status, dtype='i1').tobytes())
    return int.from_bytes(h.digest(), 'little') or 1


class SweepStore:
    """The Zarr store of one sweep (see the module docstring). Open with :meth:`open`."""

    def __init__(self, path: Path, group, spec):
        self.path = path
        self.group = group
        self.spec = spec

    # ---- opening -----------------------------------------------------------------------
    @classmethod
    def open(  # noqa: A003 - the store's constructor, named like the files it opens
        cls, path, spec, restart: bool = False
    ) -> 'SweepStore':
        """
        Create the store for ``spec`` at ``path``, or reopen it to resume.

        An existing store is reopened only when it carries this package's marker and format
        version, the same sweep digest (:meth:`SweepSpec.digest`) and arrays of the right shapes
        and types.

        Parameters
        ----------
        path : str or os.PathLike
            The Zarr directory.
        spec : SweepSpec
            The sweep the store holds.
        restart : bool, default False
            Delete an earlier store *of this package* (of any sweep) first and create a new one; a
            foreign directory is never deleted.

        Returns
        -------
        SweepStore
            The open store.

        Raises
        ------
        ErrorMapError
            When xarray/zarr are missing, or ``path`` is a file, an unreadable or foreign Zarr
            store, a store of another format version or (without ``restart``) another sweep, or a
            corrupt store.

        """
        _, zarr = require_sweep_extra('a sweep store')
        p = Path(path)
        if p.exists():
            group = cls._check_existing(p, spec, zarr, allow_other_sweep=restart)
            if not restart:
                return cls(p, group, spec)
            shutil.rmtree(p)
        cls._create(p, spec)
        return cls(p, zarr.open_group(str(p), mode='r+'), spec)

    @staticmethod
    def _check_existing(p: Path, spec, zarr, allow_other_sweep: bool = False):
        if not p.is_dir():
            raise ErrorMapError(f'{p} exists and is not a directory: not an error-map sweep store')
        check_store_files(p)  # no FIFO, device or symlink: reading one could block or never end
        try:
            group = zarr.open_group(str(p), mode='r+')
            attrs = dict(group.attrs)
        # zarr's errors for an unreadable group vary by cause
        except Exception as exc:  # noqa: BLE001
            raise ErrorMapError(
                f'{p}: not a readable Zarr store ({type(exc).__name__}: {exc}); '
                f'delete it or choose another --out'
            ) from None
        if attrs.get('store_kind') != STORE_KIND:
            raise ErrorMapError(
                f"{p} is a Zarr store this package did not write (no '{STORE_KIND}' marker); "
                f'refusing to write into it'
            )
        if attrs.get('store_format_version') != STORE_FORMAT_VERSION:
            raise ErrorMapError(
                f'{p}: store format {attrs.get("store_format_version")!r}, this package reads '
                f'{STORE_FORMAT_VERSION}'
            )
        if allow_other_sweep:
            return group
        if attrs.get('sweep_digest') != spec.digest():
            raise ErrorMapError(
                f'{p} holds a different sweep (other arguments or scene); delete it, pass '
                f'--restart, or choose another --out'
            )
        want = {
            'error_deg': (spec.shape, 'float64'),
            'status': (spec.shape, 'int8'),
            'chunk_checksum': ((spec.shape[1], spec.shape[3]), 'uint64'),
        }
        for name, (shape, dtype) in want.items():
            try:
                arr = group[name]
                ok = tuple(arr.shape) == tuple(shape) and str(arr.dtype) == dtype
            except Exception:  # noqa: BLE001 - a missing or unreadable array
                ok = False
            if not ok:
                raise ErrorMapError(
                    f'{p}: array {name!r} is missing or has the wrong shape/type '
                    f'(want {shape} {dtype}); the store is corrupt, delete it'
                )
        return group

    @staticmethod
    def _create(p: Path, spec) -> None:
        import dask.array as da

        xr, _ = require_sweep_extra('a sweep store')
        M, A, Y, P, R = spec.shape
        chunks = (M, 1, Y, 1, R)
        meta = spec.to_meta()
        ds = xr.Dataset(
            {
                'error_deg': (
                    DIMS,
                    da.zeros(spec.shape, dtype=np.float64, chunks=chunks),
                    {'units': 'deg'},
                ),
                'status': (DIMS, da.full(spec.shape, -1, dtype=np.int8, chunks=chunks)),
                'chunk_checksum': (
                    ('sun_altitude', 'pitch'),
                    da.zeros((A, P), dtype=np.uint64, chunks=(1, 1)),
                    {
                        'long_name': "blake2b-64 of the chunk's error_deg and status bytes; "
                        '0 = not written'
                    },
                ),
            },
            coords=_coords(spec.methods, [getattr(spec, k) for k in AXES]),
            attrs={
                **_attrs_from_meta(meta),
                'store_kind': STORE_KIND,
                'store_format_version': STORE_FORMAT_VERSION,
                'sweep_digest': spec.digest(),
                'complete': False,
            },
        )
        encoding = {
            'error_deg': {'chunks': chunks, 'fill_value': 0.0},
            'status': {'chunks': chunks, 'fill_value': -1},
            'chunk_checksum': {'chunks': (1, 1), 'fill_value': 0},
        }
        p.parent.mkdir(parents=True, exist_ok=True)
        # compute=False: metadata and coordinates only; each chunk's region is written when it is
        # computed
        ds.to_zarr(
            str(p), mode='w-', compute=False, encoding=encoding, consolidated=False, zarr_format=3
        )

    # ---- chunks ------------------------------------------------------------------------
    def write_chunk(self, ia: int, ip: int, err: np.ndarray, status: np.ndarray) -> None:
        """
        Write one chunk's region, then its checksum.

        The checksum is written last, so a write torn between the two is detected, never trusted.

        Parameters
        ----------
        ia : int
            Index of the chunk's sun altitude.
        ip : int
            Index of the chunk's pitch.
        err : numpy.ndarray
            Errors [deg], shape (methods, yaws, rolls).
        status : numpy.ndarray
            Status codes (int8), same shape as ``err``.

        """
        self.group['error_deg'][:, ia, :, ip, :] = err
        self.group['status'][:, ia, :, ip, :] = status
        self.group['chunk_checksum'][ia, ip] = np.uint64(chunk_checksum(err, status))

    def read_chunk(self, ia: int, ip: int):
        """
        Return a stored chunk whose bytes match its checksum.

        Parameters
        ----------
        ia : int
            Index of the chunk's sun altitude.
        ip : int
            Index of the chunk's pitch.

        Returns
        -------
        tuple of numpy.ndarray or None
            ``(err, status)``: errors [deg] and status codes, shape (methods, yaws, rolls); None
            when the chunk was never written (checksum 0).

        Raises
        ------
        _DamagedChunk
            When the chunk was written but its checksum or data cannot be read or do not match, or
        it holds values no sweep writes (unknown status codes, errors not finite or not folded).

        """
        try:
            want = int(self.group['chunk_checksum'][ia, ip])
        except Exception as exc:  # noqa: BLE001 - a damaged checksum chunk
            raise _DamagedChunk(f'its checksum cannot be read ({type(exc).__name__})') from None
        if want == 0:
            return None
        try:
            err = np.asarray(self.group['error_deg'][:, ia, :, ip, :])
            status = np.asarray(self.group['status'][:, ia, :, ip, :])
        # a damaged data chunk (codec, truncated file, ...)
        except Exception as exc:  # noqa: BLE001
            raise _DamagedChunk(f'its data cannot be read ({type(exc).__name__}: {exc})') from None
        if chunk_checksum(err, status) != want:
            raise _DamagedChunk('its data do not match its checksum')
        problem = _chunk_problem(err, status)
        if problem:
            raise _DamagedChunk(problem)
        return err, status

    def chunk_name(self, ia: int, ip: int) -> str:
        """
        Return a readable name of one chunk for messages.

        Parameters
        ----------
        ia : int
            Index of the chunk's sun altitude.
        ip : int
            Index of the chunk's pitch.

        Returns
        -------
        str
            E.g. ``"chunk (sun altitude 30 deg, pitch 5 deg) [2, 1]"``.

        """
        return (
            f'chunk (sun altitude {self.spec.sun_altitude_deg[ia]:g} deg, pitch '
            f'{self.spec.pitch_deg[ip]:g} deg)'
            f' [{ia}, {ip}]'
        )

    def scan(self, chunks, err: np.ndarray, status: np.ndarray, log=None) -> list:
        """
        Copy every verified stored chunk into ``err``/``status``; return the ones to compute.

        A damaged chunk is named on ``log`` and returned for recomputation, never used.

        Parameters
        ----------
        chunks : iterable of tuple of int
            ``(ia, ip)`` indices of the chunks to look at.
        err : numpy.ndarray
            The whole map's errors [deg], shape ``spec.shape``; filled in place.
        status : numpy.ndarray
            The whole map's status codes, shape ``spec.shape``; filled in place.
        log : file-like, optional
            Where damaged chunks are reported; default the current ``sys.stderr``.

        Returns
        -------
        list of tuple of int
            ``(ia, ip)`` of the chunks not written or damaged, in the order of ``chunks``.

        """
        log = sys.stderr if log is None else log
        todo = []
        for ia, ip in chunks:
            try:
                got = self.read_chunk(ia, ip)
            except _DamagedChunk as exc:
                print(
                    f'errormap: {self.path}: {self.chunk_name(ia, ip)} is damaged ({exc}); '
                    'recomputing it (--restart recomputes the whole sweep)',
                    file=log,
                )
                got = None
            if got is None:
                todo.append((ia, ip))
            else:
                err[:, ia, :, ip, :], status[:, ia, :, ip, :] = got
        return todo

    def finish(self, meta: dict) -> None:
        """
        Record the final meta and mark the store complete.

        Parameters
        ----------
        meta : dict
            The finished map's meta (written to the store's attributes as in the module docstring).

        """
        self.group.attrs.update({**_attrs_from_meta(meta), 'complete': True})


class _DamagedChunk(Exception):
    pass


def _chunk_problem(err: np.ndarray, status: np.ndarray) -> str:
    """Return what no sweep writes in a chunk (a map would fail to validate), or ''."""
    from .errormap import STATUS_CODES, STATUS_ESTIMATOR_ERROR, STATUS_NOT_COMPUTED, STATUS_OTHER

    known = [*STATUS_CODES.values(), STATUS_NOT_COMPUTED, STATUS_ESTIMATOR_ERROR, STATUS_OTHER]
    unknown = np.setdiff1d(np.unique(status), known)
    if unknown.size:
        return f'its status holds unknown code(s) {unknown[:5].tolist()}'
    if not np.all(np.isfinite(err)) or np.any(np.abs(err) > 90.0 + 1e-9):
        return 'its errors are not finite or not folded to (-90, 90]'
    return ''


def read_store_map(path) -> ErrorMap:
    """
    Load and validate the map of a complete sweep store.

    Bounded: the store may hold only regular files and directories
    (:func:`~polarization_compass.map_bounds.check_store_files`) and the shapes its metadata
    declare must be those of its axes, within the map bounds, before any chunk is decoded
    (:func:`~polarization_compass.map_bounds.check_store_shapes`). Every written chunk must match
    its checksum, every unwritten one must be all "not computed" (status -1); the map is then
    validated (:meth:`ErrorMap.validate`).

    Parameters
    ----------
    path : str or os.PathLike
        The Zarr directory of a sweep.

    Returns
    -------
    ErrorMap
        The validated map with its meta.

    Raises
    ------
    ErrorMapError
        When xarray/zarr are missing, or the store is unreadable, foreign, unfinished, corrupt,
        holds a special file or a symlink, declares shapes beyond its axes or the bounds, has
        nested or invalid meta JSON, is damaged (a chunk not matching its checksum), or its map
        does not validate.

    """
    _, zarr = require_sweep_extra('reading a Zarr error map')
    p = Path(path)
    check_store_files(p)  # no FIFO, device or symlink: reading one could block or never end
    try:
        g = zarr.open_group(str(p), mode='r')
        attrs = dict(g.attrs)
    except Exception as exc:  # noqa: BLE001 - zarr's errors for an unreadable group vary by cause
        raise ErrorMapError(
            f'{p}: not a readable Zarr store ({type(exc).__name__}: {exc})'
        ) from None
    if attrs.get('store_kind') != STORE_KIND:
        raise ErrorMapError(
            f"{p} is a Zarr store this package did not write (no '{STORE_KIND}' marker)"
        )
    if not attrs.get('complete'):
        raise ErrorMapError(f'{p} is an unfinished sweep; rerun the sweep to complete it')
    check_store_shapes(g, p, ('method', *DIMS[1:]))  # before any chunk is decoded
    meta = load_json(str(attrs.get('meta_json', '{}')), f'{p}: meta_json', ErrorMapError)
    try:
        methods = tuple(str(x) for x in np.asarray(g['method'][:]).tolist())
        axes = [np.asarray(g[_AXIS_DIM[k]][:], dtype=float) for k in AXES]
        err = np.asarray(g['error_deg'][:])
        status = np.asarray(g['status'][:])
        sums = np.asarray(g['chunk_checksum'][:])
    except Exception as exc:  # noqa: BLE001 - a missing array, a damaged chunk, bad JSON
        raise ErrorMapError(f'{p}: corrupt sweep store ({type(exc).__name__}: {exc})') from None
    if err.ndim != 5 or sums.shape != (err.shape[1], err.shape[3]) or status.shape != err.shape:
        raise ErrorMapError(f'{p}: corrupt sweep store (array shapes disagree)')
    for ia in range(sums.shape[0]):
        for ip in range(sums.shape[1]):
            e, s = err[:, ia, :, ip, :], status[:, ia, :, ip, :]
            if (
                sums[ia, ip] == 0
                and np.any(s != -1)
                or sums[ia, ip] != 0
                and chunk_checksum(e, s) != sums[ia, ip]
            ):
                raise ErrorMapError(
                    f'{p}: chunk [{ia}, {ip}] does not match its checksum (damaged store)'
                )
    m = ErrorMap(
        err.astype(float), status, methods, *axes, meta=meta if isinstance(meta, dict) else {}
    )
    try:
        return m.validate()
    except ErrorMapError as exc:
        raise ErrorMapError(f'{p}: {exc}') from None
