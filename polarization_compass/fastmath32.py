"""float32 elementary functions for numba kernels (inlined into the caller's loop, which keeps its own
fastmath flags and vectorises). ROS-free, no state.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["sincos32"]


@njit(inline="always", cache=True)
def sincos32(a):  # pragma: no cover - compiled
    """float32 (sin a, cos a) for |a| <= pi/2: Taylor polynomials to a^11 / a^12 in Horner form
    (truncation < 6e-8 at pi/2, below float32 rounding). Callers with wider angles fold them first."""
    z = a * a
    s = np.float32(1.0 / 39916800.0)
    s = s * -z + np.float32(1.0 / 362880.0)
    s = s * -z + np.float32(1.0 / 5040.0)
    s = s * -z + np.float32(1.0 / 120.0)
    s = s * -z + np.float32(1.0 / 6.0)
    s = a * (np.float32(1.0) - z * s)
    c = np.float32(1.0 / 479001600.0)
    c = c * -z + np.float32(1.0 / 3628800.0)
    c = c * -z + np.float32(1.0 / 40320.0)
    c = c * -z + np.float32(1.0 / 720.0)
    c = c * -z + np.float32(1.0 / 24.0)
    c = c * -z + np.float32(0.5)
    c = np.float32(1.0) - z * c
    return s, c
