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
Read a tilt error map in any of its file formats (the one loader the nodes, CLI and replay use).

Sits above the map type (:mod:`polarization_compass.errormap`: the ``.npz`` format) and the
labelled-array formats (:mod:`polarization_compass.errormap_store`: NetCDF 3 and Zarr sweep
stores), so that neither of those imports the other's readers back.
"""

from __future__ import annotations

from pathlib import Path

from .errormap import ErrorMap, ErrorMapError, read_npz_map

__all__ = ['load_error_map']


def load_error_map(path) -> ErrorMap:
    """
    Load and validate a map (never unpickles).

    Bounded: only a regular file or a sweep-store directory is opened; an ``.npz`` has the shapes
    its arrays declare checked before anything is decompressed
    (:func:`~polarization_compass.errormap.read_npz_map`); deeply nested meta JSON is an error too.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.npz`` of :meth:`ErrorMap.save`, a NetCDF 3 file or a complete Zarr sweep store
        (:mod:`~polarization_compass.errormap_store`; the NetCDF reader needs only scipy, the Zarr
        one the ``sweep`` extra).

    Returns
    -------
    ErrorMap
        The validated map, float64 errors and axes [deg].

    Raises
    ------
    ErrorMapError
        The file is missing, not an error map, corrupt, or inconsistent (the message names the file
        and the reason); a Zarr store that is unfinished or whose chunks do not match their
        checksums.

    """
    from .safe_load import regular_file

    p = Path(path)
    if p.is_dir():
        if not any((p / n).exists() for n in ('.zgroup', 'zarr.json', '.zattrs')):
            raise ErrorMapError(
                f'error map {str(p)!r} does not exist (a directory, not a sweep store)'
            )
        from .errormap_store import read_store_map

        return read_store_map(p)
    if not p.exists() and not p.is_symlink():
        raise ErrorMapError(f'error map {str(p)!r} does not exist')
    regular_file(p, ErrorMapError, 'error map')  # a FIFO or a device is refused before it is read
    with open(p, 'rb') as fh:
        head = fh.read(4)
    if head[:3] == b'CDF':
        from .errormap_netcdf import read_netcdf_map

        return read_netcdf_map(p)
    return read_npz_map(p)
