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
What an error budget is asked: its configuration, the declared sources and their switches.

:class:`BudgetConfig` (a scene, the sampling, the IMU/mounting errors, the correction) and its
checks (:func:`check_config`, :func:`parse_imu` for ``--imu``); :func:`declared_sources` names the
error sources a configuration declares (:data:`SOURCES`) and :func:`without` switches one off, as
the breakdown of :func:`polarization_compass.budget.run_budget` does.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

from .errors import CompassError
from .motion import MountingErrors
from .scene import Scene

__all__ = [
    'BudgetError',
    'BudgetConfig',
    'MAX_BUDGET_PIXELS',
    'SOURCES',
    'check_config',
    'declared_sources',
    'parse_imu',
    'published_sigma_floor_deg',
    'without',
]

_NOISE_KEYS = ('shot_noise', 'read_noise', 'quantization')
SOURCES = (
    'noise',
    'calibration',
    'clouds',
    'haze',
    'skyline',
    'ground',
    'optics',
    'sky_model',
    'tilt',
    'imu',
    'boresight',
)


class BudgetError(CompassError):
    """Unusable budget input (no method, bad --imu, no samples)."""


def published_sigma_floor_deg() -> float:
    """
    Return heading_estimator's default ``sigma_floor_deg`` (specs/params/).

    Returns
    -------
    float
        The smallest yaw sigma the node publishes [deg]: the model error of real skies.

    """
    from .specs.params import defaults, ESTIMATOR

    return float(defaults(ESTIMATOR)['sigma_floor_deg'])


@dataclass(frozen=True)
class BudgetConfig:
    """
    What an error budget runs: a scene, the sampling and the IMU/mounting errors.

    Attributes
    ----------
    scene : Scene
        The scene (site, time/sun, camera, sky, atmosphere, optics, sensor); its seed seeds the
        samples.
    samples : int, default 50
        Monte Carlo frames per condition.
    tilt_max_deg : float, default 0
        Largest ``|pitch| + |roll|`` of the sampled attitudes [deg]; 0 keeps the camera level.
    imu : MountingErrors, default no errors
        IMU and mounting errors applied to the pitch and roll that tilt-aware methods read.
    methods : tuple of str, default ()
        Method names of the estimator registry to run; empty runs every registered method.
    correction : {"error_map", "none"}, default "error_map"
        What the graph's ``tilt_corrector`` does to methods that do not read the tilt: invert
        their tilt error with the error map at the IMU's (erroneous) pitch and roll, or nothing
        (their raw tilt error).
    error_map : str, optional
        The error map ``.npz``; None = the map shipped with the package.
    correction_sigma_deg : float, default 0
        1-sigma of the map's own error for this camera and sky [deg] (interpolation and a map made
        for another camera), added in quadrature to corrected methods' sigmas, as the node's
        ``correction_sigma_deg`` parameter.
    sigma_floor_deg : float, default: heading_estimator's ``sigma_floor_deg`` (0.01)
        The smallest sigma a node publishes (the model error of real skies); the sigma
        calibration is computed with ``max(sigma, floor)``, what a robot receives
        (``sigma_calibration_raw`` without it).

    """

    scene: Scene
    samples: int = 50
    tilt_max_deg: float = 0.0
    imu: MountingErrors = MountingErrors()
    methods: tuple = ()
    correction: str = 'error_map'
    error_map: str | None = None
    correction_sigma_deg: float = 0.0
    sigma_floor_deg: float = field(default_factory=published_sigma_floor_deg)


def parse_imu(text: str | None) -> MountingErrors:
    """
    Parse ``key=value,...`` into :class:`MountingErrors`.

    Keys are the fields of :class:`~polarization_compass.motion.MountingErrors` (angles [deg],
    ``time_offset_s`` [s], ``tilt_rate_deg_s`` [deg/s]), plus ``bias_deg`` (sets both tilt biases)
    and ``boresight_deg`` (sets the roll and pitch boresight). Empty parts are skipped.

    Parameters
    ----------
    text : str or None
        The ``--imu`` argument, e.g. ``"noise_deg=0.5,bias_deg=0.2"``; None or empty for no
        errors.

    Returns
    -------
    MountingErrors
        The parsed errors.

    Raises
    ------
    BudgetError
        For a part without ``=``, a value that is not a number, an unknown key, or values that
        :class:`MountingErrors` rejects.

    """
    if not text:
        return MountingErrors()
    vals = {}
    for part in text.split(','):
        if not part.strip():
            continue
        if '=' not in part:
            raise BudgetError(f'--imu: expected key=value, got {part!r}')
        k, v = (s.strip() for s in part.split('=', 1))
        try:
            f = float(v)
        except ValueError:
            raise BudgetError(f'--imu: {k} must be a number, got {v!r}') from None
        if k == 'bias_deg':
            vals.update(pitch_bias_deg=f, roll_bias_deg=f)
        elif k == 'boresight_deg':
            vals.update(boresight_roll_deg=f, boresight_pitch_deg=f)
        elif k in MountingErrors.FIELDS:
            vals[k] = f
        else:
            raise BudgetError(
                f'--imu: unknown key {k!r}; known: bias_deg, boresight_deg, '
                f'{", ".join(MountingErrors.FIELDS)}'
            )
    try:
        return MountingErrors(**vals)
    except ValueError as exc:
        raise BudgetError(f'--imu: {exc}') from None


