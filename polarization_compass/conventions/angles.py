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

"""Angle wrapping and axial (mod 180 deg) angles: array forms and one-float ``*_float`` forms."""

from __future__ import annotations

import math

import numpy as np


def wrap_180_deg(angle_deg):
    """
    Wrap angles in degrees to (-180, 180].

    Parameters
    ----------
    angle_deg : float or array_like
        Angle(s) [deg], any value.

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [deg] in (-180, 180]; a float for scalar input.

    """
    a = np.asarray(angle_deg, dtype=float)
    w = np.mod(a + 180.0, 360.0) - 180.0  # [-180, 180)
    w = np.where(w == -180.0, 180.0, w)
    return w if w.ndim else float(w)


def wrap_360_deg(angle_deg):
    """
    Wrap angles in degrees to [0, 360).

    Parameters
    ----------
    angle_deg : float or array_like
        Angle(s) [deg], any value.

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [deg] in [0, 360); a float for scalar input.

    """
    a = np.asarray(angle_deg, dtype=float)
    w = np.mod(a, 360.0)
    w = np.where(w >= 360.0, 0.0, w)  # np.mod(-1e-20, 360) == 360.0 in floating point
    return w if w.ndim else float(w)


def wrap_180_deg_float(angle_deg: float) -> float:
    """
    Wrap one finite float in degrees to (-180, 180], as :func:`wrap_180_deg` does.

    Plain arithmetic, no numpy call: the same floor modulo as ``np.mod`` and so the same bits,
    cheap enough to run once per estimate in sweeps of 1e5, and compilable by numba
    (``njit(inline="always")(...)``) for kernels.

    Parameters
    ----------
    angle_deg : float
        Angle [deg], finite.

    Returns
    -------
    float
        The angle [deg] in (-180, 180].

    """
    w = (angle_deg + 180.0) % 360.0 - 180.0
    return 180.0 if w == -180.0 else w


def wrap_360_deg_float(angle_deg: float) -> float:
    """
    Wrap one finite float in degrees to [0, 360), as :func:`wrap_360_deg` does.

    Plain arithmetic like :func:`wrap_180_deg_float`.

    Parameters
    ----------
    angle_deg : float
        Angle [deg], finite.

    Returns
    -------
    float
        The angle [deg] in [0, 360).

    """
    w = angle_deg % 360.0
    return 0.0 if w >= 360.0 else w


def fold_axial_rad_float(angle_rad: float) -> float:
    """
    Fold one finite axial angle (mod pi) in radians to (-pi/2, pi/2], as :func:`fold_axial_rad`.

    Plain arithmetic like :func:`wrap_180_deg_float`.

    Parameters
    ----------
    angle_rad : float
        Axial angle [rad], finite, defined modulo pi.

    Returns
    -------
    float
        The angle [rad] in (-pi/2, pi/2].

    """
    w = (angle_rad + 0.5 * math.pi) % math.pi - 0.5 * math.pi
    return 0.5 * math.pi if w <= -0.5 * math.pi else w


def fold_axial_deg(angle_deg):
    """
    Fold axial angles (defined mod 180 deg) to (-90, 90].

    Used for heading errors of axial methods, which measure the solar meridian modulo 180 deg. A
    finite float is folded without numpy (hot in sweeps) and gives the same bits.

    Parameters
    ----------
    angle_deg : float or array_like
        Axial angle(s) [deg].

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [deg] in (-90, 90]; a float for scalar input.

    """
    if isinstance(angle_deg, float) and math.isfinite(angle_deg):
        w = (
            angle_deg + 90.0
        ) % 180.0 - 90.0  # a scalar: the same floor modulo without numpy (sweeps)
        return 90.0 if w <= -90.0 else w
    a = np.asarray(angle_deg, dtype=float)
    w = np.mod(a + 90.0, 180.0) - 90.0  # [-90, 90)
    w = np.where(w <= -90.0, 90.0, w)
    return w if w.ndim else float(w)


def fold_axial_rad(angle_rad):
    """
    Fold axial angles (defined mod pi) to (-pi/2, pi/2].

    Parameters
    ----------
    angle_rad : float or array_like
        Axial angle(s) [rad].

    Returns
    -------
    float or numpy.ndarray
        The angle(s) [rad] in (-pi/2, pi/2]; a float for scalar input.

    """
    a = np.asarray(angle_rad, dtype=float)
    w = np.mod(a + np.pi / 2, np.pi) - np.pi / 2
    w = np.where(w <= -np.pi / 2, np.pi / 2, w)
    return w if w.ndim else float(w)


def fold_aop_rad(aop_rad):
    """
    Fold an AoP image to [-pi/2, pi/2), the ``render`` contract.

    Parameters
    ----------
    aop_rad : array_like
        Angle of polarization [rad] in the eq 28 convention, any value; float32 stays float32.

    Returns
    -------
    numpy.ndarray
        The AoP [rad] in [-pi/2, pi/2), same dtype and shape as the input.

    """
    a = np.asarray(aop_rad)
    half = a.dtype.type(np.pi / 2) if a.dtype.kind == 'f' else np.pi / 2
    w = np.mod(a + half, 2 * half) - half
    return np.where(w >= half, -half, w).astype(a.dtype, copy=False)


def axial_mean_rad(angles_rad, weights=None):
    """
    Compute the weighted axial (mod pi) circular mean ``0.5 * arg(sum w exp(2i a))``.

    The doubled-angle mean of axial data, with the resultant length R in [0, 1] as the measure of
    concentration (1 = all equal, 0 = no preferred axis).

    Parameters
    ----------
    angles_rad : array_like
        Axial angles [rad], defined modulo pi.
    weights : array_like, optional
        Non-negative weights, the shape of ``angles_rad``; equal weights by default.

    Returns
    -------
    mean_rad : float
        The mean axis [rad] in [-pi/2, pi/2]; 0 when the weights sum to 0 or less.
    resultant_length : float
        R = |sum w exp(2i a)| / sum w in [0, 1]; 0 when the weights sum to 0 or less.

    """
    a = np.asarray(angles_rad, dtype=float)
    w = np.ones_like(a) if weights is None else np.asarray(weights, dtype=float)
    c = float(np.sum(w * np.cos(2 * a)))
    s = float(np.sum(w * np.sin(2 * a)))
    total = float(np.sum(w))
    if total <= 0:
        return 0.0, 0.0
    return 0.5 * math.atan2(s, c), math.hypot(c, s) / total


def axial_difference_deg(a_deg, b_deg):
    """
    Compute the difference a - b of two axial angles (mod 180 deg), folded to (-90, 90].

    Parameters
    ----------
    a_deg, b_deg : float or array_like
        Axial angles [deg], broadcast against each other.

    Returns
    -------
    float or numpy.ndarray
        a - b [deg] in (-90, 90].

    """
    return fold_axial_deg(np.asarray(a_deg, dtype=float) - np.asarray(b_deg, dtype=float))
