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
The photodiode-array sensor description (YAML) and its validation.

Format (one YAML mapping)::

    angle_zero: horizontal        # meridian | horizontal: what a 0 deg polarizer is parallel to
    angle_sense: ccw              # cw | ccw: increasing angle, looking out along a unit's axis
    units:                        # 1..64 units
      - azimuth_deg: 0            # clockwise from the body's front, seen from above
        elevation_deg: 45         # above the body's x-y plane (90 = zenith)
        channels_deg: [135, 45, 90, 0]   # polarizer angle of each channel, recording's order
        acceptance_deg: 60        # full cone angle the unit integrates over (simulator; > 0)
        gains: [1, 1, 1, 1]       # optional relative channel gains (default 1)
        gains_sigma: [0, 0, 0, 0] # optional 1-sigma of the gains (written by calibrate-array)
        enabled: true             # optional; false: the unit is never used for a heading
        dark_offset: [0, 0, 0, 0] # optional reading of each channel in the dark (subtracted)
    saturation: [-32768, 32767]   # optional readings at or beyond these limits are saturated
    mount:                        # optional: the sensor's tilt on the body (:mod:`..mount`)
      pitch_deg: -4.1
      roll_deg: -2.0

With a ``mount``, :meth:`ArrayGeometry.axes_body` and :meth:`ArrayGeometry.evectors_body` are in
the body frame (the units' own description is the sensor's), so every estimator reads the body's
heading and levels with the body's pitch and roll.
The frame conventions (body frame, angle zero and sense) are :mod:`..conventions`'.
Every problem is a one-line :class:`ArrayGeometryError` naming the key.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math

import numpy as np

from ..conventions import ANGLE_SENSES, ANGLE_ZEROS, unit_axis_body, unit_evector_body
from ..errors import CompassError
from ..mount import Mount, mount_from_dict, mount_to_dict, MountError, R_body_sensor
from ..safe_load import load_yaml, read_text

__all__ = [
    'ArrayGeometry',
    'ArrayGeometryError',
    'UnitGeometry',
    'load_array_geometry',
    'geometry_from_dict',
    'geometry_to_dict',
    'MAX_UNITS',
    'MIN_CHANNELS',
    'MAX_CHANNELS',
]

MAX_UNITS = 64
MIN_CHANNELS, MAX_CHANNELS = 2, 4
_MAX_TEXT = 1_000_000  # characters of YAML


class ArrayGeometryError(CompassError):
    """A sensor description that cannot be used."""


@dataclass(frozen=True)
class UnitGeometry:
    """One photodiode unit: viewing direction (deg), polarizer angles (deg) and relative gains."""

    azimuth_deg: float
    elevation_deg: float
    channels_deg: tuple
    acceptance_deg: float
    gains: tuple
    gains_sigma: tuple | None = None
    enabled: bool = True
    dark_offset: tuple | None = None

    @property
    def n_channels(self) -> int:
        """Return the number of polarizer channels of this unit."""
        return len(self.channels_deg)


