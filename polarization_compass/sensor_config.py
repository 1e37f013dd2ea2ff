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
Configuration of the sensor effects: a scene's ``sensor:`` mapping, validated.

:func:`parse_sensor_config` turns the mapping (schema in :mod:`polarization_compass.sensor`) into
a :class:`SensorConfig`; :func:`sensor_config_for_encoding` does so for the raw image encoding of
a simulated camera.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .demosaic import check_ifov_k, DEMOSAIC_METHODS, IFOV_K_DEFAULT
from .errors import CompassError
from .mosaic import layout_from_mapping, MosaicLayout, SensorError

__all__ = [
    'EFFECTS',
    'SensorConfig',
    'parse_sensor_config',
    'sensor_config_for_encoding',
]

#: Every key a ``sensor:`` mapping may hold, in pipeline order.
EFFECTS = (
    'mosaic',
    'exposure',
    'extinction_ratio',
    'calibration',
    'shot_noise',
    'read_noise',
    'quantization',
    'demosaic',
    'ifov_check',
)
_BITS = (8, 10, 12, 14, 16)


# ------------------------------------------------------------------------------------------------
# Configuration
# ------------------------------------------------------------------------------------------------
def _params(cfg, name, allowed):
    d = cfg.get(name)
    if d is None:
        return {}
    if not isinstance(d, dict):
        raise SensorError(f'sensor.{name} must be a mapping (e.g. {{}}), got {type(d).__name__}')
    unknown = set(d) - set(allowed)
    if unknown:
        raise SensorError(
            f'unknown key(s) {sorted(unknown)} in sensor.{name}; allowed: {sorted(allowed)}'
        )
    return d


def _number(d, key, default, lo, hi, where, lo_open=False):
    v = d.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise SensorError(f'sensor.{where}.{key} must be a number, got {v!r}')
    f = float(v)
    if not math.isfinite(f) or not ((lo < f) if lo_open else (lo <= f)) or f > hi:
        raise SensorError(
            f'sensor.{where}.{key} must be finite and in {"(" if lo_open else "["}{lo}, {hi}], '
            f'got {v!r}'
        )
    return f


@dataclass(frozen=True)
class SensorConfig:
    """
    Hold validated sensor parameters; ``None`` marks an effect the scene did not declare.

    Built by :func:`parse_sensor_config` (the module docstring gives the schema and the physics).

    Attributes
    ----------
    layout : MosaicLayout
        Polarizer angles of the 2 x 2 mosaic and the direction of its 45 deg polarizer.
    full_well_e : float
        Full-well capacity [electrons]; also the ADC full scale when quantised.
    fill : float
        Mean signal of an unpolarized S0 = 1 pixel as a fraction of the full well.
    extinction_ratio : float or None
        Polarizer extinction ratio ER (> 1); None for ideal polarizers.
    shot_gaussian_above_e : float or None
        Mean [electrons] above which shot noise is drawn Gaussian, not Poisson; None: no shot
        noise.
    read_sigma_e : float or None
        Read noise [electrons rms]; None: no read noise.
    bits : int or None
        ADC bits; None: no quantisation (float32 electrons).
    demosaic : {"bilinear", "superpixel"}
        Demosaic method.
    saturates : bool
        ``exposure`` declared: the well is finite and clips at ``full_well_e``.
    calibration : dict or None
        Per-pixel calibration errors (``angle_error_deg`` [deg], ``extinction_ratio_spread``,
        ``gain_rms``, ``crosstalk`` and ``seed``); None if undeclared.
    ifov_check_k : float
        Threshold [noise sigmas] of the demosaic's IFOV (redundancy) check; 0 = off.

    """

    layout: MosaicLayout
    full_well_e: float
    fill: float
    extinction_ratio: float | None
    shot_gaussian_above_e: float | None
    read_sigma_e: float | None
    bits: int | None
    demosaic: str
    saturates: bool = False  # ``exposure`` declared: the well is finite (clip at full_well_e)
    calibration: dict | None = (
        None  # per-pixel DoFP calibration errors (module docstring), None if undeclared
    )
    ifov_check_k: float = IFOV_K_DEFAULT

    @property
    def d(self) -> float:
        """Polarizer efficiency (ER - 1) / (ER + 1); 1 for an ideal polarizer."""
        er = self.extinction_ratio
        return 1.0 if er is None else (er - 1.0) / (er + 1.0)

    @property
    def n0_e(self) -> float:
        """Mean electrons of an unpolarized pixel at S0 = 1."""
        return self.fill * self.full_well_e

    @property
    def max_dn(self) -> int | None:
        """ADC full scale 2^bits - 1 [DN], or None without quantisation."""
        return None if self.bits is None else (1 << self.bits) - 1

    @property
    def saturation_level(self) -> float | None:
        """
        Return the raw value at which a sample is saturated, or None.

        The ADC's full scale when quantised, the full well when ``exposure`` is declared, else None
        (an unlimited well never saturates).
        """
        if self.bits is not None:
            return float(self.max_dn)
        return self.full_well_e if self.saturates else None

    def describe(self) -> dict:
        """
        Return the parameters as plain values for a frame's metadata.

        Returns
        -------
        dict
            The mosaic layout, exposure (``full_well_e`` [electrons] or None for an unlimited
            well, ``fill``, ``n0_e`` [electrons], saturation, ADC full scale [electrons]),
            extinction ratio, noise parameters [electrons], quantisation bits, demosaic method and
            calibration; None for an effect not declared.

        """
        # exposure.full_well_e is the saturation level of an unquantised mosaic (None: unlimited
        # well); n0_e the electrons of an unpolarized S0 = 1 pixel, the scale of every
        # electron-domain stage
        return {
            'mosaic': self.layout.describe(),
            'exposure': {
                'full_well_e': self.full_well_e if self.saturates else None,
                'fill': self.fill,
                'n0_e': self.n0_e,
                'saturation': self.saturates,
                'adc_full_scale_e': None if self.bits is None else self.full_well_e,
            },
            'extinction_ratio': self.extinction_ratio,
            'shot_noise_gaussian_above_e': self.shot_gaussian_above_e,
            'read_noise_sigma_e': self.read_sigma_e,
            'quantization_bits': self.bits,
            'demosaic': self.demosaic,
            'calibration': None if self.calibration is None else dict(self.calibration),
            'ifov_check_k': self.ifov_check_k,
        }


