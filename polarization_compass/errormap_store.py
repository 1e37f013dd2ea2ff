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
Error maps as labelled arrays: xarray Dataset, Zarr sweep store, NetCDF export.

The xarray Dataset, the Zarr store a sweep writes into, and the NetCDF export.

The Dataset of a map (:func:`map_to_dataset`) has

``error_deg``  float64 (method, sun_altitude, yaw, pitch, roll): fold_axial(estimated psi - true
               psi), deg
``status``     int8, same dims: the codes of :data:`~polarization_compass.errormap.STATUS_CODES`
coordinates    ``method`` (names) and ``sun_altitude``, ``yaw``, ``pitch``, ``roll`` in degrees
               (attribute ``units: deg``)
attributes     ``meta_json`` (the map's whole ``meta``, JSON), and, for a reader that does not
               parse it, ``camera``, ``sky``, ``sampling`` (JSON) and ``package_version``.

A sweep writes into a :class:`SweepStore`, a Zarr (format 3) directory holding that Dataset plus
the bookkeeping variable ``chunk_checksum`` (sun_altitude, pitch), uint64. The Zarr chunks of
``error_deg`` and ``status`` are exactly the sweep's chunks (one sun altitude x one pitch, every
method, yaw and roll), so each finished chunk writes its own region, then its checksum (blake2b of
the region's bytes); 0 means "not written". Reopening the store with the same sweep (same
:meth:`SweepSpec.digest`) resumes: a chunk counts as done only when its stored bytes hash to its
checksum; a chunk that does not (a kill between the two writes, a damaged file) is named on stderr
and recomputed, never used. A directory that is not such a store (another program's Zarr, another
sweep, unreadable metadata) is refused with :class:`ErrorMapError`.

