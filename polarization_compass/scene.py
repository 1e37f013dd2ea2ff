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
from importlib import resources
import math
from pathlib import Path

from .camera import CameraError, CameraModel
from .camera_pixels import PixelSelection
from .conventions import CameraAttitude
from .errors import CompassError
from .safe_load import load_yaml, read_text

__all__ = [
    'Scene',
    'Site',
    'Validity',
    'SceneError',
    'load_scene',
    'default_scene',
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


def _num(mapping: dict, key: str, default, lo=-math.inf, hi=math.inf, where='') -> float:
    v = mapping.get(key, default)
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise SceneError(f'{where}{key} must be a number, got {v!r}') from None
    if not math.isfinite(f) or not (lo <= f <= hi):
        raise SceneError(f'{where}{key} must be finite and in [{lo}, {hi}], got {v!r}')
    return f


def _check_keys(mapping, allowed, where):
    if not isinstance(mapping, dict):
        raise SceneError(f'{where.rstrip(".")} must be a mapping, got {type(mapping).__name__}')
    unknown = set(mapping) - set(allowed)
    if unknown:
        raise SceneError(
            f'unknown key(s) {sorted(unknown)} in {where.rstrip(".") or "scene"}; '
            f'allowed: {sorted(allowed)}'
        )


def _pixels_from_dict(d: dict) -> PixelSelection:
    _check_keys(d, {'mode', 'stride', 'nx', 'ny', 'x0', 'y0', 'width', 'height'}, 'pixels.')
    mode = d.get('mode', 'full')
    if mode == 'full':
        return PixelSelection.full()
    if mode == 'stride':
        return PixelSelection.strided(int(_num(d, 'stride', 1, 1, 20000, 'pixels.')))
    if mode == 'grid':
        return PixelSelection.grid(
            int(_num(d, 'nx', 96, 1, 20000, 'pixels.')),
            int(_num(d, 'ny', 80, 1, 20000, 'pixels.')),
        )
    if mode == 'region':
        return PixelSelection.rect(
            *(int(_num(d, k, None, 1, 20000, 'pixels.')) for k in ('x0', 'y0', 'width', 'height')),
            stride=int(_num(d, 'stride', 1, 1, 20000, 'pixels.')),
        )
    raise SceneError(f'pixels.mode must be full|stride|grid|region, got {mode!r}')


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


def scene_from_dict(d: dict) -> Scene:
    """
    Validate a scene mapping (as from YAML) and build a :class:`Scene`.

    Every key is optional (the defaults are :class:`Scene`'s); numbers are checked for range,
    and the sky, radiance, sensor, photodiode-array, atmosphere and optics declarations are built
    once so that a bad parameter fails here, not at the first frame.

    Parameters
    ----------
    d : dict or None
        The mapping in the module's schema; None is the default scene.

    Returns
    -------
    Scene
        The validated scene.

    Raises
    ------
    SceneError
        Naming the key, for an unknown key, a value of the wrong type or out of range, or a
        declaration its model refuses.

    """
    if d is None:
        d = {}
    _check_keys(d, _SCENE_KEYS, '')
    base = Scene()
    site = _site_from_dict(d.get('site', {}) or {}, base.site)
    t = parse_time_utc(d['time_utc']) if 'time_utc' in d else base.time_utc
    sun_model, sun_fixed = _sun_from_dict(d.get('sun', {}) or {})
    att = _attitude_from_dict(d.get('attitude', {}) or {})
    cam = _camera_from_dict(d.get('camera', {}) or {})
    pixels = _pixels_from_dict(d.get('pixels', {}) or {})
    sky, radiance = _sky_and_radiance(d)
    validity = _validity_from_dict(d.get('validity', {}) or {}, base.validity)
    sensor = d.get('sensor') or {}
    if not isinstance(sensor, dict):
        raise SceneError('sensor must be a mapping of effect name to its parameters')
    seed = int(_num(d, 'seed', 0, 0, 2**32 - 1))
    scene = Scene(
        str(d.get('name', base.name)),
        site,
        t,
        sun_model,
        sun_fixed,
        att,
        cam,
        pixels,
        sky,
        radiance,
        validity,
        dict(sensor),
        seed,
    )
    scene = _with_stages(scene, d, seed, cam)
    _check_models(scene, pixels)
    return scene


#: The keys a scene mapping may hold.
_SCENE_KEYS = {
    'name',
    'site',
    'time_utc',
    'sun',
    'attitude',
    'camera',
    'pixels',
    'sky',
    'radiance',
    'validity',
    'sensor',
    'seed',
    'photodiode_array',
    'atmosphere',
    'optics',
}


def _site_from_dict(site_d: dict, default: Site) -> Site:
    """Return the ``site`` mapping's :class:`Site`, missing keys from ``default``."""
    _check_keys(site_d, {'latitude_deg', 'longitude_deg', 'altitude_m'}, 'site.')
    return Site(
        _num(site_d, 'latitude_deg', default.latitude_deg, -90, 90, 'site.'),
        _num(site_d, 'longitude_deg', default.longitude_deg, -180, 180, 'site.'),
        _num(site_d, 'altitude_m', default.altitude_m, -500, 10000, 'site.'),
    )


def _sun_from_dict(sun_d: dict) -> tuple:
    """Return the ``sun`` mapping's (model, fixed (azimuth_deg, altitude_deg) or None)."""
    _check_keys(sun_d, {'model', 'azimuth_deg', 'altitude_deg'}, 'sun.')
    sun_fixed = None
    sun_model = sun_d.get('model', 'spa')
    if sun_model not in ('spa', 'paper'):
        raise SceneError(f"sun.model must be 'spa' or 'paper', got {sun_model!r}")
    if 'azimuth_deg' in sun_d or 'altitude_deg' in sun_d:
        if not ('azimuth_deg' in sun_d and 'altitude_deg' in sun_d):
            raise SceneError('a fixed sun needs both sun.azimuth_deg and sun.altitude_deg')
        sun_fixed = (
            _num(sun_d, 'azimuth_deg', 0, -360, 720, 'sun.'),
            _num(sun_d, 'altitude_deg', 0, -90, 90, 'sun.'),
        )
    return sun_model, sun_fixed


def _attitude_from_dict(att_d: dict) -> CameraAttitude:
    """Return the ``attitude`` mapping's :class:`CameraAttitude` (0 for a missing angle)."""
    _check_keys(att_d, {'bearing_deg', 'pitch_deg', 'roll_deg'}, 'attitude.')
    return CameraAttitude(
        _num(att_d, 'bearing_deg', 0.0, -360, 720, 'attitude.'),
        _num(att_d, 'pitch_deg', 0.0, -90, 90, 'attitude.'),
        _num(att_d, 'roll_deg', 0.0, -180, 180, 'attitude.'),
    )


def _camera_from_dict(cam_d: dict) -> CameraModel:
    """Return the ``camera`` mapping's :class:`CameraModel`; its own errors become SceneError."""
    allowed = {f.name for f in dataclasses.fields(CameraModel)}
    _check_keys(cam_d, allowed, 'camera.')
    try:
        # 2448.0 is a whole number of pixels; true, "2448" or 2448.5 are not (CameraModel says
        # which field)
        return CameraModel(
            **{
                k: (
                    int(v)
                    if k in ('width_px', 'height_px') and isinstance(v, float) and v.is_integer()
                    else v
                )
                for k, v in cam_d.items()
            }
        )
    except (CameraError, TypeError, ValueError) as exc:
        raise SceneError(f'camera: {exc}') from None


def _sky_and_radiance(d: dict) -> tuple:
    """Return copies of the ``sky`` and ``radiance`` (or None) mappings, type-checked."""
    sky = d.get('sky') or {'model': 'rayleigh', 'dop_max': 1.0}
    if not isinstance(sky, dict):
        raise SceneError('sky must be a mapping such as {model: rayleigh, dop_max: 1.0}')
    radiance = d.get('radiance')
    if radiance is not None and not isinstance(radiance, dict):
        raise SceneError('radiance must be null or a mapping such as {model: cie_clear}')
    return dict(sky), (dict(radiance) if radiance else None)


def _validity_from_dict(val_d: dict, default: Validity) -> Validity:
    """Return the ``validity`` mapping's :class:`Validity`, missing keys from ``default``."""
    _check_keys(val_d, {'sun_exclusion_deg', 'min_altitude_deg', 'min_dop'}, 'validity.')
    return Validity(
        _num(val_d, 'sun_exclusion_deg', default.sun_exclusion_deg, 0, 90, 'validity.'),
        _num(val_d, 'min_altitude_deg', default.min_altitude_deg, -90, 90, 'validity.'),
        _num(val_d, 'min_dop', default.min_dop, 0, 1, 'validity.'),
    )


def _with_stages(scene: Scene, d: dict, seed: int, cam: CameraModel) -> Scene:
    """Return ``scene`` with its declared photodiode array, atmosphere and optics, built once."""
    if d.get('photodiode_array') is not None:
        from .photodiode.geometry import ArrayGeometryError
        from .photodiode.simulate import ArraySensor

        try:
            ArraySensor.from_config(d['photodiode_array'])
        except ArrayGeometryError as exc:
            raise SceneError(str(exc)) from None
        scene = scene.replace(photodiode_array=dict(d['photodiode_array']))
    if d.get('atmosphere') is not None:
        from .atmosphere import Atmosphere, AtmosphereError

        try:
            Atmosphere(d['atmosphere'], seed)
        except (AtmosphereError, TypeError) as exc:
            raise SceneError(str(exc)) from None
        scene = scene.replace(atmosphere=dict(d['atmosphere']))
    if d.get('optics') is not None:
        from .optics import Optics, OpticsError

        try:
            Optics(d['optics'], cam)
        except (OpticsError, TypeError) as exc:
            raise SceneError(str(exc)) from None
        scene = scene.replace(optics=dict(d['optics']))
    return scene


def _check_models(scene: Scene, pixels: PixelSelection) -> None:
    """Build the sky, sensor and radiance models once: bad parameters fail here, not at a frame."""
    from .sky import SkyModelError
    from .sky_models import make_sky_model

    try:
        make_sky_model(scene.sky)
    except SkyModelError as exc:
        raise SceneError(f'sky: {exc}') from None
    if scene.sensor:
        from .sensor import SensorError, SensorPipeline

        try:
            SensorPipeline.from_config(scene.sensor, scene.camera)
        except SensorError as exc:
            raise SceneError(f'sensor: {exc}') from None
    if scene.effects and (pixels.mode not in ('full', 'region') or pixels.stride > 1):
        raise SceneError(
            f'sensor effects ({", ".join(scene.effects)}) need contiguous pixels (pixels.mode '
            'full, '
            f'or region with stride 1), got pixels {pixels.describe()}'
        )
    if scene.radiance:
        from .radiance import make_radiance_model, RadianceError

        try:
            make_radiance_model(scene.radiance)
        except RadianceError as exc:
            raise SceneError(f'radiance: {exc}') from None


def load_scene(path: str | Path | None = None) -> Scene:
    """
    Load a scene YAML file (safe loader).

    ``None`` gives the embedded default (the paper's set-up).

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The YAML file; None for ``data/default_scene.yaml`` in the package.

    Returns
    -------
    Scene
        The validated scene (see :func:`scene_from_dict`).

    Raises
    ------
    SceneError
        Prefixed with the file name, when the file cannot be read or parsed, or its scene is
        invalid.

    """
    if path is None:
        text = (
            resources.files('polarization_compass').joinpath('data/default_scene.yaml').read_text()
        )
        where = 'embedded default scene'
    else:
        text = read_text(path, SceneError, 'scene file')
        where = str(path)
    data = load_yaml(text, where, SceneError)
    try:
        return scene_from_dict(data)
    except SceneError as exc:
        raise SceneError(f'{where}: {exc}') from None


def default_scene() -> Scene:
    """
    Return the embedded default scene: the paper's set-up in Nanjing.

    Returns
    -------
    Scene
        ``load_scene(None)``: site, time, camera and sky of the paper's section 4.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 4 and Table 1.

    """
    return load_scene(None)
