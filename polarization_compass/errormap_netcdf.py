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
An error map as one NetCDF 3 file: export and a reader that needs only numpy and scipy.

Exports: :func:`export_netcdf` writes one NetCDF **3** file (classic 64-bit offset format, through
xarray's scipy engine: no HDF5/netCDF4 library needed); :meth:`ErrorMap.save` writes today's
``.npz``. :func:`read_netcdf_map` reads such a file with ``scipy.io.netcdf_file`` only (no xarray,
no pickle), checks the digest of its content (attribute :data:`DIGEST_ATTR`; an ``.npz`` has its
zip CRCs) and validates it like the ``.npz`` loader (names, shapes, axes, finiteness, folding,
status codes).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .errormap import AXES, ErrorMap, ErrorMapError
from .errormap_dataset import _AXIS_DIM, DIMS, map_to_dataset
from .map_bounds import map_digest
from .safe_load import load_json, regular_file

__all__ = ['DIGEST_ATTR', 'export_netcdf', 'read_netcdf_map']

_NETCDF_MAGIC = (b'CDF\x01', b'CDF\x02')
#: NetCDF attribute holding the digest of the map's content (integrity, as an .npz's zip CRCs).
DIGEST_ATTR = 'content_blake2b'
#: Largest NetCDF map file: 1 GiB (as an .npz map).
MAX_NETCDF_BYTES = 1 << 30


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