def declared_sources(cfg: BudgetConfig) -> list[str]:
    """
    Return the sources of error the configuration declares, in :data:`SOURCES` order.

    Parameters
    ----------
    cfg : BudgetConfig
        The budget configuration.

    Returns
    -------
    list of str
        The names of :data:`SOURCES` that are switched on: sensor noise keys, DoFP calibration,
        clouds, haze, skyline, ground, optics, a non-Rayleigh sky model, ``tilt_max_deg > 0``,
        IMU errors, boresight errors.

    """
    s = cfg.scene
    atm = s.atmosphere or {}
    on = {
        'noise': any(k in s.sensor for k in _NOISE_KEYS),
        'calibration': 'calibration' in s.sensor,
        'clouds': atm.get('clouds') is not None,
        'haze': atm.get('haze') is not None,
        'skyline': atm.get('skyline') is not None,
        'ground': atm.get('ground') is not None,
        'optics': bool(s.optics),
        'sky_model': (s.sky or {}).get('model', 'rayleigh') != 'rayleigh',
        'tilt': cfg.tilt_max_deg > 0,
        'imu': cfg.imu.has_imu,
        'boresight': cfg.imu.has_boresight,
    }
    return [k for k in SOURCES if on[k]]


def without(cfg: BudgetConfig, source: str) -> BudgetConfig:
    """
    Return the configuration with ``source`` switched off.

    ``sky_model`` is replaced by the Rayleigh sky of the same ``dop_max``; ``tilt`` sets
    ``tilt_max_deg`` to 0; the others drop their sensor keys, atmosphere entry, optics or IMU
    errors.

    Parameters
    ----------
    cfg : BudgetConfig
        The budget configuration.
    source : str
        One of :data:`SOURCES`.

    Returns
    -------
    BudgetConfig
        A new configuration; ``cfg`` is unchanged.

    Raises
    ------
    BudgetError
        When ``source`` is not one of :data:`SOURCES`.

    """
    import dataclasses

    s = cfg.scene
    if source == 'noise':
        return dataclasses.replace(
            cfg,
            scene=s.replace(sensor={k: v for k, v in s.sensor.items() if k not in _NOISE_KEYS}),
        )
    if source == 'calibration':
        return dataclasses.replace(
            cfg, scene=s.replace(sensor={k: v for k, v in s.sensor.items() if k != 'calibration'})
        )
    if source in ('clouds', 'haze', 'skyline', 'ground'):
        atm = {k: v for k, v in (s.atmosphere or {}).items() if k != source}
        return dataclasses.replace(cfg, scene=s.replace(atmosphere=atm or None))
    if source == 'optics':
        return dataclasses.replace(cfg, scene=s.replace(optics=None))
    if source == 'sky_model':
        return dataclasses.replace(
            cfg,
            scene=s.replace(
                sky={'model': 'rayleigh', 'dop_max': float(s.sky.get('dop_max', 1.0))}
            ),
        )
    if source == 'tilt':
        return dataclasses.replace(cfg, tilt_max_deg=0.0)
    if source in ('imu', 'boresight'):
        return dataclasses.replace(cfg, imu=cfg.imu.without(source))
    raise BudgetError(f'unknown source {source!r}')


#: Largest camera a budget renders: 2^25 pixels per frame, as a frame file
#: (:data:`~polarization_compass.frame_io.MAX_FRAME_PIXELS`).
MAX_BUDGET_PIXELS = 1 << 25


def check_config(cfg: BudgetConfig) -> list:
    """
    Check a budget's configuration before anything is computed; return its methods.

    Parameters
    ----------
    cfg : BudgetConfig
        The configuration.

    Returns
    -------
    list of str
        The methods to run (all registered ones when ``cfg.methods`` is empty).

    Raises
    ------
    BudgetError
        No samples, an unknown method or correction, a negative or non-finite sigma, negative IMU
        noise, or a camera of more than :data:`MAX_BUDGET_PIXELS` pixels (a frame of it would take
        gigabytes).

    """
    from .estimators import registry

    if cfg.samples < 1:
        raise BudgetError('samples must be >= 1')
    methods = list(cfg.methods) or list(registry.names())
    unknown = [m for m in methods if m not in registry.names()]
    if unknown:
        raise BudgetError(f'unknown method(s) {unknown}; known: {", ".join(registry.names())}')
    if cfg.correction not in ('error_map', 'none'):
        raise BudgetError(f"correction must be 'error_map' or 'none', got {cfg.correction!r}")
    if not (math.isfinite(cfg.correction_sigma_deg) and cfg.correction_sigma_deg >= 0.0):
        raise BudgetError(f'correction_sigma_deg must be >= 0, got {cfg.correction_sigma_deg}')
    if not (math.isfinite(cfg.sigma_floor_deg) and cfg.sigma_floor_deg >= 0.0):
        raise BudgetError(f'sigma_floor_deg must be >= 0, got {cfg.sigma_floor_deg}')
    if cfg.imu.noise_deg < 0.0:
        raise BudgetError(f'--imu: noise_deg is a 1-sigma, >= 0; got {cfg.imu.noise_deg}')
    cam = cfg.scene.camera
    if int(cam.width_px) * int(cam.height_px) > MAX_BUDGET_PIXELS:
        raise BudgetError(
            f'the scene camera has {cam.width_px} x {cam.height_px} pixels, more than the '
            f'{MAX_BUDGET_PIXELS} a budget renders; use a smaller (binned) camera'
        )
    return methods
