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
An error map as a labelled xarray Dataset, the form its Zarr store and NetCDF file share.

The Dataset of a map (:func:`map_to_dataset`) has

``error_deg``  float64 (method, sun_altitude, yaw, pitch, roll): fold_axial(estimated psi - true
               psi), deg
``status``     int8, same dims: the codes of :data:`~polarization_compass.errormap.STATUS_CODES`
coordinates    ``method`` (names) and ``sun_altitude``, ``yaw``, ``pitch``, ``roll`` in degrees
               (attribute ``units: deg``)
attributes     ``meta_json`` (the map's whole ``meta``, JSON), and, for a reader that does not
               parse it, ``camera``, ``sky``, ``sampling`` (JSON) and ``package_version``.

xarray, zarr and dask are the optional extra ``sweep`` (``pip install
polarization_compass[sweep]``); the NetCDF reader needs only numpy and scipy.
"""

from __future__ import annotations

import json

import numpy as np

from .errormap import AXES, ErrorMap, ErrorMapError

__all__ = ['DIMS', 'map_to_dataset', 'require_sweep_extra']

#: Dataset dimension of each ErrorMap axis.
DIMS = ('method', 'sun_altitude', 'yaw', 'pitch', 'roll')
_AXIS_DIM = dict(zip(AXES, DIMS[1:]))


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