def parse_sensor_config(cfg: dict) -> SensorConfig:
    """
    Validate a scene's ``sensor:`` mapping (see the module docstring).

    Missing keys take the defaults of a Sony IMX250MZR shown in the module docstring.

    Parameters
    ----------
    cfg : dict or None
        Effect name -> its parameters (``{}`` or None for the defaults); None is no effects.

    Returns
    -------
    SensorConfig
        The validated parameters.

    Raises
    ------
    SensorError
        Naming the key, for an unknown effect or parameter, a number out of range, unsupported
        quantisation bits, an extinction-ratio spread without an extinction ratio, or an unknown
        demosaic method.

    """
    if cfg is None:
        cfg = {}
    if not isinstance(cfg, dict):
        raise SensorError(
            f'sensor must be a mapping of effect name to parameters, got {type(cfg).__name__}'
        )
    unknown = [k for k in cfg if k not in EFFECTS]
    if unknown:
        raise SensorError(
            f'unknown sensor effect(s) {sorted(map(str, unknown))}; known: {", ".join(EFFECTS)}'
        )
    layout = layout_from_mapping(_params(cfg, 'mosaic', ('layout', 'pol45_toward')))
    exp = _params(cfg, 'exposure', ('full_well_e', 'fill'))
    full_well = _number(exp, 'full_well_e', 10500.0, 1.0, 1e8, 'exposure')
    fill = _number(exp, 'fill', 0.5, 0.0, 1000.0, 'exposure', lo_open=True)
    er = _extinction_ratio(cfg)
    shot, read = _noise(cfg)
    bits = _quantization_bits(cfg)
    cal = _calibration(cfg, er)
    method = cfg.get('demosaic', 'bilinear')
    if method is None:
        method = 'bilinear'
    if method not in DEMOSAIC_METHODS:
        raise SensorError(f'sensor.demosaic must be one of {DEMOSAIC_METHODS}, got {method!r}')
    return SensorConfig(
        layout,
        full_well,
        fill,
        er,
        shot,
        read,
        bits,
        method,
        saturates='exposure' in cfg,
        calibration=cal,
        ifov_check_k=_ifov_check_k(cfg),
    )


def _extinction_ratio(cfg: dict) -> float | None:
    """Return ``extinction_ratio.value``, or None when the effect is not declared."""
    if 'extinction_ratio' not in cfg:
        return None
    return _number(
        _params(cfg, 'extinction_ratio', ('value',)),
        'value',
        100.0,
        1.0,
        1e12,
        'extinction_ratio',
        lo_open=True,
    )