@dataclass(frozen=True)
class ArrayGeometry:
    """A photodiode-array sensor: its units and the polarizer angle convention they share."""

    units: tuple
    angle_zero: str = 'meridian'
    angle_sense: str = 'cw'
    extra: dict = field(default_factory=dict)
    mount: Mount | None = None

    @property
    def n_units(self) -> int:
        """Return the number of units."""
        return len(self.units)

    @property
    def saturation(self) -> tuple | None:
        """Return the (low, high) reading limits (at or beyond: saturated), None without."""
        s = self.extra.get('saturation')
        return None if s is None else (float(s[0]), float(s[1]))

    @property
    def n_channels(self) -> int:
        """Channels per unit (the recording's last axis): the largest over the units."""
        return max(u.n_channels for u in self.units)

    def axes_body(self) -> np.ndarray:
        """
        View axes of the units in the REP-103 body frame.

        Returns
        -------
        numpy.ndarray
            (U, 3) unit vectors (:func:`~polarization_compass.conventions.unit_axis_body`, turned
            by the mount).

        """
        return self.body_from_sensor(
            unit_axis_body(
                [u.azimuth_deg for u in self.units], [u.elevation_deg for u in self.units]
            )
        )

    def body_from_sensor(self, v_sensor) -> np.ndarray:
        """
        Turn vectors from the sensor's frame (the units' description) into the body frame.

        Parameters
        ----------
        v_sensor : array_like
            (..., 3) vectors in the sensor's frame.

        Returns
        -------
        numpy.ndarray
            (..., 3) the same vectors in the body frame (unchanged without a mount).

        """
        v = np.asarray(v_sensor, dtype=float)
        return v if self.mount is None else v @ R_body_sensor(self.mount).T

    def sensor_from_body(self, v_body) -> np.ndarray:
        """
        Turn body-frame vectors into the sensor's frame (the inverse of :meth:`body_from_sensor`).

        Parameters
        ----------
        v_body : array_like
            (..., 3) vectors in the body frame.

        Returns
        -------
        numpy.ndarray
            (..., 3) the same vectors in the sensor's frame.

        """
        v = np.asarray(v_body, dtype=float)
        return v if self.mount is None else v @ R_body_sensor(self.mount)

    def evectors_body(self, angle_rad) -> np.ndarray:
        """
        Body-frame E-vectors of polarization angles measured by the units.

        Parameters
        ----------
        angle_rad : array_like
            (..., U) angles of polarization [rad] in the units' convention (``angle_zero``,
            ``angle_sense``).

        Returns
        -------
        numpy.ndarray
            (..., U, 3) unit E-vectors in the body frame
            (:func:`~polarization_compass.conventions.unit_evector_body`, turned by the mount).

        """
        az = np.array([u.azimuth_deg for u in self.units])
        el = np.array([u.elevation_deg for u in self.units])
        return self.body_from_sensor(
            unit_evector_body(angle_rad, az, el, self.angle_zero, self.angle_sense)
        )

    def with_convention(self, angle_zero: str, angle_sense: str) -> 'ArrayGeometry':
        """
        Return a copy with another polarizer angle convention.

        Parameters
        ----------
        angle_zero : str
            ``meridian`` or ``horizontal``.
        angle_sense : str
            ``cw`` or ``ccw``.

        Returns
        -------
        ArrayGeometry
            The same units with the given convention.

        """
        return replace(self, angle_zero=angle_zero, angle_sense=angle_sense)

    def with_mount(self, mount: Mount | None) -> 'ArrayGeometry':
        """
        Return a copy with another mount.

        Parameters
        ----------
        mount : Mount or None
            The sensor's tilt on the body (None: level).

        Returns
        -------
        ArrayGeometry
            The same units and convention on this mount.

        """
        return replace(self, mount=mount)

    def with_gains(self, gains, gains_sigma=None) -> 'ArrayGeometry':
        """
        Return a copy with new per-unit channel gains.

        Parameters
        ----------
        gains : sequence of sequence of float
            Per unit, one relative gain per channel.
        gains_sigma : sequence of (sequence of float or None), optional
            Per unit, the 1-sigma of each gain (None: not known).

        Returns
        -------
        ArrayGeometry
            The same units and convention with these gains.

        """
        units = []
        for i, u in enumerate(self.units):
            g = tuple(float(v) for v in gains[i])
            gs = None if gains_sigma is None else tuple(float(v) for v in gains_sigma[i])
            units.append(replace(u, gains=g, gains_sigma=gs))
        return replace(self, units=tuple(units))


