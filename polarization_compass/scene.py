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
Scenes: what a render simulates, declared in YAML (loaded with ``yaml.safe_load`` only).

A scene names the site and time (or a fixed sun), the camera, the attitude, the pixels wanted,
the sky model, an optional radiance model and each sensor effect. Anything not declared is not
computed: an ideal scene never touches the sensor code, a scene without ``radiance`` never
evaluates a radiance model, and a sparse ``pixels`` selection renders only those pixels.

Schema (every key optional; defaults are the paper's set-up, see ``data/default_scene.yaml``)::

    name: str
    site: {latitude_deg, longitude_deg, altitude_m}
    time_utc: ISO 8601 (UTC; 'Z' or an offset)
    sun: {model: spa|paper}  or  {azimuth_deg, altitude_deg}   # fixed sun, no ephemeris
    attitude: {bearing_deg, pitch_deg, roll_deg}   # bearing of camera +y, clockwise from N
    camera: {model, width_px, height_px, focal_length_mm, pixel_pitch_x_um, pixel_pitch_y_um, ...}
    pixels: {mode: full} | {mode: stride, stride: N} | {mode: grid, nx, ny}
            | {mode: region, x0, y0, width, height[, stride]}
    sky: {model: rayleigh, dop_max: 1.0}
         | {model: berry_dennis_lee, separation_deg: ..., dop_max: ...}
    radiance: null | {model: cie_clear, ...}
    validity: {sun_exclusion_deg, min_altitude_deg, min_dop}
    sensor: {} | {mosaic: {...}, shot_noise: {...}, read_noise: {...}, quantization: {...},
                  extinction_ratio: {...}, demosaic: superpixel|bilinear}
    photodiode_array: null | {geometry: <mapping or YAML path>, brightness, noise_rel, integrate}
                       # a photodiode-array compass beside the camera (docs/photodiode-arrays.md)
    atmosphere: null | {clouds: {...}, haze: {turbidity}, skyline: {...}}   # see atmosphere.py
    optics: null | {sun: {...}, flare: {...}, vignetting: {...}}            # see optics.py
    seed: int
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
import datetime as _dt

from .camera import CameraModel
from .camera_pixels import PixelSelection
from .conventions import CameraAttitude
from .errors import CompassError

__all__ = [
    'Scene',
    'Site',
    'Validity',
    'SceneError',
    'parse_time_utc',
]


class SceneError(CompassError):
    """A scene file or mapping that cannot be used; the message names the key."""


@dataclass(frozen=True)
class Site:
    """
    Hold the observer's geodetic position; the defaults are the paper's site in Nanjing.

    Parameters
    ----------
    latitude_deg : float, default 32.026778
        Geodetic latitude [deg, north positive], in [-90, 90].
    longitude_deg : float, default 118.853306
        Longitude [deg, east positive], in [-180, 180].
    altitude_m : float, default 30
        Height above sea level [m].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4.

    """

    latitude_deg: float = 32.026778  # 32 deg 01' 36.4" N (paper, section 4)
    longitude_deg: float = 118.853306  # 118 deg 51' 11.9" E
    altitude_m: float = 30.0


@dataclass(frozen=True)
class Validity:
    """
    Which rendered pixels are usable.

    Those not within ``sun_exclusion_deg`` of the sun, at or above ``min_altitude_deg``, and with
    DoP >= ``min_dop``.
    """

    sun_exclusion_deg: float = 3.0
    min_altitude_deg: float = 0.0
    min_dop: float = 0.0


@dataclass(frozen=True)
class Scene:
    """
    Hold everything a render simulates; build one with :func:`scene_from_dict`.

    Only declared stages are computed (see the module docstring for the YAML schema).

    Parameters
    ----------
    name : str, default "paper_nanjing"
        Name recorded in each frame's metadata.
    site : Site
        Observer's latitude, longitude [deg] and altitude [m].
    time_utc : datetime.datetime
        Aware UTC time of the scene (default 2019-11-15 06:00 UTC).
    sun_model : {"spa", "paper"}, default "spa"
        Ephemeris: NREL SPA (through pvlib) or the paper's eqs 2-10.
    sun_fixed : tuple of float, optional
        ``(azimuth_deg, altitude_deg)`` of a fixed sun [deg, azimuth clockwise from North]; no
        ephemeris when given.
    attitude : CameraAttitude
        Camera bearing, pitch and roll [deg] (eq 21).
    camera : CameraModel
        Camera intrinsics (default the paper's imager, Table 1).
    pixels : PixelSelection
        Pixels to render.
    sky : dict
        Sky polarization model and its parameters, e.g. ``{'model': 'rayleigh', 'dop_max': 1}``.
    radiance : dict, optional
        Radiance model, None for none.
    validity : Validity
        Which rendered pixels are usable.
    sensor : dict
        Sensor effects by name (empty for an ideal sensor).
    seed : int, default 0
        Seed of the scene's noise, clouds and readings.
    photodiode_array, atmosphere, optics : dict, optional
        Photodiode-array compass, atmosphere (clouds, haze, skyline) and lens optics, each
        rendered only when declared.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4, Table 1, eqs 2-10
       and 21.

    """

    name: str = 'paper_nanjing'
    site: Site = Site()
    time_utc: _dt.datetime = _dt.datetime(2019, 11, 15, 6, 0, 0, tzinfo=_dt.timezone.utc)
    sun_model: str = 'spa'
    sun_fixed: tuple[float, float] | None = None  # (azimuth_deg, altitude_deg)
    attitude: CameraAttitude = CameraAttitude(0.0, 0.0, 0.0)
    camera: CameraModel = CameraModel()
    pixels: PixelSelection = PixelSelection()
    sky: dict = field(default_factory=lambda: {'model': 'rayleigh', 'dop_max': 1.0})
    radiance: dict | None = None
    validity: Validity = Validity()
    sensor: dict = field(default_factory=dict)
    seed: int = 0
    photodiode_array: dict | None = None  # rendered only when declared
    atmosphere: dict | None = None  # clouds / haze / skyline, applied only when declared
    optics: dict | None = None  # sun glare / flare ghosts / vignetting, only when declared

    def __hash__(self):  # dict fields: hash by identity is enough for caching per scene object
        return id(self)

    def replace(self, **changes) -> 'Scene':
        """
        Return a copy of the scene with some fields changed.

        Parameters
        ----------
        **changes
            Field names of :class:`Scene` and their new values (not validated again).

        Returns
        -------
        Scene
            The new scene; this one is unchanged.

        """
        return dataclasses.replace(self, **changes)

    @property
    def effects(self) -> list[str]:
        """Sensor effects the scene declares (empty for an ideal sensor)."""
        return [k for k in self.sensor if k != 'demosaic']

    def to_dict(self) -> dict:
        """
        Return the scene as a mapping in the YAML schema of this module.

        Returns
        -------
        dict
            Plain values (time as ISO 8601 with ``Z``, angles [deg], altitude [m]) that
            :func:`scene_from_dict` reads back into an equal scene; a pixel list is summarised by
            its count only.

        """
        d = {
            'name': self.name,
            'site': dataclasses.asdict(self.site),
            'time_utc': self.time_utc.isoformat().replace('+00:00', 'Z'),
            'sun': (
                {'azimuth_deg': self.sun_fixed[0], 'altitude_deg': self.sun_fixed[1]}
                if self.sun_fixed
                else {'model': self.sun_model}
            ),
            'attitude': {
                'bearing_deg': self.attitude.bearing_deg,
                'pitch_deg': self.attitude.pitch_deg,
                'roll_deg': self.attitude.roll_deg,
            },
            'camera': {k: v for k, v in dataclasses.asdict(self.camera).items() if v is not None},
            'pixels': _pixels_to_dict(self.pixels),
            'sky': dict(self.sky),
            'radiance': dict(self.radiance) if self.radiance else None,
            'validity': dataclasses.asdict(self.validity),
            'sensor': dict(self.sensor),
            'seed': self.seed,
        }
        if self.photodiode_array is not None:
            d['photodiode_array'] = dict(self.photodiode_array)
        if self.atmosphere is not None:
            d['atmosphere'] = dict(self.atmosphere)
        if self.optics is not None:
            d['optics'] = dict(self.optics)
        return d


def parse_time_utc(value) -> _dt.datetime:
    """
    Convert an ISO 8601 string or datetime to an aware UTC datetime.

    Naive input is taken as UTC; a ``Z`` suffix means UTC; a date is its midnight UTC.

    Parameters
    ----------
    value : str or datetime.datetime or datetime.date
        The time, e.g. ``'2019-11-15T06:00:00Z'``.

    Returns
    -------
    datetime.datetime
        The same instant, timezone-aware, in UTC.

    Raises
    ------
    SceneError
        When a string is not ISO 8601, or the value is of another type.

    """
    if isinstance(value, _dt.datetime):
        t = value
    elif isinstance(value, _dt.date):
        t = _dt.datetime(value.year, value.month, value.day)
    elif isinstance(value, str):
        s = value.strip()
        if s.endswith('Z') or s.endswith('z'):
            s = s[:-1] + '+00:00'
        try:
            t = _dt.datetime.fromisoformat(s)
        except ValueError:
            raise SceneError(
                f'time {value!r} is not ISO 8601 (e.g. 2019-11-15T06:00:00Z)'
            ) from None
    else:
        raise SceneError(f'time must be an ISO 8601 string, got {type(value).__name__}')
    if t.tzinfo is None:
        t = t.replace(tzinfo=_dt.timezone.utc)
    return t.astimezone(_dt.timezone.utc)


def _pixels_to_dict(p: PixelSelection) -> dict:
    if p.mode == 'stride':
        return {'mode': 'stride', 'stride': p.stride}
    if p.mode == 'grid':
        return {'mode': 'grid', 'nx': p.nx, 'ny': p.ny}
    if p.mode == 'region':
        x0, y0, w, h = p.region
        return {'mode': 'region', 'x0': x0, 'y0': y0, 'width': w, 'height': h, 'stride': p.stride}
    if p.mode == 'list':
        return {'mode': 'list', 'count': len(p.x_list) // 4}
    return {'mode': 'full'}
