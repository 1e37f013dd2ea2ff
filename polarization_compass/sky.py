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
Sky polarization models, evaluated in the camera frame.

Every model answers, for unit viewing rays in the camera frame, the angle of polarization in the
paper's eq 28 convention (folded to [-pi/2, pi/2)), the degree of polarization and which pixels are
valid: ``model.polarization(sun_cam, zenith_cam, rays_cam, limits) -> (aop, dop, valid)`` with
``limits = (cos sun-exclusion radius, sin minimum altitude, minimum DoP)``; invalid pixels hold
``aop = dop = 0``. Working in the camera frame is exact and cheap: a rotation commutes with the
cross product, so ``R^T (S x P) = (R^T S) x (R^T P)`` and only the sun and zenith vectors are
rotated per frame, never the millions of rays.

Models
------
``rayleigh``          eqs 11-19 via the cross product ``E = S x P`` (physics notes 1), ``dop_max``.
``berry_dennis_lee``  neutral-point model (see ``sky_bdl``).

The models by name, and building one from a scene's ``sky`` mapping, are
:mod:`~polarization_compass.sky_models` (:func:`~polarization_compass.sky_models.make_sky_model`).

"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange
import numpy as np

from .errors import CompassError
from .fastmath import axial_atan2_f32, FM
from .runtime import kernel_array

__all__ = [
    'RayleighParams',
    'RayleighSky',
    'SkyModelError',
    'rayleigh_pixel',
    'rayleigh_reference',
]


class SkyModelError(CompassError):
    """Unknown sky model or out-of-range parameter."""


def _check_dop_max(dop_max) -> float:
    d = float(dop_max)
    if not (math.isfinite(d) and 0.0 < d <= 1.0):
        raise SkyModelError(f'dop_max must be in (0, 1], got {dop_max!r}')
    return d


class RayleighParams(NamedTuple):
    """
    Hold one frame's float32 parameters of :func:`rayleigh_pixel` (a named tuple numba reads).

    Parameters
    ----------
    sx, sy, sz : numpy.float32
        Unit sun vector in the camera frame.
    zx, zy, zz : numpy.float32
        Unit zenith (ENU up) vector in the camera frame.
    dop_max : numpy.float32
        Maximum DoP.
    cos_sun_excl, sin_min_alt, min_dop : numpy.float32
        The validity limits (see :meth:`RayleighSky.polarization`).

    """

    sx: np.float32
    sy: np.float32
    sz: np.float32
    zx: np.float32
    zy: np.float32
    zz: np.float32
    dop_max: np.float32
    cos_sun_excl: np.float32
    sin_min_alt: np.float32
    min_dop: np.float32


@njit(inline='always', cache=True, fastmath=FM)
def rayleigh_pixel(rx, ry, rz, p):  # pragma: no cover - compiled
    """
    Return the Rayleigh AoP, DoP and validity of one unit ray (float32, compiled, inlined).

    The per-pixel body of :class:`RayleighSky`'s kernel and of the fused sky-and-effects pass
    (:mod:`polarization_compass.sky_effects`): E = S x P in the camera frame, DoP ``dop_max (1 -
    c^2) / (1 + c^2)`` with c = S . P (eq 11), valid outside the sun-exclusion disk, above the
    minimum altitude and at or above the minimum DoP. Branch-free (bitwise &, selects) so that the
    caller's loop vectorises.

    Parameters
    ----------
    rx, ry, rz : float32
        Unit viewing ray in the camera frame.
    p : RayleighParams
        The frame's sun and zenith vectors, maximum DoP and validity limits.

    Returns
    -------
    aop : float32
        AoP [rad] in [-pi/2, pi/2) (eq 28), 0 where invalid.
    dop : float32
        DoP, 0 where invalid.
    valid : bool
        Whether the pixel passes the limits.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 11, 19 and 28.

    """
    one = np.float32(1.0)
    zero = np.float32(0.0)
    ex = p.sy * rz - p.sz * ry  # E = S x P (camera frame)
    ey = p.sz * rx - p.sx * rz
    c = p.sx * rx + p.sy * ry + p.sz * rz  # cos(scattering angle)
    c2 = c * c
    d = p.dop_max * (one - c2) / (one + c2)
    above = p.zx * rx + p.zy * ry + p.zz * rz >= p.sin_min_alt
    ok = (c <= p.cos_sun_excl) & above & (d >= p.min_dop)
    a = axial_atan2_f32(ex, ey)
    return (a if ok else zero), (d if ok else zero), ok


@njit(parallel=True, cache=True, fastmath=FM)
def _rayleigh_kernel(rays, p, aop, dop, valid):  # pragma: no cover - compiled
    """Fused Rayleigh AoP/DoP and validity (``p`` a :class:`RayleighParams`); invalid: 0, 0."""
    n = rays.shape[1]
    for i in prange(n):
        a, d, ok = rayleigh_pixel(rays[0, i], rays[1, i], rays[2, i], p)
        valid[i] = ok
        aop[i] = a
        dop[i] = d


