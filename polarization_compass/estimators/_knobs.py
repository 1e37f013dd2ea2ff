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

"""The knobs of the heading estimators: their specification and validation."""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .base import EstimatorError

__all__ = ['Knob', 'COMMON_KNOBS', 'KnobbedEstimator']


# --------------------------------------------------------------------------------------------
# Knobs
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Knob:
    default: object
    kind: str  # "int" | "float" | "bool" | "choice" | "region" | "float_or_none"
    lo: float = -math.inf
    hi: float = math.inf
    choices: tuple = ()
    doc: str = ''

    def check(self, name: str, value):
        if self.kind == 'region':
            if value is None:
                return None
            try:
                vals = tuple(int(v) for v in value)
            except (TypeError, ValueError):
                raise EstimatorError(
                    f'knob {name} must be (x0, y0, width, height) integers or None, got {value!r}'
                ) from None
            if len(vals) != 4 or vals[0] < 1 or vals[1] < 1 or vals[2] < 1 or vals[3] < 1:
                raise EstimatorError(
                    f'knob {name} must be (x0 >= 1, y0 >= 1, width >= 1, height >= 1), got '
                    f'{value!r}'
                )
            return vals
        if self.kind == 'choice':
            if value not in self.choices:
                raise EstimatorError(
                    f'knob {name} must be one of {", ".join(map(str, self.choices))}, got '
                    f'{value!r}'
                )
            return value
        if self.kind == 'bool':
            if not isinstance(value, (bool, np.bool_)):
                raise EstimatorError(f'knob {name} must be true or false, got {value!r}')
            return bool(value)
        if self.kind == 'float_or_none' and value is None:
            return None
        if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, (int, float, np.integer, np.floating)
        ):
            raise EstimatorError(f'knob {name} must be a number, got {value!r}')
        v = float(value)
        if self.kind == 'int':
            if not math.isfinite(v) or v != int(v):
                raise EstimatorError(f'knob {name} must be an integer, got {value!r}')
            v = int(v)
        if not (math.isfinite(v) and self.lo <= v <= self.hi):
            raise EstimatorError(
                f'knob {name} must be in [{self.lo:g}, {self.hi:g}], got {value!r}'
            )
        return v


#: Knobs every method has (a method may override a default).
COMMON_KNOBS = {
    'stride': Knob(1, 'int', 1, 1024, doc='use every stride-th sensor pixel (rows and columns)'),
    'region': Knob(
        None, 'region', doc='(x0, y0, width, height) in 1-based sensor pixels, or None'
    ),
    'min_dop': Knob(
        0.02, 'float', 0.0, 0.99, doc='ignore pixels with a lower degree of polarization'
    ),
    'min_pixels': Knob(50, 'int', 3, 10**9, doc='fewer usable pixels: status too_few_pixels'),
    'max_sun_altitude_deg': Knob(
        89.0,
        'float',
        1.0,
        90.0,
        doc='sun higher than this (ephemeris or data): status sun_near_zenith',
    ),
    'min_sun_altitude_deg': Knob(
        0.0, 'float', -10.0, 10.0, doc='sun lower than this (ephemeris): status sun_below_horizon'
    ),
    'block_px': Knob(
        32, 'int', 1, 4096, doc='block size (sensor pixels) of the cluster-robust uncertainty'
    ),
    'sigma_floor_deg': Knob(
        0.0,
        'float',
        0.0,
        90.0,
        doc='added in quadrature to the statistical sigma (sky-model error budget)',
    ),
    'brightness_min_t': Knob(
        8.0,
        'float',
        1.0,
        1e6,
        doc='t statistic the brightness gradient needs to resolve the 180 deg ambiguity',
    ),
    'prior_max_diff_deg': Knob(
        60.0,
        'float',
        1.0,
        90.0,
        doc='a prior bearing resolves the ambiguity only if a candidate is this close',
    ),
}


class KnobbedEstimator:
    """Mixin: validates ``self.knobs`` against ``KNOBS`` (COMMON_KNOBS plus the method's own)."""

    OWN_KNOBS: dict = {}
    KNOB_DEFAULTS: dict = {}  # overrides of common defaults
    NO_KNOBS: tuple = ()  # common knobs a method does not have

    def __init__(self, **knobs):
        super().__init__(**knobs)
        self.knobs = self._validate_knobs(knobs)

    @classmethod
    def knob_specs(cls) -> dict:
        specs = {k: v for k, v in COMMON_KNOBS.items() if k not in cls.NO_KNOBS}
        specs.update(cls.OWN_KNOBS)
        for k, v in cls.KNOB_DEFAULTS.items():
            s = specs[k]
            specs[k] = Knob(v, s.kind, s.lo, s.hi, s.choices, s.doc)
        return specs

    def _validate_knobs(self, given: dict) -> dict:
        specs = self.knob_specs()
        unknown = sorted(set(given) - set(specs))
        if unknown:
            raise EstimatorError(
                f'{self.name}: unknown knob(s) {", ".join(unknown)}; known: '
                f'{", ".join(sorted(specs))}'
            )
        out = {k: s.default for k, s in specs.items()}
        for k, v in given.items():
            out[k] = specs[k].check(k, v)
        out.setdefault('stride', 1)
        out.setdefault('region', None)
        if out['min_sun_altitude_deg'] >= out['max_sun_altitude_deg']:
            raise EstimatorError(
                f'{self.name}: min_sun_altitude_deg must be below max_sun_altitude_deg'
            )
        return out