def _number(where: str, v, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ArrayGeometryError(f'{where} must be a number, got {v!r}')
    v = float(v)
    if not math.isfinite(v) or not (lo <= v <= hi):
        raise ArrayGeometryError(f'{where} must be finite and in [{lo:g}, {hi:g}], got {v:g}')
    return v


def _numbers(where: str, v, n: int | None, lo: float, hi: float) -> tuple:
    if not isinstance(v, (list, tuple)):
        raise ArrayGeometryError(f'{where} must be a list of numbers, got {type(v).__name__}')
    if n is not None and len(v) != n:
        raise ArrayGeometryError(f'{where} must have {n} entries (one per channel), got {len(v)}')
    return tuple(_number(f'{where}[{i}]', x, lo, hi) for i, x in enumerate(v))


_UNIT_KEYS = {
    'azimuth_deg',
    'elevation_deg',
    'channels_deg',
    'acceptance_deg',
    'gains',
    'gains_sigma',
    'enabled',
    'name',
    'dark_offset',
}
_TOP_KEYS = {'units', 'angle_zero', 'angle_sense', 'name', 'notes', 'mount', 'saturation'}


def _unit(i: int, d) -> UnitGeometry:
    where = f'units[{i}]'
    if not isinstance(d, dict):
        raise ArrayGeometryError(
            f'{where} must be a mapping with azimuth_deg, elevation_deg, channels_deg, '
            f'acceptance_deg'
        )
    unknown = sorted(set(map(str, d)) - _UNIT_KEYS)
    if unknown:
        raise ArrayGeometryError(
            f'{where}: unknown key(s) {", ".join(unknown)}; known: {", ".join(sorted(_UNIT_KEYS))}'
        )
    for k in ('azimuth_deg', 'elevation_deg', 'channels_deg', 'acceptance_deg'):
        if k not in d:
            raise ArrayGeometryError(f'{where}: missing {k}')
    az = _number(f'{where}.azimuth_deg', d['azimuth_deg'], -360.0, 360.0)
    el = _number(f'{where}.elevation_deg', d['elevation_deg'], -90.0, 90.0)
    ch = d['channels_deg']
    if not isinstance(ch, (list, tuple)) or not (MIN_CHANNELS <= len(ch) <= MAX_CHANNELS):
        raise ArrayGeometryError(
            f'{where}.channels_deg must list {MIN_CHANNELS}-{MAX_CHANNELS} polarizer angles, '
            f'got {ch!r}'[:200]
        )
    chans = _numbers(f'{where}.channels_deg', ch, None, -360.0, 360.0)
    folded = [round(c % 180.0, 6) % 180.0 for c in chans]
    if len(set(folded)) != len(folded):
        raise ArrayGeometryError(
            f'{where}.channels_deg has two polarizers at the same angle (mod 180): {list(chans)}'
        )
    acc = _number(f'{where}.acceptance_deg', d['acceptance_deg'], 1e-3, 180.0)
    gains = (
        _numbers(f'{where}.gains', d['gains'], len(chans), 1e-6, 1e6)
        if d.get('gains') is not None
        else (1.0,) * len(chans)
    )
    gs = (
        _numbers(f'{where}.gains_sigma', d['gains_sigma'], len(chans), 0.0, 1e6)
        if d.get('gains_sigma') is not None
        else None
    )
    enabled = d.get('enabled', True)
    if not isinstance(enabled, bool):
        raise ArrayGeometryError(f'{where}.enabled must be true or false, got {enabled!r}')
    dark = (
        _numbers(f'{where}.dark_offset', d['dark_offset'], len(chans), -1e9, 1e9)
        if d.get('dark_offset') is not None
        else None
    )
    return UnitGeometry(az, el, chans, acc, gains, gs, enabled, dark)


def _saturation(where: str, v) -> list:
    """Validate ``saturation``: one number h (limits -h, h) or [low, high]."""
    if isinstance(v, (list, tuple)):
        if len(v) != 2:
            raise ArrayGeometryError(f'{where}: saturation must be one number or [low, high]')
        lo, hi = _numbers(f'{where}: saturation', v, None, -1e12, 1e12)
    else:
        hi = _number(f'{where}: saturation', v, 1e-12, 1e12)
        lo = -hi
    if not lo < hi:
        raise ArrayGeometryError(f'{where}: saturation must be [low, high] with low < high')
    return [lo, hi]


def geometry_from_dict(d, where: str = 'array geometry') -> ArrayGeometry:
    """
    Validate a parsed sensor description and build the geometry.

    Parameters
    ----------
    d : dict
        The YAML mapping (see the module docstring for the keys).
    where : str, optional
        Name of the source, for the error messages.

    Returns
    -------
    ArrayGeometry
        The validated geometry.

    Raises
    ------
    ArrayGeometryError
        One line naming the key that is missing, unknown or out of range.

    """
    if not isinstance(d, dict):
        raise ArrayGeometryError(
            f"{where}: expected a mapping with 'units', 'angle_zero', 'angle_sense'"
        )
    unknown = sorted(set(map(str, d)) - _TOP_KEYS)
    if unknown:
        raise ArrayGeometryError(
            f'{where}: unknown key(s) {", ".join(unknown)}; known: {", ".join(sorted(_TOP_KEYS))}'
        )
    for k in ('units', 'angle_zero', 'angle_sense'):
        if k not in d:
            raise ArrayGeometryError(f'{where}: missing {k}')
    if d['angle_zero'] not in ANGLE_ZEROS:
        raise ArrayGeometryError(
            f'{where}: angle_zero must be one of {", ".join(ANGLE_ZEROS)}, got {d["angle_zero"]!r}'
        )
    if d['angle_sense'] not in ANGLE_SENSES:
        raise ArrayGeometryError(
            f'{where}: angle_sense must be one of {", ".join(ANGLE_SENSES)}, '
            f'got {d["angle_sense"]!r}'
        )
    units = d['units']
    if not isinstance(units, list) or not (1 <= len(units) <= MAX_UNITS):
        n = len(units) if isinstance(units, list) else type(units).__name__
        raise ArrayGeometryError(f'{where}: units must be a list of 1-{MAX_UNITS} units, got {n}')
    parsed = tuple(_unit(i, u) for i, u in enumerate(units))
    extra = {k: d[k] for k in ('name', 'notes') if k in d}
    if d.get('saturation') is not None:
        extra['saturation'] = _saturation(where, d['saturation'])
    try:
        mount = mount_from_dict(d['mount'], f'{where}: mount') if 'mount' in d else None
    except MountError as exc:
        raise ArrayGeometryError(str(exc)) from None
    return ArrayGeometry(parsed, d['angle_zero'], d['angle_sense'], extra, mount)


def load_array_geometry(path) -> ArrayGeometry:
    """
    Read and validate a sensor description YAML file.

    Parameters
    ----------
    path : str or path-like
        The YAML file (safe loader; at most 1e6 characters).

    Returns
    -------
    ArrayGeometry
        The validated geometry.

    Raises
    ------
    ArrayGeometryError
        Missing, unreadable, too large or invalid file (one line).

    """
    text = read_text(path, ArrayGeometryError, 'array geometry')
    if len(text) > _MAX_TEXT:
        raise ArrayGeometryError(
            f'array geometry {str(path)!r}: {len(text)} characters, more than {_MAX_TEXT}'
        )
    return geometry_from_dict(load_yaml(text, str(path), ArrayGeometryError), str(path))


def geometry_to_dict(g: ArrayGeometry) -> dict:
    """
    Return the YAML mapping of a geometry (round-trips through :func:`geometry_from_dict`).

    Parameters
    ----------
    g : ArrayGeometry
        The geometry.

    Returns
    -------
    dict
        ``angle_zero``, ``angle_sense``, ``units`` (with gains, and gains_sigma / enabled when
        set), ``mount`` when there is one.

    """
    units = []
    for u in g.units:
        d = {
            'azimuth_deg': u.azimuth_deg,
            'elevation_deg': u.elevation_deg,
            'channels_deg': list(u.channels_deg),
            'acceptance_deg': u.acceptance_deg,
            'gains': [float(v) for v in u.gains],
        }
        if u.gains_sigma is not None:
            d['gains_sigma'] = [float(v) for v in u.gains_sigma]
        if not u.enabled:
            d['enabled'] = False
        if u.dark_offset is not None:
            d['dark_offset'] = [float(v) for v in u.dark_offset]
        units.append(d)
    out = dict(g.extra)
    out.update({'angle_zero': g.angle_zero, 'angle_sense': g.angle_sense, 'units': units})
    if g.mount is not None:
        out['mount'] = mount_to_dict(g.mount)
    return out