class RayleighSky:
    """
    Single-scattering Rayleigh sky (eqs 11-19).

    The E-vector of a viewing ray P is ``S x P`` (S the sun direction), its DoP
    ``dop_max sin^2(gamma) / (1 + cos^2(gamma))`` with gamma the scattering angle (eq 11).

    Parameters
    ----------
    dop_max : float, default 1.0
        Maximum degree of polarization, in (0, 1].

    Raises
    ------
    SkyModelError
        ``dop_max`` is not a finite number in (0, 1].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 11-19.

    """

    name = 'rayleigh'

    def __init__(self, dop_max: float = 1.0):
        self.dop_max = _check_dop_max(dop_max)

    def params(self) -> dict:
        """
        Return the model's parameters, as a scene's ``sky`` mapping writes them.

        Returns
        -------
        dict
            ``{'model': 'rayleigh', 'dop_max': float}``; :func:`make_sky_model` rebuilds the model
            from it.

        """
        return {'model': self.name, 'dop_max': self.dop_max}

    def polarization(self, sun_cam, zenith_cam, rays_cam, limits=(1.0, -1.0, 0.0)):
        """
        Return the AoP, DoP and validity of viewing rays in the camera frame.

        Validity is fused into the same compiled pass as the polarization; invalid pixels get
        aop = dop = 0.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Unit sun vector in the camera frame.
        zenith_cam : array_like, shape (3,)
            Unit zenith (ENU up) vector in the camera frame.
        rays_cam : array_like, shape (3, N)
            Unit viewing rays in the camera frame (converted to read-only contiguous float32,
            :func:`~polarization_compass.runtime.kernel_array`).
        limits : tuple of float, default (1.0, -1.0, 0.0)
            (cosine of the sun-exclusion radius, sine of the minimum altitude, minimum DoP); the
            default accepts every pixel.

        Returns
        -------
        aop : numpy.ndarray, shape (N,), float32
            Angle of polarization [rad] in [-pi/2, pi/2), eq 28 convention (camera frame).
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization [0, dop_max] (eq 11).
        valid : numpy.ndarray, shape (N,), bool
            True where the pixel passes the limits.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eqs 11, 19 and 28.

        """
        rays = kernel_array(rays_cam, np.float32)  # one argument type: the kernel compiles once
        n = rays.shape[1]
        aop = np.empty(n, np.float32)
        dop = np.empty(n, np.float32)
        valid = np.empty(n, np.bool_)
        _rayleigh_kernel(rays, self.pixel_params(sun_cam, zenith_cam, limits), aop, dop, valid)
        return aop, dop, valid

    def pixel_params(self, sun_cam, zenith_cam, limits=(1.0, -1.0, 0.0)) -> RayleighParams:
        """
        Return the float32 parameters of :func:`rayleigh_pixel` after the ray, for one frame.

        Parameters
        ----------
        sun_cam, zenith_cam : array_like, shape (3,)
            Unit sun and zenith (ENU up) vectors in the camera frame.
        limits : tuple of float, default (1.0, -1.0, 0.0)
            (cosine of the sun-exclusion radius, sine of the minimum altitude, minimum DoP).

        Returns
        -------
        RayleighParams
            The sun and zenith vectors, ``dop_max`` and the limits, as float32.

        """
        s = np.asarray(sun_cam, dtype=np.float64).reshape(3)
        z = np.asarray(zenith_cam, dtype=np.float64).reshape(3)
        f32 = np.float32
        return RayleighParams(
            f32(s[0]),
            f32(s[1]),
            f32(s[2]),
            f32(z[0]),
            f32(z[1]),
            f32(z[2]),
            f32(self.dop_max),
            f32(limits[0]),
            f32(limits[1]),
            f32(limits[2]),
        )


def rayleigh_reference(
    sun_azimuth_deg, sun_altitude_deg, view_azimuth_deg, view_altitude_deg, dop_max=1.0
):
    """
    Compute the paper's own formulas, eqs 11, 14, 16-18, in ENU (float64).

    An independent path for tests, written term by term from the paper rather than through the
    cross product. Eq 18 divides by sin(gamma): undefined at the sun and the anti-sun.

    Parameters
    ----------
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], clockwise from North.
    sun_altitude_deg : float or array_like
        Sun altitude [deg].
    view_azimuth_deg : float or array_like
        Azimuth of the viewing direction [deg], clockwise from North.
    view_altitude_deg : float or array_like
        Altitude of the viewing direction [deg].
    dop_max : float, default 1.0
        Maximum degree of polarization (eq 11).

    Returns
    -------
    e_enu : numpy.ndarray, shape (..., 3)
        Unit E-vector in ENU (eq 18).
    dop : numpy.ndarray
        Degree of polarization (eq 11).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 11, 14 and 16-18.

    """
    As, hs = np.radians(sun_azimuth_deg), np.radians(sun_altitude_deg)
    Ap, hp = np.radians(view_azimuth_deg), np.radians(view_altitude_deg)
    cos_g = np.sin(hp) * np.sin(hs) + np.cos(hp) * np.cos(hs) * np.cos(As - Ap)
    sin_g = np.sqrt(np.clip(1 - cos_g**2, 0, None))
    e = np.stack(
        [
            (np.cos(As) * np.sin(hp) * np.cos(hs) - np.cos(Ap) * np.cos(hp) * np.sin(hs)) / sin_g,
            (-np.sin(As) * np.sin(hp) * np.cos(hs) + np.sin(Ap) * np.cos(hp) * np.sin(hs)) / sin_g,
            np.sin(As - Ap) * np.cos(hs) * np.cos(hp) / sin_g,
        ],
        axis=-1,
    )
    dop = dop_max * sin_g**2 / (1 + cos_g**2)
    return e, dop
