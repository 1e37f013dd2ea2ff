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
Berry-Dennis-Lee (2004) neutral-point sky, evaluated in the camera frame.

M. V. Berry, M. R. Dennis and R. L. Lee Jr, "Polarization singularities in the clear sky",
New J. Phys. 6 (2004) 162. Single (Rayleigh) scattering has two index +1 singularities of the
polarization-line pattern, at the sun and at the anti-sun. Multiple scattering splits each into two
index +1/2 neutral points on the solar meridian: Babinet (above the sun) and Brewster (below it),
Arago (above the anti-sun) and the "fourth" point (below the anti-sun). Here each lies
``separation_deg`` from the sun or anti-sun (real skies: 15-20 deg; ``separation_deg = 0`` is
exactly Rayleigh).

The paper's model
-----------------
On the stereographic projection of the sky sphere, ``zeta = tan(theta / 2) exp(i phi)`` (theta the
zenith angle), the pattern is the complex function

    w(zeta) = -4 (zeta - z_B)(zeta - z_F)(zeta - z_R)(zeta - z_A)
              / ((1 + |zeta|^2)^2 |z_B - z_F| |z_R - z_A|)

with z_B, z_R Babinet and Brewster, and z_F = -1/conj(z_B), z_A = -1/conj(z_R) their antipodes
(the fourth point and Arago). The polarization direction is arg(w)/2 in the local projected basis
(after removing the constant phase 2 arg(z_sun)), and |w| is the intensity of polarization.

Frame-independent form used here (derivation)
---------------------------------------------
1. Chord lengths on the unit sphere: |p - q| = 2|zeta_p - zeta_q| /
   sqrt((1+|zeta_p|^2)(1+|zeta_q|^2)). For an antipodal pair (n, -n) and a sky point P this gives 2
   |zeta - z_n| |zeta - z_-n| / ((1 + |zeta|^2) |z_n - z_-n|) = 2 sin(g/2) cos(g/2) = |P x n|, g
   the angle between P and n. Hence |w| = |P x n_B| |P x n_R|: the product of the sines of the
   angular distances from P to Babinet and to Brewster. With n_B = n_R = S this is sin^2(gamma).
2. Phase: for three points z1, z2, z of a circle, (z - z1)(z - z2)/(z2 - z1) is (a positive
   multiple of) the tangent of the circle at z pointing towards z1 along the arc that avoids z2.
   The great circle through P and n passes through -n, and stereographic projection maps it to a
   circle and preserves angles, so arg[(zeta - z_n)(zeta - z_-n)] = theta_n + arg(z_-n - z_n),
   where theta_n is the angle of the tangent t_n at P of the geodesic from P to n. Both constants
   arg(z_F - z_B) and arg(z_A - z_R) equal arg(z_sun) + pi, so the constant phase is removed
   exactly and 2 chi = pi + theta_B + theta_R: the E-vector is perpendicular to the bisector of the
   geodesic directions from P towards Babinet and towards Brewster. The relation is covariant under
   any rotation or reflection of the local basis, so no basis (and no projection pole) is needed.
3. In 3-D: a = n_B - (n_B . P) P and b = n_R - (n_R . P) P (|a| = |P x n_B|, |b| = |P x n_R|).
The bisector is s = |b| a + |a| b; the E axis is P x s, or equivalently d = |b| a - |a| b (the
two are parallel axes, s perpendicular to d). The kernel uses whichever of s, d is longer, so it
never divides and stays exact both where a ~ b (Rayleigh limit: E ~ P x S = -(S x P)) and where
a ~ -b (between Babinet and Brewster, and between Arago and the fourth point: E parallel to the
solar meridian, "negative" polarization). AoP is then atan2(E_x, E_y) folded to [-pi/2, pi/2)
exactly as in :class:`sky.RayleighSky` (paper eq 28).
4. DoP: BDL's |w| plays the role of Rayleigh's polarized intensity sin^2(gamma), and the total
intensity 1 + cos^2(gamma) = 2 - sin^2(gamma) becomes 2 - |w|, so
DoP = dop_max |w| / (2 - |w|); with separation 0 it is exactly Rayleigh's
dop_max sin^2(gamma) / (1 + cos^2(gamma)). |w| <= 1, so DoP is in [0, dop_max].