def _noise(cfg: dict) -> tuple:
    """Return (shot noise's Gaussian threshold [e-], read noise [e- rms]); None if undeclared."""
    shot = None
    if 'shot_noise' in cfg:
        # Knuth's Poisson method multiplies uniforms down to exp(-lambda): keep lambda where that
        # is exact
        shot = _number(
            _params(cfg, 'shot_noise', ('gaussian_above_e',)),
            'gaussian_above_e',
            20.0,
            0.0,
            200.0,
            'shot_noise',
        )
    read = None
    if 'read_noise' in cfg:
        read = _number(
            _params(cfg, 'read_noise', ('sigma_e',)), 'sigma_e', 2.3, 0.0, 1e6, 'read_noise'
        )
    return shot, read


def _quantization_bits(cfg: dict) -> int | None:
    """Return ``quantization.bits`` (one of ``_BITS``), or None when the effect is not declared."""
    if 'quantization' not in cfg:
        return None
    q = _params(cfg, 'quantization', ('bits',))
    b = q.get('bits', 12)
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or int(b) not in _BITS:
        raise SensorError(f'sensor.quantization.bits must be one of {_BITS}, got {b!r}')
    return int(b)


def _calibration(cfg: dict, er: float | None) -> dict | None:
    """Return the ``calibration`` parameters, or None; a ratio spread needs ``er``."""
    if 'calibration' not in cfg:
        return None
    c = _params(
        cfg,
        'calibration',
        ('angle_error_deg', 'extinction_ratio_spread', 'gain_rms', 'crosstalk', 'seed'),
    )
    cal = {
        'angle_error_deg': _number(c, 'angle_error_deg', 0.0, 0.0, 45.0, 'calibration'),
        'extinction_ratio_spread': _number(
            c, 'extinction_ratio_spread', 0.0, 0.0, 3.0, 'calibration'
        ),
        'gain_rms': _number(c, 'gain_rms', 0.0, 0.0, 0.3, 'calibration'),
        'crosstalk': _number(c, 'crosstalk', 0.0, 0.0, 0.2, 'calibration'),
        'seed': int(_number(c, 'seed', 0, 0, 2**32 - 1, 'calibration')),
    }
    if cal['extinction_ratio_spread'] > 0 and er is None:
        raise SensorError(
            'sensor.calibration.extinction_ratio_spread needs sensor.extinction_ratio (the '
            'mean ratio the spread is around)'
        )
    return cal


def _ifov_check_k(cfg: dict) -> float:
    """Return ``ifov_check.k_sigma`` (the demosaic's default when undeclared)."""
    if 'ifov_check' not in cfg:
        return IFOV_K_DEFAULT
    ic = _params(cfg, 'ifov_check', ('k_sigma',))
    try:
        return check_ifov_k(ic.get('k_sigma', IFOV_K_DEFAULT))
    except SensorError as exc:
        raise SensorError(f'sensor.ifov_check.k_sigma: {exc}') from None


def sensor_config_for_encoding(sensor_cfg: dict, encoding: str) -> SensorConfig:
    """
    Return the SensorConfig a simulated camera applies for a raw image encoding.

    The ``sky_simulator`` node and ``record-sim`` both use it.

    ``32FC1``: the scene's mosaic layout, exposure and extinction ratio only (ideal: no noise, no
    quantisation). ``mono16``/``mono8``: the scene's effects, quantised with the scene's bits or,
    if it declares none, 12 (mono16) / 8 (mono8) bits; bits must fit the encoding. Raises
    CompassError (one line, ``scene sensor: ...`` for a bad scene mapping).

    Parameters
    ----------
    sensor_cfg : dict or None
        The scene's ``sensor:`` mapping.
    encoding : {"32FC1", "mono16", "mono8"}
        ROS ``sensor_msgs/Image`` encoding of the raw mosaic.

    Returns
    -------
    SensorConfig
        The parameters the simulated camera applies.

    Raises
    ------
    CompassError
        When the scene's mapping is invalid, or its quantisation bits do not fit the encoding.

    """
    cfg = dict(sensor_cfg or {})
    if encoding == '32FC1':
        cfg = {k: v for k, v in cfg.items() if k in ('mosaic', 'exposure', 'extinction_ratio')}
    else:
        cfg.setdefault('quantization', {'bits': 12 if encoding == 'mono16' else 8})
    try:
        parsed = parse_sensor_config(cfg)
    except SensorError as exc:
        raise CompassError(f'scene sensor: {exc}') from None
    if encoding == 'mono8' and parsed.bits > 8:
        raise CompassError(
            f"encoding mono8 cannot carry the scene's {parsed.bits}-bit samples: use mono16"
        )
    if encoding == 'mono16' and parsed.bits <= 8:
        raise CompassError(f'the scene quantises to {parsed.bits} bits: use encoding mono8')
    return parsed
