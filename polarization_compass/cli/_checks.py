"""Argument checks shared by the subcommands: one-line :class:`~polarization_compass.errors.CompassError`
messages naming the option as the user typed it."""
from __future__ import annotations

import math

from ..errors import CompassError

__all__ = ["check_range", "check_together"]


def check_range(name: str, v, lo: float, hi: float) -> None:
    """``--name`` (None = not given) must be finite and in [lo, hi]."""
    if v is None:
        return
    if not math.isfinite(v) or not (lo <= v <= hi):
        raise CompassError(f"--{name} must be finite and in [{lo}, {hi}], got {v}")


def check_together(name_a: str, a, name_b: str, b) -> None:
    """``--name_a`` and ``--name_b`` are both given or both left out."""
    if (a is None) != (b is None):
        raise CompassError(f"--{name_a} and --{name_b} go together")