This form needs no stereographic coordinates, so it has none of their artefacts: the projection
formula above jumps by 90 deg of AoP when Babinet crosses the zenith (sun higher than 90 deg -
separation), and z = infinity is the nadir; neutral points below the horizon (low sun) are ordinary
points.

Not modelled: the horizon depolarization that BDL add to the intensity of polarization, and the
dependence of the neutral-point separation on sun altitude and wavelength (one constant here). With
the sun exactly at the zenith (or nadir) the solar meridian is undefined; the neutral points are
then put on the great circle through the sun and the frame's +x axis (or +y), a deterministic
choice.

"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange
import numpy as np

from .fastmath import axial_atan2_f32, FM
from .runtime import kernel_array
from .sky import _check_dop_max, SkyModelError

__all__ = ['BdlParams', 'BerryDennisLeeSky', 'bdl_pixel', 'neutral_points', 'SEPARATION_RANGE_DEG']

#: Allowed neutral-point separation (deg from the sun / anti-sun).
SEPARATION_RANGE_DEG = (0.0, 40.0)


def neutral_points(sun, zenith, separation_deg: float) -> dict:
    """
    Return unit directions of the four neutral points.

    Babinet and Brewster lie on the solar meridian ``separation_deg`` above and below the sun
    (towards / away from the zenith along the great circle through sun and zenith); Arago and the
    fourth point are the antipodes of Brewster and Babinet (above / below the anti-sun). With the
    sun at the zenith or nadir the meridian is undefined and the great circle through the sun and
    the frame's +x (or +y) axis is used.

    Parameters
    ----------
    sun : array_like, shape (3,)
        Sun direction in any frame (normalised here).
    zenith : array_like, shape (3,)
        Zenith (up) direction in the same frame (normalised here).
    separation_deg : float
        Angular distance of each neutral point from the sun or anti-sun [deg].

    Returns
    -------
    dict
        float64 unit vectors, shape (3,), in the frame of ``sun``, keyed ``babinet``,
        ``brewster``, ``arago``, ``fourth``.

    References
    ----------
    .. [1] M. V. Berry, M. R. Dennis and R. L. Lee Jr, "Polarization singularities in the clear
       sky", New J. Phys. 6 (2004) 162.

    """
    s = np.asarray(sun, dtype=np.float64).reshape(3)
    z = np.asarray(zenith, dtype=np.float64).reshape(3)
    s = s / np.linalg.norm(s)
    z = z / np.linalg.norm(z)
    up = z - np.dot(z, s) * s  # tangent at the sun towards the zenith
    n_up = float(np.linalg.norm(up))
    if n_up < 1e-9:  # sun at the zenith/nadir: meridian undefined
        ref = np.array([1.0, 0.0, 0.0]) if abs(s[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        up = ref - np.dot(ref, s) * s
        n_up = float(np.linalg.norm(up))
    up = up / n_up
    d = math.radians(float(separation_deg))
    babinet = math.cos(d) * s + math.sin(d) * up
    brewster = math.cos(d) * s - math.sin(d) * up
    return {'babinet': babinet, 'brewster': brewster, 'arago': -brewster, 'fourth': -babinet}


class BdlParams(NamedTuple):
    """
    Hold one frame's float32 parameters of :func:`bdl_pixel` (a named tuple numba reads).

    Parameters
    ----------
    bx, by, bz : numpy.float32
        Unit Babinet neutral point in the camera frame.
    rx, ry, rz : numpy.float32
        Unit Brewster neutral point in the camera frame.
    sx, sy, sz : numpy.float32
        Unit sun vector in the camera frame.
    zx, zy, zz : numpy.float32
        Unit zenith (ENU up) vector in the camera frame.
    dop_max : numpy.float32
        Maximum DoP.
    cos_sun_excl, sin_min_alt, min_dop : numpy.float32
        The validity limits (see :meth:`BerryDennisLeeSky.polarization`).

    """

    bx: np.float32
    by: np.float32
    bz: np.float32
    rx: np.float32
    ry: np.float32
    rz: np.float32
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
def bdl_pixel(px, py, pz, q):  # pragma: no cover - compiled
    """
    Return the BDL AoP, DoP and validity of one unit ray (float32, compiled, inlined).

    The per-pixel body of :class:`BerryDennisLeeSky`'s kernel and of the fused sky-and-effects
    pass (:mod:`polarization_compass.sky_effects`); module docstring, steps 3-4.

    Parameters
    ----------
    px, py, pz : float32
        Unit viewing ray in the camera frame.
    q : BdlParams
        The frame's neutral points, sun and zenith vectors, maximum DoP and validity limits.

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
    .. [1] M. V. Berry, M. R. Dennis and R. L. Lee Jr, "Polarization singularities in the clear
       sky", New J. Phys. 6 (2004) 162.

    """
    one = np.float32(1.0)
    two = np.float32(2.0)
    zero = np.float32(0.0)
    # tangent-plane components of Babinet (a) and Brewster (b) at P
    pb = q.bx * px + q.by * py + q.bz * pz
    ax = q.bx - pb * px
    ay = q.by - pb * py
    az = q.bz - pb * pz
    pr = q.rx * px + q.ry * py + q.rz * pz
    cx = q.rx - pr * px
    cy = q.ry - pr * py
    cz = q.rz - pr * pz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(cx * cx + cy * cy + cz * cz)
    # bisector s and its perpendicular d (both scaled by la * lb)
    s0 = lb * ax + la * cx
    s1 = lb * ay + la * cy
    s2 = lb * az + la * cz
    d0 = lb * ax - la * cx
    d1 = lb * ay - la * cy
    d2 = lb * az - la * cz
    use_s = (s0 * s0 + s1 * s1 + s2 * s2) >= (d0 * d0 + d1 * d1 + d2 * d2)
    ex = (py * s2 - pz * s1) if use_s else d0  # E = P x s  or  E = d
    ey = (pz * s0 - px * s2) if use_s else d1
    w = la * lb
    if w > one:
        w = one
    dv = q.dop_max * w / (two - w)
    c = q.sx * px + q.sy * py + q.sz * pz
    above = q.zx * px + q.zy * py + q.zz * pz >= q.sin_min_alt
    ok = (c <= q.cos_sun_excl) & above & (dv >= q.min_dop)
    a = axial_atan2_f32(ex, ey)
    return (a if ok else zero), (dv if ok else zero), ok


@njit(parallel=True, cache=True, fastmath=FM)
def _bdl_kernel(rays, q, aop, dop, valid):  # pragma: no cover - compiled
    """Fused BDL AoP/DoP and validity (module docstring, steps 3-4); invalid: aop = dop = 0."""
    n = rays.shape[1]
    for i in prange(n):
        a, d, ok = bdl_pixel(rays[0, i], rays[1, i], rays[2, i], q)
        valid[i] = ok
        aop[i] = a
        dop[i] = d


class BerryDennisLeeSky:
    """
    Berry-Dennis-Lee neutral-point sky.

    Parameters
    ----------
    separation_deg : float, default 18.0
        Distance of each neutral point from the sun or anti-sun [deg], in
        :data:`SEPARATION_RANGE_DEG` ([0, 40]); 0 is exactly the Rayleigh sky.
    dop_max : float, default 0.75
        Maximum degree of polarization, in (0, 1].

    Raises
    ------
    SkyModelError
        ``separation_deg`` or ``dop_max`` is not a number or out of range.

    References
    ----------
    .. [1] M. V. Berry, M. R. Dennis and R. L. Lee Jr, "Polarization singularities in the clear
       sky", New J. Phys. 6 (2004) 162.

    """

    name = 'berry_dennis_lee'

    def __init__(self, separation_deg: float = 18.0, dop_max: float = 0.75):
        try:
            sep = float(separation_deg)
        except (TypeError, ValueError):
            raise SkyModelError(
                f'separation_deg must be a number, got {separation_deg!r}'
            ) from None
        lo, hi = SEPARATION_RANGE_DEG
        if not (math.isfinite(sep) and lo <= sep <= hi):
            raise SkyModelError(
                f'separation_deg must be in [{lo:g}, {hi:g}] deg, got {separation_deg!r}'
            )
        self.separation_deg = sep
        try:
            self.dop_max = _check_dop_max(dop_max)
        except (TypeError, ValueError) as exc:
            if isinstance(exc, SkyModelError):
                raise
            raise SkyModelError(f'dop_max must be a number in (0, 1], got {dop_max!r}') from None

    def params(self) -> dict:
        """
        Return the model's parameters, as a scene's ``sky`` mapping writes them.

        Returns
        -------
        dict
            ``{'model': 'berry_dennis_lee', 'separation_deg': float, 'dop_max': float}``;
            :func:`~polarization_compass.sky_models.make_sky_model` rebuilds the model from it.

        """
        return {'model': self.name, 'separation_deg': self.separation_deg, 'dop_max': self.dop_max}

    def neutral_points_cam(self, sun_cam, zenith_cam) -> dict:
        """
        Return the four neutral points as unit vectors in the camera frame.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Sun direction in the camera frame.
        zenith_cam : array_like, shape (3,)
            Zenith (ENU up) direction in the camera frame.

        Returns
        -------
        dict
            float64 unit vectors, shape (3,), in the camera frame, keyed ``babinet``,
            ``brewster``, ``arago``, ``fourth`` (see :func:`neutral_points`).

        """
        return neutral_points(sun_cam, zenith_cam, self.separation_deg)

    def polarization(self, sun_cam, zenith_cam, rays_cam, limits=(1.0, -1.0, 0.0)):
        """
        Return the AoP, DoP and validity of viewing rays in the camera frame.

        The E-vector is perpendicular to the bisector of the geodesic directions towards Babinet
        and Brewster; DoP = dop_max |w| / (2 - |w|) with |w| the product of the sines of the
        angular distances to those two points (module docstring). Invalid pixels get aop = dop = 0.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Unit sun vector in the camera frame.
        zenith_cam : array_like, shape (3,)
            Unit zenith (ENU up) vector in the camera frame.
        rays_cam : array_like, shape (3, N)
            Unit viewing rays in the camera frame (converted to contiguous float32).
        limits : tuple of float, default (1.0, -1.0, 0.0)
            (cosine of the sun-exclusion radius, sine of the minimum altitude, minimum DoP); the
            default accepts every pixel.

        Returns
        -------
        aop : numpy.ndarray, shape (N,), float32
            Angle of polarization [rad] in [-pi/2, pi/2), the seed paper's eq 28 convention.
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization [0, dop_max].
        valid : numpy.ndarray, shape (N,), bool
            True where the pixel passes the limits.

        References
        ----------
        .. [1] M. V. Berry, M. R. Dennis and R. L. Lee Jr, "Polarization singularities in the clear
           sky", New J. Phys. 6 (2004) 162.
        .. [2] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), eq 28.

        """
        rays = kernel_array(rays_cam, np.float32)  # one argument type: the kernel compiles once
        n = rays.shape[1]
        aop = np.empty(n, np.float32)
        dop = np.empty(n, np.float32)
        valid = np.empty(n, np.bool_)
        _bdl_kernel(rays, self.pixel_params(sun_cam, zenith_cam, limits), aop, dop, valid)
        return aop, dop, valid

    def pixel_params(self, sun_cam, zenith_cam, limits=(1.0, -1.0, 0.0)) -> BdlParams:
        """
        Return the float32 parameters of :func:`bdl_pixel` after the ray, for one frame.

        Parameters
        ----------
        sun_cam, zenith_cam : array_like, shape (3,)
            Unit sun and zenith (ENU up) vectors in the camera frame.
        limits : tuple of float, default (1.0, -1.0, 0.0)
            (cosine of the sun-exclusion radius, sine of the minimum altitude, minimum DoP).

        Returns
        -------
        BdlParams
            The Babinet and Brewster points, the sun and zenith vectors, ``dop_max`` and the
            limits, as float32.

        """
        s = np.asarray(sun_cam, dtype=np.float64).reshape(3)
        z = np.asarray(zenith_cam, dtype=np.float64).reshape(3)
        npts = neutral_points(s, z, self.separation_deg)
        b, r = npts['babinet'], npts['brewster']
        f32 = np.float32
        return BdlParams(
            f32(b[0]),
            f32(b[1]),
            f32(b[2]),
            f32(r[0]),
            f32(r[1]),
            f32(r[2]),
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
