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
Argument checks shared by the subcommands.

Each failure is a one-line :class:`~polarization_compass.errors.CompassError` naming the option as
the user typed it.
"""

from __future__ import annotations

import math

from ..errors import CompassError

__all__ = ['check_range', 'check_together']


def check_range(name: str, v, lo: float, hi: float) -> None:
    """``--name`` (None = not given) must be finite and in [lo, hi]."""
    if v is None:
        return
    if not math.isfinite(v) or not (lo <= v <= hi):
        raise CompassError(f'--{name} must be finite and in [{lo}, {hi}], got {v}')


def check_together(name_a: str, a, name_b: str, b) -> None:
    """``--name_a`` and ``--name_b`` are both given or both left out."""
    if (a is None) != (b is None):
        raise CompassError(f'--{name_a} and --{name_b} go together')
