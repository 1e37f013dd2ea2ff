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
Reading a scene: from a mapping in the YAML schema, or from a YAML file.

:func:`scene_from_dict` checks every key and value of a scene mapping (the schema is in
:mod:`.scene`'s docstring) and builds the :class:`.scene.Scene`, with the stages it declares
validated once; :func:`load_scene` reads a YAML file (``yaml.safe_load`` only) and
:func:`default_scene` the paper's set-up (``data/default_scene.yaml``).
"""

from __future__ import annotations

import dataclasses
from importlib import resources
import math
from pathlib import Path

from .camera import CameraError, CameraModel
from .camera_pixels import PixelSelection
from .conventions import CameraAttitude
from .safe_load import load_yaml, read_text
from .scene import parse_time_utc, Scene, SceneError, Site, Validity


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
