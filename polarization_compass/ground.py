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
The ground below the geometric horizon: a diffuse reflector plus an optional smooth dielectric.

A camera sees the ground where a viewing ray points below the geometric horizon (ENU elevation
< 0): a fisheye whose field exceeds 90 deg, or a tilted camera. A scene declares it under
``atmosphere.ground`` (nothing is built or computed otherwise)::

    atmosphere:
      ground: {albedo: 0.2, specular: {fraction: 0.5, refractive_index: 1.33}}

Model (per ground pixel, viewing ray d, zenith z, mirror ray m = d - 2 (d . z) z, i.e. (e, n, -u)
in ENU)::

    S_ground = (1 - f) * albedo * Lbar * (1, 0, 0)  +  f * M_R(theta_i, n) S_sky(m)

- Diffuse part: a Lambertian, unpolarized reflector of albedo ``albedo`` lit by the sky dome:
  its radiance is albedo E / pi with E the sky's irradiance on the horizontal ground, and E / pi
  is the sky's cosine-weighted mean radiance Lbar over the upper hemisphere (evaluated on a fixed
  16 x 32 quadrature of the sky as the scene renders it, relative to the clear zenith; uniform
  radiance 1 gives Lbar = 1). Approximation: the direct sunbeam is left out (so the ground is as
  bright as under an overcast sky of the same dome radiance), and the dome is the sky seen from
  the camera (the skyline's obstacles count with their ``ground_radiance``).
- Specular part (``specular`` declared; weight ``fraction`` f): a smooth dielectric of refractive
  index n (water 1.33, wet asphalt about 1.5) reflecting the sky from the mirror direction. The
  sky's Stokes vector (I, Q, U) is rotated into the s/p basis of the plane of incidence, multiplied
  by the Fresnel reflection Mueller matrix and rotated back into the viewing ray's frame. With the
  s axis perpendicular to the plane of incidence and Q = I_s - I_p::

      M_R = [[(R_s + R_p)/2, (R_s - R_p)/2, 0          ],
             [(R_s - R_p)/2, (R_s + R_p)/2, 0          ],
             [0,             0,             r_s r_p    ]]

  R_s = r_s^2, R_p = r_p^2 (Fresnel; Born & Wolf, "Principles of Optics", 7th ed., sec. 1.5.2;
  the Mueller form: Collett, "Field Guide to Polarization", SPIE 2005, "Mueller matrices for
  reflection and transmission"). For a dielectric with n > 1 seen from air there is no total
  reflection, r_s and r_p are real: the s/p phase difference is 0 or 180 deg (the sign of
  r_s r_p, which changes at Brewster's angle), so no circular part arises and only the linear
  Stokes parameters change. Here r_p is the ratio of the reflected to the incident field's
  component *along the surface* (so r_p = r_s = (1 - n)/(1 + n) at normal incidence, where a
  mirror keeps the E-vector's direction): r_p = -tan(theta_i - theta_t)/tan(theta_i + theta_t)
  in Born & Wolf's notation, r_s = -sin(theta_i - theta_t)/sin(theta_i + theta_t).
  At Brewster's angle (tan theta_B = n: 53.1 deg for water) R_p = 0 and the reflected light is
  fully s-polarized, its E-vector horizontal -- why skylight reflected from water is polarized
  horizontally near that angle (Horvath & Varju, "Polarized Light in Animal Vision", Springer
  2004, ch. 22; Konnen, "Polarized Light in Nature", 1985).

The mirror-direction sky is whatever the scene renders there (clear sky, radiance, haze, clouds,
skyline obstacles; the sun's disk and its glint are not: lens optics act on the image only).
Ground pixels are never valid (not sky), but carry the reflection's AoP, DoP and radiance so the
rendered frame and the sensor's mosaic show it.
"""

from __future__ import annotations

import math

from numba import njit, prange
import numpy as np

from .errors import CompassError
from .fastmath import axial_atan2_f32, FM, sincos_folded

__all__ = [
    'GroundError',
    'Ground',
    'fresnel_amplitudes',
    'fresnel_reflection_mueller',
    'brewster_angle_deg',
]


class GroundError(CompassError):
    """A scene's ``atmosphere.ground`` mapping that cannot be used; the message names the key."""


def _num(v, key: str, lo: float, hi: float, lo_open: bool = False) -> float:
    if isinstance(v, bool):
        raise GroundError(f'atmosphere.ground.{key} must be a number, got {v!r}')
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise GroundError(f'atmosphere.ground.{key} must be a number, got {v!r}') from None
    ok = math.isfinite(f) and (lo < f if lo_open else lo <= f) and f <= hi
    if not ok:
        rng = f'({lo}, {hi}]' if lo_open else f'[{lo}, {hi}]'
        raise GroundError(f'atmosphere.ground.{key} must be finite and in {rng}, got {v!r}')
    return f


def fresnel_amplitudes(cos_incidence, refractive_index):
    """
    Return the Fresnel amplitude reflection coefficients r_s, r_p of a smooth dielectric.

    Light from air (index 1) onto a medium of real index n > 1 (no absorption, no total
    reflection): cos theta_t = sqrt(1 - sin^2 theta_i / n^2),
    r_s = (cos theta_i - n cos theta_t) / (cos theta_i + n cos theta_t),
    r_p = (cos theta_t - n cos theta_i) / (n cos theta_i + cos theta_t), where r_p relates the
    field components along the surface (r_p = r_s at normal incidence; Born & Wolf's r_parallel
    with the opposite sign).

    Parameters
    ----------
    cos_incidence : float or array_like
        cos theta_i of the angle of incidence from the surface normal, clipped to [0, 1].
    refractive_index : float
        Refractive index n of the medium relative to air, > 1.

    Returns
    -------
    r_s, r_p : numpy.ndarray
        Amplitude reflection coefficients (float64, the shape of ``cos_incidence``); the
        reflectances are their squares.

    References
    ----------
    .. [1] M. Born and E. Wolf, "Principles of Optics", 7th ed., Cambridge 1999, sec. 1.5.2
       (Fresnel formulae).

    """
    c = np.clip(np.asarray(cos_incidence, dtype=float), 0.0, 1.0)
    n = float(refractive_index)
    ct = np.sqrt(1.0 - (1.0 - c * c) / (n * n))
    r_s = (c - n * ct) / (c + n * ct)
    r_p = (ct - n * c) / (n * c + ct)
    return r_s, r_p


def fresnel_reflection_mueller(cos_incidence, refractive_index):
    """
    Return the linear (3 x 3) Mueller matrix of Fresnel reflection in the s/p basis.

    Stokes vectors (I, Q, U) with Q = I_s - I_p (s: perpendicular to the plane of incidence) and U
    at 45 deg between s and p; the circular part is decoupled (r_s, r_p real, so it only scales by
    r_s r_p) and left out.

    Parameters
    ----------
    cos_incidence : float or array_like
        cos theta_i of the angle of incidence, clipped to [0, 1].
    refractive_index : float
        Refractive index n of the medium relative to air, > 1.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        [[(R_s + R_p)/2, (R_s - R_p)/2, 0], [(R_s - R_p)/2, (R_s + R_p)/2, 0], [0, 0, r_s r_p]].

    References
    ----------
    .. [1] E. Collett, "Field Guide to Polarization", SPIE Press 2005, Mueller matrices for
       reflection.
    .. [2] M. Born and E. Wolf, "Principles of Optics", 7th ed., sec. 1.5.2.

    """
    r_s, r_p = fresnel_amplitudes(cos_incidence, refractive_index)
    a = 0.5 * (r_s * r_s + r_p * r_p)
    b = 0.5 * (r_s * r_s - r_p * r_p)
    z = np.zeros_like(a)
    return np.stack(
        [np.stack([a, b, z], -1), np.stack([b, a, z], -1), np.stack([z, z, r_s * r_p], -1)], -2
    )


def brewster_angle_deg(refractive_index) -> float:
    """
    Return Brewster's angle of incidence, atan(n), from air onto index n.

    Parameters
    ----------
    refractive_index : float
        Refractive index n relative to air.

    Returns
    -------
    float
        Angle of incidence [deg] from the surface normal at which R_p = 0 (53.06 deg for n = 1.33).

    References
    ----------
    .. [1] M. Born and E. Wolf, "Principles of Optics", 7th ed., sec. 1.5.3.

    """
    return math.degrees(math.atan2(float(refractive_index), 1.0))


#: Quadrature of the cosine-weighted hemisphere mean (midpoint rule in sin^2 of the zenith angle,
#: which makes the weight uniform): rings x azimuths.
_HEMI_RINGS = 16
_HEMI_AZIMUTHS = 32


def _hemisphere_enu() -> np.ndarray:
    """Directions (3, K) whose plain mean of a radiance is its cosine-weighted hemisphere mean."""
    s2 = (np.arange(_HEMI_RINGS) + 0.5) / _HEMI_RINGS  # sin^2(zenith angle)
    az = (np.arange(_HEMI_AZIMUTHS) + 0.5) * (2 * math.pi / _HEMI_AZIMUTHS)
    st = np.sqrt(s2)[:, None]
    ct = np.sqrt(1.0 - s2)[:, None]
    e = (st * np.sin(az)).ravel()
    n = (st * np.cos(az)).ravel()
    u = np.broadcast_to(ct, (_HEMI_RINGS, _HEMI_AZIMUTHS)).ravel()
    return np.stack([e, n, u])


@njit(parallel=True, cache=True, fastmath=FM)
def _ground_kernel(idx, d_rays, m_rays, z, f, sky_m, surface, out):  # pragma: no cover - compiled
    """
    Write the ground's Stokes vector as AoP/DoP/radiance at the pixels ``idx`` (float64 inside).

    The sky seen along m_rays[:, k] (``sky_m``: AoP eq 28, DoP, radiance) is reflected by the
    Fresnel Mueller matrix in the s/p basis of the plane of incidence (s = z x d, with ``z`` the
    zenith in the camera frame; ``f``, a horizontal unit vector, at the nadir) and added, weighted
    by the specular fraction, to the unpolarized diffuse radiance (``surface``: diffuse radiance,
    specular fraction, refractive index). ``out`` is (aop, dop, intensity, valid), written at
    ``idx``. Branch-free (selects) apart from the pixel loop.
    """
    zx, zy, zz = z
    fx, fy, fz = f
    aop_m, dop_m, inten_m = sky_m
    diffuse, frac, n = surface
    aop, dop, inten, valid = out
    inv_n2 = 1.0 / (n * n)
    for k in prange(idx.size):
        i = idx[k]
        dx = float(d_rays[0, k])
        dy = float(d_rays[1, k])
        dz = float(d_rays[2, k])
        mx = float(m_rays[0, k])
        my = float(m_rays[1, k])
        mz = float(m_rays[2, k])
        cos_i = min(max(-(zx * dx + zy * dy + zz * dz), 0.0), 1.0)
        # s: perpendicular to the plane of incidence (horizontal); at the nadir any horizontal axis
        ax = zy * dz - zz * dy
        ay = zz * dx - zx * dz
        az = zx * dy - zy * dx
        l2 = ax * ax + ay * ay + az * az
        ok = l2 > 1e-24
        inv = 1.0 / math.sqrt(l2 if ok else 1.0)
        sx = ax * inv if ok else fx
        sy = ay * inv if ok else fy
        sz = az * inv if ok else fz
        # p axes with the same component along the surface: p_m = s x m, p_d = d x s
        pmx = sy * mz - sz * my
        pmy = sz * mx - sx * mz
        pmz = sx * my - sy * mx
        pdx = dy * sz - dz * sy
        pdy = dz * sx - dx * sz
        # the sky's E-vector at m, lifted from its eq 28 AoP (conventions.evector_cam_from_aop;
        # its sign and length do not matter)
        sa, ca = sincos_folded(float(aop_m[k]))
        ex = mz * sa
        ey = mz * ca
        ez = -(mx * sa + my * ca)
        c = ex * sx + ey * sy + ez * sz
        w = ex * pmx + ey * pmy + ez * pmz
        nrm = c * c + w * w
        ii = float(inten_m[k])
        p = float(dop_m[k]) * ii / (nrm if nrm > 0.0 else 1.0)
        q = p * (c * c - w * w)
        u = p * (2.0 * c * w)
        # Fresnel (fresnel_amplitudes), inlined
        ct = math.sqrt(1.0 - (1.0 - cos_i * cos_i) * inv_n2)
        rs = (cos_i - n * ct) / (cos_i + n * ct)
        rp = (ct - n * cos_i) / (n * cos_i + ct)
        a0 = 0.5 * (rs * rs + rp * rp)
        b0 = 0.5 * (rs * rs - rp * rp)
        tot = diffuse + frac * (a0 * ii + b0 * q)
        sq = frac * (b0 * ii + a0 * q)
        su = frac * (rs * rp * u)
        pol = math.sqrt(sq * sq + su * su)
        # E-vector at chi = atan2(U, Q)/2 from s towards p_d, by the half-angle formulas
        hc = math.sqrt(max(pol + sq, 0.0))
        hs = math.sqrt(max(pol - sq, 0.0))
        hs = hs if su >= 0.0 else -hs
        valid[i] = False
        inten[i] = np.float32(tot)
        dop[i] = np.float32(min(pol / tot, 1.0) if tot > 0.0 else 0.0)
        aop[i] = axial_atan2_f32(np.float32(hc * sx + hs * pdx), np.float32(hc * sy + hs * pdy))


class Ground:
    """
    The ground below the geometric horizon (module docstring for the model and its references).

    Parameters
    ----------
    albedo : float, default 0.2
        Diffuse (Lambertian) reflectance, [0, 1].
    specular : dict or None, default None
        ``{fraction: f, refractive_index: n}``: the share f in [0, 1] of a smooth dielectric's
        Fresnel reflection (default f = 1), index n in (1, 4] (default 1.33, water); None: no
        specular part.

    Raises
    ------
    GroundError
        A value that is not a number, not finite or out of its range, or an unknown key in
        ``specular`` (the message names the key).

    References
    ----------
    .. [1] M. Born and E. Wolf, "Principles of Optics", 7th ed., sec. 1.5.2.
    .. [2] E. Collett, "Field Guide to Polarization", SPIE Press 2005.

    """

    def __init__(self, albedo=0.2, specular=None):
        self.albedo = _num(albedo, 'albedo', 0.0, 1.0)
        self.fraction = 0.0
        self.refractive_index = 1.33
        self.specular = specular is not None
        if specular is not None:
            if not isinstance(specular, dict):
                raise GroundError(
                    'atmosphere.ground.specular must be a mapping {fraction, refractive_index}, '
                    f'got {type(specular).__name__}'
                )
            unknown = set(specular) - {'fraction', 'refractive_index'}
            if unknown:
                raise GroundError(
                    f'unknown key(s) {sorted(unknown)} in atmosphere.ground.specular; allowed: '
                    "['fraction', 'refractive_index']"
                )
            self.fraction = _num(specular.get('fraction', 1.0), 'specular.fraction', 0.0, 1.0)
            self.refractive_index = _num(
                specular.get('refractive_index', 1.33),
                'specular.refractive_index',
                1.0,
                4.0,
                lo_open=True,
            )
        self._hemi = _hemisphere_enu()

    def params(self) -> dict:
        """
        Return the ground's parameters, as a scene's ``atmosphere.ground`` mapping writes them.

        Returns
        -------
        dict
            ``albedo`` and ``specular`` (``{fraction, refractive_index}`` or None).

        """
        spec = None
        if self.specular:
            spec = {'fraction': self.fraction, 'refractive_index': self.refractive_index}
        return {'albedo': self.albedo, 'specular': spec}

    def dome_radiance(self, R_enu_cam, sky_at) -> float:
        """
        Return the sky's cosine-weighted mean radiance over the upper hemisphere, E / pi.

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU (``v_enu = R_enu_cam @ v_cam``).
        sky_at : callable
            ``sky_at(rays_cam) -> (aop, dop, radiance)`` of the sky seen along (3, K) float32
            camera-frame rays.

        Returns
        -------
        float
            Lbar, relative to the clear zenith (1 for a uniform sky of radiance 1).

        """
        R = np.asarray(R_enu_cam, dtype=float)
        rays = np.ascontiguousarray(R.T @ self._hemi, dtype=np.float32)
        return float(np.mean(np.asarray(sky_at(rays)[2], dtype=float)))

    def apply(self, R_enu_cam, rays_cam, has_ray, aop, dop, intensity, valid, sky_at) -> int:
        """
        Render the ground at the pixels whose ray points below the geometric horizon, in place.

        Those pixels become invalid and take the ground's radiance, DoP and AoP (eq 28).

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU (``v_enu = R_enu_cam @ v_cam``).
        rays_cam : numpy.ndarray, shape (3, N), float32
            Unit viewing rays in the camera frame, contiguous.
        has_ray : numpy.ndarray, shape (N,), bool, or None
            False for pixels the lens does not see through (fisheye beyond its field); None: all.
        aop : numpy.ndarray, shape (N,), float32
            Angle of polarization [rad], eq 28 convention; written at ground pixels.
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization [0, 1]; written at ground pixels.
        intensity : numpy.ndarray, shape (N,), float32
            Radiance relative to the clear zenith; written at ground pixels.
        valid : numpy.ndarray, shape (N,), bool
            Pixel validity; cleared at ground pixels.
        sky_at : callable
            ``sky_at(rays_cam) -> (aop, dop, radiance)``: (M,) float32 arrays of the sky seen along
            (3, M) float32 camera-frame rays (all above the horizon), as the scene renders it.

        Returns
        -------
        int
            The number of ground pixels.

        """
        R = np.asarray(R_enu_cam, dtype=np.float64)
        z = R[2].copy()  # the zenith in the camera frame
        u = z.astype(np.float32) @ rays_cam
        below = u < 0.0
        if has_ray is not None:
            below &= has_ray
        idx = np.flatnonzero(below)
        if idx.size == 0:
            return 0
        d = np.ascontiguousarray(rays_cam[:, idx])
        m = np.ascontiguousarray(d - (2.0 * u[idx]) * z.astype(np.float32)[:, None])
        diffuse = (1.0 - self.fraction) * self.albedo
        if diffuse > 0.0:
            diffuse *= self.dome_radiance(R, sky_at)
        if self.fraction <= 0.0:  # unpolarized
            valid[idx] = False
            intensity[idx] = np.float32(diffuse)
            aop[idx] = 0.0
            dop[idx] = 0.0
            return int(idx.size)
        aop_m, dop_m, inten_m = sky_at(m)
        # a horizontal axis for the nadir pixel: z x (1, 0, 0), or z x (0, 1, 0) if z is near x
        f = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        f /= np.linalg.norm(f)
        _ground_kernel(
            idx,
            d,
            m,
            (float(z[0]), float(z[1]), float(z[2])),
            (float(f[0]), float(f[1]), float(f[2])),
            (
                np.ascontiguousarray(aop_m, dtype=np.float32),
                np.ascontiguousarray(dop_m, dtype=np.float32),
                np.ascontiguousarray(inten_m, dtype=np.float32),
            ),
            (float(diffuse), float(self.fraction), float(self.refractive_index)),
            (aop, dop, intensity, valid),
        )
        return int(idx.size)