Exports: :func:`export_netcdf` writes one NetCDF **3** file (classic 64-bit offset format, through
xarray's scipy engine: no HDF5/netCDF4 library needed); :meth:`ErrorMap.save` writes today's
``.npz``. :func:`read_netcdf_map` reads such a file with ``scipy.io.netcdf_file`` only (no xarray,
no pickle), checks the digest of its content (attribute :data:`DIGEST_ATTR`; an ``.npz`` has its
zip CRCs) and validates it like the ``.npz`` loader (names, shapes, axes, finiteness, folding,
status codes). Reading a store is bounded (:mod:`~polarization_compass.map_bounds`): regular files
only, shapes declared by the metadata checked against the axes before any chunk is decoded.

xarray, zarr and dask are the optional extra ``sweep`` (``pip install
polarization_compass[sweep]``); the NetCDF reader needs only numpy and scipy.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
import shutil
import sys

import numpy as np

from .errormap import AXES, ErrorMap, ErrorMapError
from .map_bounds import check_store_files, check_store_shapes, map_digest
from .safe_load import load_json, regular_file

__all__ = [
    'SweepStore',
    'map_to_dataset',
    'export_netcdf',
    'read_netcdf_map',
    'read_store_map',
    'chunk_checksum',
    'STORE_KIND',
    'STORE_FORMAT_VERSION',
    'DIMS',
    'require_sweep_extra',
]

STORE_KIND = 'polarization_compass.errormap.sweep'
STORE_FORMAT_VERSION = 1
#: Dataset dimension of each ErrorMap axis.
DIMS = ('method', 'sun_altitude', 'yaw', 'pitch', 'roll')
_AXIS_DIM = dict(zip(AXES, DIMS[1:]))
_NETCDF_MAGIC = (b'CDF\x01', b'CDF\x02')
#: NetCDF attribute holding the digest of the map's content (integrity, as an .npz's zip CRCs).
DIGEST_ATTR = 'content_blake2b'
#: Largest NetCDF map file: 1 GiB (as an .npz map).
MAX_NETCDF_BYTES = 1 << 30


def require_sweep_extra(what: str = 'this'):
    """
    Import and return (xarray, zarr), naming the extra when they are missing.

    Parameters
    ----------
    what : str, default "this"
        What needs them, for the error message.

    Returns
    -------
    xarray : module
        The imported ``xarray``.
    zarr : module
        The imported ``zarr``.

    Raises
    ------
    ErrorMapError
        When either cannot be imported; the message names the optional extra ``sweep``.

    """
    try:
        import xarray
        import zarr
    except ImportError as exc:
        raise ErrorMapError(
            f"{what} needs the optional extra 'sweep' (pip install polarization_compass[sweep], "
            f'installed by make): {exc}'
        ) from None
    return xarray, zarr


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


def _attrs_from_meta(meta: dict) -> dict:
    scene = meta.get('scene') or {}
    return {
        'meta_json': json.dumps(meta, sort_keys=True),
        'camera': json.dumps(scene.get('camera'), sort_keys=True),
        'sky': json.dumps(scene.get('sky'), sort_keys=True),
        'sampling': json.dumps(meta.get('sampling'), sort_keys=True),
        'package_version': str(meta.get('package_version', '')),
    }


def _coords(methods, axes) -> dict:
    coords = {
        'method': ('method', np.array(list(methods), dtype=object))
    }  # variable-length UTF-8 in Zarr 3
    for name, a in zip(AXES, axes):
        coords[_AXIS_DIM[name]] = (_AXIS_DIM[name], np.asarray(a, dtype=float), {'units': 'deg'})
    return coords


def map_to_dataset(m: ErrorMap):
    """
    Return the map as an ``xarray.Dataset``.

    The map is validated first. Variables ``error_deg`` [deg] and ``status`` (int8) over the dims
    :data:`DIMS`, coordinates ``method`` and the four axes [deg], and the map's meta in the
    attributes (module docstring).

    Parameters
    ----------
    m : ErrorMap
        The error map.

    Returns
    -------
    xarray.Dataset
        The labelled map.

    Raises
    ------
    ErrorMapError
        When xarray/zarr are missing (:func:`require_sweep_extra`) or the map does not validate.

    """
    xr, _ = require_sweep_extra('an xarray Dataset of a map')
    m.validate()
    ds = xr.Dataset(
        {
            'error_deg': (
                DIMS,
                m.error_deg,
                {
                    'units': 'deg',
                    'long_name': 'fold_axial(estimated psi - true psi), in (-90, 90]',
                },
            ),
            'status': (
                DIMS,
                m.status.astype(np.int8),
                {'long_name': 'status code, see meta_json'},
            ),
        },
        coords=_coords(m.methods, m.axes()),
        attrs=_attrs_from_meta(m.meta),
    )
    return ds


def export_netcdf(m: ErrorMap, path) -> Path:
    """
    Write the map as one NetCDF 3 file, atomically.

    The Dataset of :func:`map_to_dataset` plus the digest of its content (attribute
    :data:`DIGEST_ATTR`, :func:`~polarization_compass.map_bounds.map_digest`), written in the
    classic 64-bit offset format with xarray's scipy engine to ``<path>.tmp`` and then renamed over
    ``path``; parent directories are created.

    Parameters
    ----------
    m : ErrorMap
        The error map.
    path : str or os.PathLike
        The output file.

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    ErrorMapError
        When xarray/zarr are missing or the map does not validate (:func:`map_to_dataset`).

    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + '.tmp')
    ds = map_to_dataset(m)
    ds.attrs[DIGEST_ATTR] = map_digest(
        m.error_deg, m.status, m.methods, m.axes(), ds.attrs['meta_json']
    )
    ds.to_netcdf(tmp, engine='scipy', format='NETCDF3_64BIT')
    os.replace(tmp, p)
    return p


def _char_rows(a: np.ndarray) -> list[str]:
    """Names stored as a NetCDF 3 char array (rows of bytes) -> str."""
    a = np.asarray(a)
    if a.dtype.kind == 'S' and a.ndim == 2:
        return [b''.join(row).decode('utf-8').rstrip('\x00') for row in a]
    if a.dtype.kind in 'SU' and a.ndim == 1:
        return [x.decode('utf-8') if isinstance(x, bytes) else str(x) for x in a]
    raise ValueError(f'method names must be a char array, got {a.dtype} {a.shape}')


def read_netcdf_map(path) -> ErrorMap:
    """
    Load and validate a map written by :func:`export_netcdf`.

    Read with ``scipy.io.netcdf_file`` only (no xarray, no pickle), after checking that it is a
    regular file of at most :data:`MAX_NETCDF_BYTES`, the NetCDF 3 magic bytes and that the
    header's shapes fit the file's size; its content must match its digest (:data:`DIGEST_ATTR`),
    then it is validated like the ``.npz`` loader (:meth:`ErrorMap.validate`).

    Parameters
    ----------
    path : str or os.PathLike
        The NetCDF file.

    Returns
    -------
    ErrorMap
        The validated map with its meta.

    Raises
    ------
    ErrorMapError
        Naming the file and the reason: missing, not NetCDF 3, truncated, missing variables, wrong
        dims, corrupt, no digest or content not matching it, ``meta_json`` not a JSON object (or
        nested too deeply), non-float errors, or a map that does not validate.

    """
    p = regular_file(path, ErrorMapError, 'error map', MAX_NETCDF_BYTES)
    with open(p, 'rb') as fh:
        if fh.read(4) not in _NETCDF_MAGIC:
            raise ErrorMapError(f'{p}: not a NetCDF 3 file')
    methods, axes, err, status, meta_raw, digest = _read_netcdf_arrays(p)
    if isinstance(meta_raw, bytes):
        try:
            meta_raw = meta_raw.decode('utf-8')
        except UnicodeDecodeError as exc:
            raise ErrorMapError(f'{p}: meta_json is not valid JSON ({exc})') from None
    if err.dtype.kind != 'f':
        raise ErrorMapError(f'{p}: error_deg must be floating point, got {err.dtype}')
    if digest is None:
        raise ErrorMapError(
            f'{p}: no {DIGEST_ATTR} attribute (written by an older version?); export it again'
        )
    if map_digest(err, status, methods, axes, str(meta_raw)) != digest:
        raise ErrorMapError(f'{p}: its content does not match its digest (damaged or edited)')
    meta = load_json(str(meta_raw), f'{p}: meta_json', ErrorMapError)
    if not isinstance(meta, dict):
        raise ErrorMapError(f'{p}: meta_json is not valid JSON (not an object)')
    m = ErrorMap(err.astype(float), status, tuple(methods), *axes, meta=meta)
    try:
        return m.validate()
    except ErrorMapError as exc:
        raise ErrorMapError(f'{p}: {exc}') from None


def _read_netcdf_arrays(p: Path):
    """Return methods, axes, errors, statuses, the meta text and the digest of a NetCDF map."""
    from scipy.io import netcdf_file

    size = p.stat().st_size
    try:
        with netcdf_file(p, 'r', mmap=False) as nc:
            v = nc.variables
            missing = [k for k in ('error_deg', 'status', *DIMS) if k not in v]
            if missing:
                raise ErrorMapError(f'{p}: not an error map (missing {", ".join(missing)})')
            if tuple(v['error_deg'].dimensions) != DIMS or tuple(v['status'].dimensions) != DIMS:
                raise ErrorMapError(f'{p}: error_deg/status must have dims {DIMS}')
            n = int(np.prod(v['error_deg'].shape, dtype=np.int64))
            if n * 9 > size:  # the header claims more data than the file holds
                raise ErrorMapError(
                    f"{p}: truncated (the header's shapes need more bytes than the file has)"
                )
            methods = _char_rows(v['method'].data)
            axes = [np.array(v[_AXIS_DIM[k]].data, dtype=float) for k in AXES]
            err = np.array(v['error_deg'].data)
            status = np.array(v['status'].data)
            attrs = nc._attributes  # noqa: SLF001 - scipy keeps the global attributes here
            meta_raw = attrs.get('meta_json', b'{}')
            digest = attrs.get(DIGEST_ATTR)
    except ErrorMapError:
        raise
    # scipy raises many types on a malformed file; all mean "corrupt"
    except Exception as exc:  # noqa: BLE001
        raise ErrorMapError(
            f'{p}: corrupt or not a NetCDF error map ({type(exc).__name__}: {exc})'
        ) from None
    if isinstance(digest, bytes):
        digest = digest.decode('ascii', 'replace')
    return methods, axes, err, status, meta_raw, digest


# --------------------------------------------------------------------------------------------
# The Zarr store a sweep writes into
# --------------------------------------------------------------------------------------------
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
