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
Tilt error maps: each method's heading error over sun altitude, yaw, pitch and roll.

Tilt error maps: the heading error of each method over sun altitude x yaw x pitch x roll (paper,
section 3).

A map holds, for every method m and grid cell (sun altitude h, yaw psi, pitch alpha, roll beta),

    error_deg[m, h, psi, alpha, beta] = fold_axial(estimated psi - true psi)   in (-90, 90] deg

computed by rendering a scene with the sun fixed at azimuth 0 and altitude h and the camera at
bearing psi (so bearing == psi, :mod:`~polarization_compass.conventions`), pitch alpha and roll
beta, then running the method on the pixels it reads (``estimator.pixels_needed(camera)``) and
nothing else.

Arrays of an :class:`ErrorMap` (and of the ``.npz`` file, loaded with ``allow_pickle=False``):

``error_deg``        float64 (methods, sun altitudes, yaws, pitches, rolls). Never NaN: cells
                     without a usable estimate hold 0 and are flagged by ``status``/``valid``.
``status``           int8, same shape: :data:`STATUS_CODES` (0 ok, 1 ok but axial, >= 2 the
                     estimator's failure status, -1 not computed (outside the tilt domain), -2 the
                     estimator raised).
``valid``            bool, same shape: status is 0 or 1 (the error is meaningful).
``methods``          unicode (methods,)
``sun_altitude_deg``, ``yaw_deg``, ``pitch_deg``, ``roll_deg``: float64 strictly increasing axes.
``meta``             0-d unicode array, JSON: scene, sampling (per-method pixel selection and
                     knobs), domain rule, status legend, package version, format version.

The tilt domain: the paper keeps |pitch| + |roll| <= 30 deg (a 108 deg field of view above the
horizon). By default a (pitch, roll) node is computed when it is a corner of a grid cell that
touches that diamond, so that every point with |pitch| + |roll| <= 30 can be interpolated from
computed nodes (the nodes one grid step outside the diamond are computed; everything further out is
skipped). ``full_domain=True`` computes every node.

The sweep that computes a map (chunks, workers, checkpoints, resume) is
:mod:`polarization_compass.sweep`; this module is the map type the nodes and the correction read.
The same map as a labelled xarray Dataset, in a Zarr store or one NetCDF 3 file:
:mod:`polarization_compass.errormap_store`;
:func:`~polarization_compass.errormap_io.load_error_map` reads ``.npz``, NetCDF and complete Zarr
stores.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import json
import os
from pathlib import Path

import numpy as np

from .errors import CompassError

__all__ = [
    'ErrorMap',
    'ErrorMapError',
    'read_npz_map',
    'tilt_domain_mask',
    'AXES',
    'STATUS_CODES',
    'STATUS_NOT_COMPUTED',
    'STATUS_ESTIMATOR_ERROR',
    'STATUS_OTHER',
    'STATUS_LEGEND',
    'DEFAULT_TILT_LIMIT_DEG',
    'FORMAT_VERSION',
]

FORMAT_VERSION = 1
DEFAULT_TILT_LIMIT_DEG = 30.0

#: int8 status codes stored in a map (by the estimator's Status *value*, so the table is stable).
STATUS_CODES = {
    'ok': 0,
    'ambiguous': 1,
    'sun_near_zenith': 2,
    'sun_below_horizon': 3,
    'too_few_pixels': 4,
    'out_of_domain': 5,
    'bad_input': 6,
    'degenerate': 7,
    'insufficient_coverage': 9,
    'poor_fit': 10,  # sm_asm/symmetry: no mirror-symmetric axis next to the plain fit
}
STATUS_NOT_COMPUTED = -1
STATUS_ESTIMATOR_ERROR = -2
STATUS_OTHER = 8  # a status value this table does not know (a newer estimator)
STATUS_LEGEND = {
    **{str(v): k for k, v in STATUS_CODES.items()},
    str(STATUS_NOT_COMPUTED): 'not_computed',
    str(STATUS_ESTIMATOR_ERROR): 'estimator_error',
    str(STATUS_OTHER): 'other',
}


class ErrorMapError(CompassError):
    """A bad sweep specification, or an error-map file that is missing, corrupt or inconsistent."""


