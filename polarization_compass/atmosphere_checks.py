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

"""The error a bad ``atmosphere`` mapping raises, and the key and number checks of its stages."""

from __future__ import annotations

import math

from .errors import CompassError

__all__ = ['AtmosphereError']


class AtmosphereError(CompassError):
    """A scene's ``atmosphere`` mapping that cannot be used; the message names the key."""


def _num(d: dict, key: str, default, lo, hi, where: str) -> float:
    v = d.get(key, default)
    if isinstance(v, bool):
        raise AtmosphereError(f'atmosphere.{where}.{key} must be a number, got {v!r}')
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise AtmosphereError(f'atmosphere.{where}.{key} must be a number, got {v!r}') from None
    if not math.isfinite(f) or not (lo <= f <= hi):
        raise AtmosphereError(
            f'atmosphere.{where}.{key} must be finite and in [{lo}, {hi}], got {v!r}'
        )
    return f


def _keys(d, allowed, where):
    if not isinstance(d, dict):
        raise AtmosphereError(f'atmosphere.{where} must be a mapping, got {type(d).__name__}')
    unknown = set(d) - set(allowed)
    if unknown:
        raise AtmosphereError(
            f'unknown key(s) {sorted(unknown)} in atmosphere.{where}; allowed: {sorted(allowed)}'
        )