def _min_abs_on(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Min |x| over the interval [lo, hi] (elementwise)."""
    return np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))


def tilt_domain_mask(
    pitch_deg, roll_deg, limit_deg: float = DEFAULT_TILT_LIMIT_DEG, support: int = 0
) -> np.ndarray:
    """
    Mark the (pitch, roll) nodes in, or supporting, the domain |pitch| + |roll| <= limit.

    ``support=0``: exactly the nodes with |pitch| + |roll| <= limit. ``support=1``: also every node
    that is a corner of a grid cell touching that region (what multilinear interpolation inside it
    reads). ``support=2``: also the nodes one step further (what cubic interpolation reads).

    Parameters
    ----------
    pitch_deg : array_like
        Pitch axis [deg], 1-D, increasing.
    roll_deg : array_like
        Roll axis [deg], 1-D, increasing.
    limit_deg : float, default 30
        Bound on |pitch| + |roll| [deg] (the paper's imager stays above the horizon within it).
    support : int, default 0
        Extra grid steps around the domain that interpolation reads (0, 1 or 2).

    Returns
    -------
    numpy.ndarray
        bool, shape (pitches, rolls).

    Raises
    ------
    ErrorMapError
        ``support`` is negative.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3 (``|alpha| + |beta|
       <= 30 deg`` for a 108 deg field of view).

    """
    p = np.asarray(pitch_deg, dtype=float)
    r = np.asarray(roll_deg, dtype=float)
    eps = 1e-9
    k = int(support)
    if k < 0:
        raise ErrorMapError(f'support must be >= 0, got {support}')

    def neighbourhood(axis):
        # min |x| over [axis[i - k], axis[i + k]] (clipped to the axis)
        n = axis.size
        i = np.arange(n)
        return _min_abs_on(axis[np.clip(i - k, 0, n - 1)], axis[np.clip(i + k, 0, n - 1)])

    return (neighbourhood(p)[:, None] + neighbourhood(r)[None, :]) <= limit_deg + eps


# --------------------------------------------------------------------------------------------
# The map
# --------------------------------------------------------------------------------------------
AXES = ('sun_altitude_deg', 'yaw_deg', 'pitch_deg', 'roll_deg')


@dataclass
class ErrorMap:
    """
    Hold a computed tilt error map (see the module docstring for the arrays' meaning).

    Parameters
    ----------
    error_deg : numpy.ndarray
        Heading error [deg] folded to (-90, 90], shape (methods, sun altitudes, yaws, pitches,
        rolls); 0 where ``status`` says there is no estimate.
    status : numpy.ndarray
        int8 codes (:data:`STATUS_CODES`, :data:`STATUS_NOT_COMPUTED`, ...), the same shape.
    methods : tuple of str
        Method names along the first axis.
    sun_altitude_deg, yaw_deg, pitch_deg, roll_deg : numpy.ndarray
        The grid axes [deg], strictly increasing; yaw is the paper's psi (eq 21), pitch alpha, roll
        beta.
    meta : dict
        JSON-able description: scene, sampling, domain rule, status legend, versions.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3 (the error over sun
       altitude, yaw, pitch and roll).

    """

    error_deg: np.ndarray
    status: np.ndarray
    methods: tuple
    sun_altitude_deg: np.ndarray
    yaw_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def valid(self) -> np.ndarray:
        """Bool mask, shape of ``status``: the cell holds an estimate (ok or axial)."""
        return (self.status == STATUS_CODES['ok']) | (self.status == STATUS_CODES['ambiguous'])

    @property
    def shape(self) -> tuple:
        """Shape of ``error_deg``: (methods, sun altitudes, yaws, pitches, rolls)."""
        return self.error_deg.shape

    def axes(self) -> tuple:
        """
        Give the four grid axes in array order.

        Returns
        -------
        tuple of numpy.ndarray
            ``(sun_altitude_deg, yaw_deg, pitch_deg, roll_deg)`` [deg].

        """
        return (self.sun_altitude_deg, self.yaw_deg, self.pitch_deg, self.roll_deg)

    def method_index(self, method: str) -> int:
        """
        Give the index of a method along the map's first axis.

        Parameters
        ----------
        method : str
            Method name.

        Returns
        -------
        int
            Its index in ``methods``.

        Raises
        ------
        ErrorMapError
            The method is not in this map (the message lists those that are).

        """
        try:
            return list(self.methods).index(method)
        except ValueError:
            raise ErrorMapError(
                f'method {method!r} is not in this map (it has {", ".join(self.methods)})'
            ) from None

    @staticmethod
    def axis_index(axis: np.ndarray, value: float, name: str, tol: float = 1e-6) -> int:
        """
        Give the index of the node of an axis equal to a value.

        Parameters
        ----------
        axis : numpy.ndarray
            One of the map's axes [deg].
        value : float
            The wanted node [deg].
        name : str
            Name of the axis, for the message.
        tol : float, default 1e-6
            Largest accepted |node - value| [deg].

        Returns
        -------
        int
            Index of the nearest node.

        Raises
        ------
        ErrorMapError
            No node lies within ``tol`` of ``value``.

        """
        i = int(np.argmin(np.abs(axis - value)))
        if abs(axis[i] - value) > tol:
            raise ErrorMapError(
                f"{name} {value:g} is not a node of the map's {name} axis ({_axis_text(axis)})"
            )
        return i

    def validate(self) -> 'ErrorMap':
        """
        Check shapes, axes, finiteness, folding and status codes.

        Returns
        -------
        ErrorMap
            ``self``, for chaining.

        Raises
        ------
        ErrorMapError
            With the first inconsistency found.

        """
        axes = self.axes()
        for name, a in zip(AXES, axes):
            if a.ndim != 1 or a.size < 1:
                raise ErrorMapError(f'{name} must be a non-empty 1-D axis, got shape {a.shape}')
            if not np.all(np.isfinite(a)):
                raise ErrorMapError(f'{name} has NaN or inf values')
            if a.size > 1 and not np.all(np.diff(a) > 0):
                raise ErrorMapError(f'{name} must be strictly increasing')
        want = (len(self.methods),) + tuple(a.size for a in axes)
        if self.error_deg.shape != want:
            raise ErrorMapError(f'error_deg has shape {self.error_deg.shape}, the axes say {want}')
        if self.status.shape != want:
            raise ErrorMapError(f'status has shape {self.status.shape}, the axes say {want}')
        if self.error_deg.dtype.kind != 'f' or not np.all(np.isfinite(self.error_deg)):
            raise ErrorMapError('error_deg must be finite floating point (no NaN/inf)')
        if np.any(np.abs(self.error_deg) > 90.0 + 1e-9):
            raise ErrorMapError('error_deg values must be folded to (-90, 90]')
        known = set(STATUS_CODES.values()) | {
            STATUS_NOT_COMPUTED,
            STATUS_ESTIMATOR_ERROR,
            STATUS_OTHER,
        }
        if self.status.dtype.kind not in 'iu' or not np.all(np.isin(self.status, list(known))):
            raise ErrorMapError('status holds unknown codes')
        if len(set(self.methods)) != len(self.methods) or not all(
            isinstance(m, str) and m for m in self.methods
        ):
            raise ErrorMapError('methods must be distinct non-empty names')
        if self.sun_altitude_deg.min() < -90 or self.sun_altitude_deg.max() > 90:
            raise ErrorMapError('sun_altitude_deg must lie in [-90, 90]')
        return self

    def save(self, path, float32: bool = False) -> Path:
        """
        Write the map as a compressed ``.npz``, atomically (a temporary file, then rename).

        Parameters
        ----------
        path : str or os.PathLike
            Destination; parent directories are created.
        float32 : bool, default False
            Store ``error_deg`` as float32: half the file, errors keep ~1e-5 deg; loading always
            gives float64.

        Returns
        -------
        pathlib.Path
            The written path.

        Raises
        ------
        ErrorMapError
            The map is inconsistent (:meth:`validate`).

        """
        self.validate()
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(p.name + '.tmp.npz')
        err = self.error_deg.astype(np.float32) if float32 else self.error_deg
        np.savez_compressed(
            tmp,
            error_deg=err,
            status=self.status.astype(np.int8),
            valid=self.valid,
            methods=np.array(self.methods, dtype=str),
            sun_altitude_deg=self.sun_altitude_deg,
            yaw_deg=self.yaw_deg,
            pitch_deg=self.pitch_deg,
            roll_deg=self.roll_deg,
            meta=np.array(json.dumps(self.meta, sort_keys=True)),
        )
        os.replace(tmp, p)
        return p


def _axis_text(a: np.ndarray) -> str:
    if a.size == 1:
        return f'{a[0]:g}'
    return f'{a[0]:g}..{a[-1]:g}, {a.size} nodes'


#: Largest map read: 1e8 cells per array (0.8 GB of float64 errors; the shipped map has 1.7e5).
MAX_MAP_CELLS = 100_000_000
#: Largest axis (nodes) and method count of a map read.
MAX_AXIS_NODES = 100_000
MAX_MAP_METHODS = 1000
#: Largest meta JSON text of a map: 1 MiB.
MAX_MAP_META_CHARS = 1 << 20
_MAP_KEYS = ('error_deg', 'status', 'methods', *AXES, 'meta')


def _check_map_headers(name: str, h: dict) -> None:
    """
    Check the shapes a map file declares before anything is decompressed.

    The axes and methods must be 1-D and of bounded length, error_deg and status exactly (methods,
    altitudes, yaws, pitches, rolls) of at most :data:`MAX_MAP_CELLS`, meta one JSON string of at
    most :data:`MAX_MAP_META_CHARS` characters.
    """
    missing = [k for k in _MAP_KEYS if k not in h]
    if missing:
        raise ErrorMapError(f'{name}: not an error map (missing {", ".join(missing)})')
    lengths = []
    for k, limit in (('methods', MAX_MAP_METHODS), *((a, MAX_AXIS_NODES) for a in AXES)):
        shp = h[k].shape
        if len(shp) != 1 or shp[0] > limit:
            raise ErrorMapError(
                f'{name}: {k} must be 1-D with at most {limit} entries, declares shape {shp}'
            )
        lengths.append(shp[0])
    if h['methods'].dtype.kind != 'U' or h['methods'].dtype.itemsize > 4 * 256:
        raise ErrorMapError(
            f'{name}: methods must be a 1-D array of names (at most 256 characters each)'
        )
    want = tuple(lengths)
    for k in ('error_deg', 'status'):
        if h[k].shape != want:
            raise ErrorMapError(
                f'{name}: {k} declares shape {h[k].shape}, the axes and methods make {want}'
            )
    n = int(np.prod(want, dtype=object)) if want else 0
    if n > MAX_MAP_CELLS:
        raise ErrorMapError(
            f'{name}: the map declares {n} cells per array, more than {MAX_MAP_CELLS}; refused '
            'before decompressing'
        )
    m = h['meta']
    if m.shape != () or m.dtype.kind != 'U' or m.dtype.itemsize // 4 > MAX_MAP_META_CHARS:
        raise ErrorMapError(
            f'{name}: meta must be one JSON string of at most {MAX_MAP_META_CHARS} characters, '
            f'got {m.dtype} of shape {m.shape}'
        )


def read_npz_map(path) -> ErrorMap:
    """
    Read and validate an ``.npz`` map written by :meth:`ErrorMap.save` (never unpickles).

    Bounded: only a regular file is opened, and the shapes its arrays declare are checked
    (:func:`_check_map_headers`) before anything is decompressed; deeply nested meta JSON is an
    error too. :func:`polarization_compass.errormap_io.load_error_map` reads every map format.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.npz`` of :meth:`ErrorMap.save`.

    Returns
    -------
    ErrorMap
        The validated map, float64 errors and axes [deg].

    Raises
    ------
    ErrorMapError
        The file is missing, not a regular file, not an error map, corrupt, or inconsistent (the
        message names the file and the reason).

    """
    from .safe_load import load_json, open_npz, regular_file

    p = Path(path)
    if not p.exists() and not p.is_symlink():
        raise ErrorMapError(f'error map {str(p)!r} does not exist')
    regular_file(p, ErrorMapError, 'error map')  # a FIFO or a device is refused before it is read
    with open_npz(
        p, ErrorMapError, 'error map', check=lambda h: _check_map_headers(str(p), h)
    ) as z:
        arrays = {k: z[k] for k in _MAP_KEYS}
    meta = load_json(str(arrays['meta'][()]), f'{p}: meta', ErrorMapError)
    if not isinstance(meta, dict):
        raise ErrorMapError(f'{p}: meta is not valid JSON (not an object)')
    methods = arrays['methods']
    if methods.dtype.kind != 'U' or methods.ndim != 1:
        raise ErrorMapError(f'{p}: methods must be a 1-D array of names')
    err = arrays['error_deg']
    if err.dtype.kind != 'f':
        raise ErrorMapError(f'{p}: error_deg must be floating point, got {err.dtype}')
    axes = []
    for k in AXES:
        a = arrays[k]
        if a.dtype.kind not in 'fiu':
            raise ErrorMapError(f'{p}: {k} must be numeric, got {a.dtype}')
        axes.append(a.astype(float))
    m = ErrorMap(
        err.astype(float), arrays['status'], tuple(str(x) for x in methods), *axes, meta=meta
    )
    try:
        return m.validate()
    except ErrorMapError as exc:
        raise ErrorMapError(f'{p}: {exc}') from None
