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
What lies between the clear sky and the camera: clouds, haze and a skyline (trees, buildings).

A scene declares these under ``atmosphere`` (each key optional; anything not declared is never
constructed and costs nothing -- each stage that runs is counted in
:mod:`polarization_compass.instrumentation`)::

    atmosphere:
      clouds:  {coverage: 0.5, scale_m: 800, height_m: 2000, optical_thickness: 3.0,
                brightness: 1.5, softness: 0.08, wind_mps: [5.0, 0.0]}
      haze:    {turbidity: 4.0}
      skyline: {elevation_deg: [8, 12, 3, 0, ...]}   # equally spaced azimuths, clockwise from N
               | {max_elevation_deg: 15, features: 24}  # a seeded random skyline
               (+ ground_radiance: 0.2)
      ground:  {albedo: 0.2, specular: {fraction: 0.5, refractive_index: 1.33}}

All stages act on the clear-sky arrays (AoP, DoP, valid, relative radiance) the sky and radiance
models produced, per pixel, in the selection's pixel order. Randomness (the cloud field, a random
skyline) comes from the scene's ``seed`` only, so a scene renders the same frames every time.

Clouds
------
A single cloud layer at ``height_m`` above the camera, drifting with the wind: transmission
exp(-tau) of the clear-sky light plus the cloud's own unpolarized radiance
(:mod:`polarization_compass.clouds` has the model and its references).

Haze
----
Turbidity T (Preetham, Shirley & Smits 1999, "A practical analytic model for daylight", SIGGRAPH: T
= (t_m + t_h) / t_m, the optical thickness of molecules plus haze over that of molecules alone; T =
2 very clear, 3 clear, 6+ hazy). Haze aerosols scatter nearly unpolarized light, so in single
scattering the polarized share of the sky light is the molecular share 1/T; relative to the
clearest sky of the model (T = 2) the DoP is scaled by ``2 / T`` (this project's derivation from
that definition: with the sky model's ``dop_max`` = 0.75 of clean air, T = 3-5 gives DoP_max
0.5-0.3, the measured range in haze, physics notes 4). The radiance, when the scene declares no
``radiance`` model, is Preetham's luminance distribution
(:class:`polarization_compass.radiance.PreethamSky`, written from the paper: no maintained PyPI
package provides it). Valid for 2 <= T <= 10 (the range of the paper's fit).

Skyline
-------
Obstacles at the horizon: the elevation of the skyline as a function of azimuth (linear,
periodic interpolation between equally spaced azimuths from North, clockwise), either declared or a
seeded random one (``features`` random heights in [0, ``max_elevation_deg``]). Pixels looking below
it see the obstacle or the ground: invalid, DoP 0, radiance ``ground_radiance`` (a diffuse,
unpolarized reflector, relative to the clear zenith).

Ground
------
Below the geometric horizon (ray elevation < 0) a declared ``ground`` replaces that: a Lambertian
reflector of ``albedo`` lit by the sky dome plus an optional smooth dielectric's Fresnel reflection
of the sky from the mirror direction (:mod:`polarization_compass.ground`, which has the model and
its references). The pixels stay invalid (not sky) but show the reflection's radiance, DoP and AoP.
The obstacles of the skyline stay opaque above the horizon, and are reflected like the sky.

"""

from __future__ import annotations

import math

from numba import njit, prange
import numpy as np

from .atmosphere_checks import _keys, _num, AtmosphereError
from .clouds import CloudLayer
from .runtime import kernel_array

__all__ = [
    'AtmosphereError',
    'Atmosphere',
    'CloudLayer',
    'Haze',
    'Skyline',
    'haze_dop_factor',
]


# ----------------------------------------------------------------------------------------------
# haze
def haze_dop_factor(turbidity: float) -> float:
    """
    Return the DoP factor ``2 / T`` for Preetham turbidity T.

    The factor on the DoP relative to the clearest sky of the model (T = 2): the molecular share of
    the scattering optical thickness under Preetham et al.'s definition of T, aerosol scattering
    taken as unpolarized (this project's derivation, module docstring and physics notes 4).

    Parameters
    ----------
    turbidity : float
        Turbidity T (dimensionless, >= 2 for a factor <= 1; :class:`Haze` accepts [2, 10]).

    Returns
    -------
    float
        DoP factor 2 / T, in (0, 1] for T >= 2.

    References
    ----------
    .. [1] A. J. Preetham, P. Shirley and B. Smits, "A practical analytic model for daylight",
       SIGGRAPH 1999.

    """
    return 2.0 / float(turbidity)


class Haze:
    """
    Haze by turbidity: DoP scaled by :func:`haze_dop_factor`.

    Also supplies the Preetham radiance (:attr:`radiance_model`) when the scene declares no
    radiance model.

    Parameters
    ----------
    turbidity : float, default 3.0
        Preetham turbidity T, in [2, 10].

    Raises
    ------
    AtmosphereError
        ``turbidity`` is not a finite number in [2, 10].

    References
    ----------
    .. [1] A. J. Preetham, P. Shirley and B. Smits, "A practical analytic model for daylight",
       SIGGRAPH 1999.

    """

    def __init__(self, turbidity=3.0):
        self.turbidity = _num({'turbidity': turbidity}, 'turbidity', 3.0, 2.0, 10.0, 'haze')
        self.factor = haze_dop_factor(self.turbidity)
        self._radiance = None

    @property
    def radiance_model(self):
        """Return the Preetham radiance model of this turbidity, built on first use."""
        if self._radiance is None:
            from .radiance import PreethamSky

            self._radiance = PreethamSky(self.turbidity)
        return self._radiance

    def params(self) -> dict:
        """
        Return the haze's parameters, with the DoP factor it implies.

        Returns
        -------
        dict
            ``turbidity`` and ``dop_factor`` (:func:`haze_dop_factor`).

        """
        return {'turbidity': self.turbidity, 'dop_factor': self.factor}

    def apply(self, dop, valid, aop, min_dop: float) -> None:
        """
        Scale the DoP by the haze factor, in place, and invalidate pixels that fall below min_dop.

        Parameters
        ----------
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization [0, 1]; multiplied by :func:`haze_dop_factor` in place.
        valid : numpy.ndarray, shape (N,), bool
            Pixel validity; cleared in place where the scaled DoP is below ``min_dop``.
        aop : numpy.ndarray, shape (N,), float32
            Angle of polarization [rad]; set to 0 (with dop) where a pixel becomes invalid.
        min_dop : float
            Minimum DoP; 0 invalidates nothing.

        """
        dop *= np.float32(self.factor)
        if min_dop > 0.0:
            low = valid & (dop < min_dop)
            valid[low] = False
            aop[low] = 0.0
            dop[low] = 0.0


# ----------------------------------------------------------------------------------------------
# skyline
@njit(parallel=True, cache=True)
def _skyline_candidates_kernel(rays, r0, r1, r2, t_max, flag):  # pragma: no cover - compiled
    """
    Flag the rays below the skyline's highest point (branch-free pass).

    flag[i] = 1 where the ray is below the skyline's highest point (u < t_max * horizontal length):
    a branch-free pass (a loop that contains the atan2 branch runs ~15x slower even when it is
    never taken, measured), the few flagged pixels are then tested exactly.
    """
    for i in prange(rays.shape[1]):
        px = rays[0, i]
        py = rays[1, i]
        pz = rays[2, i]
        e = r0[0] * px + r0[1] * py + r0[2] * pz
        nn = r1[0] * px + r1[1] * py + r1[2] * pz
        u = r2[0] * px + r2[1] * py + r2[2] * pz
        flag[i] = u < t_max * math.sqrt(e * e + nn * nn)


@njit(cache=True)
def _skyline_kernel(
    idx, rays, R, tan_elev, ground, aop, dop, inten, valid
):  # pragma: no cover - compiled
    m = tan_elev.size
    for i in idx:
        px = rays[0, i]
        py = rays[1, i]
        pz = rays[2, i]
        e = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
        nn = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
        u = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
        h = math.sqrt(e * e + nn * nn)
        az = math.atan2(e, nn)  # clockwise from North
        if az < 0.0:
            az += 2.0 * math.pi
        pos = az / (2.0 * math.pi) * m
        j = min(int(math.floor(pos)), m - 1)
        f = pos - j
        j1 = j + 1 if j + 1 < m else 0
        t = tan_elev[j] * (1.0 - f) + tan_elev[j1] * f
        if u < t * h:  # below the skyline (or the horizon)
            valid[i] = False
            aop[i] = np.float32(0.0)
            dop[i] = np.float32(0.0)
            inten[i] = np.float32(ground)


class Skyline:
    """
    Obstacles at the horizon: the skyline elevation per azimuth.

    The elevation is given at ``len(elevation_deg)`` equally spaced azimuths from North clockwise
    and linearly interpolated in tan(elevation) (periodic), or drawn at random from the seed.

    Parameters
    ----------
    elevation_deg : float or sequence of float, optional
        Skyline elevation [deg], 1-3600 values in [0, 80], the first at North.
    max_elevation_deg : float, optional
        For a random skyline: the largest elevation [deg], [0, 80].
    features : int, default 24
        For a random skyline: the number of equally spaced random heights, [2, 3600].
    ground_radiance : float, default 0.2
        Radiance of what lies below the skyline relative to the clear zenith, [0, 1e3].
    seed : int, default 0
        Seed of a random skyline (the scene's).

    Raises
    ------
    AtmosphereError
        Both or neither of ``elevation_deg`` and ``max_elevation_deg`` given, or a value that is
        not a number or out of its range.

    """

    def __init__(
        self, elevation_deg=None, max_elevation_deg=None, features=24, ground_radiance=0.2, seed=0
    ):
        if elevation_deg is not None and max_elevation_deg is not None:
            raise AtmosphereError(
                'atmosphere.skyline: give elevation_deg or max_elevation_deg, not both'
            )
        if elevation_deg is None and max_elevation_deg is None:
            raise AtmosphereError(
                'atmosphere.skyline needs elevation_deg (a number or a list) or max_elevation_deg'
            )
        if elevation_deg is not None:
            vals = elevation_deg if isinstance(elevation_deg, (list, tuple)) else [elevation_deg]
            if not 1 <= len(vals) <= 3600:
                raise AtmosphereError('atmosphere.skyline.elevation_deg needs 1-3600 values')
            elev = np.array(
                [_num({'e': v}, 'e', 0, 0.0, 80.0, 'skyline.elevation_deg') for v in vals]
            )
            self.random = None
        else:
            mx = _num({'m': max_elevation_deg}, 'm', 0, 0.0, 80.0, 'skyline.max_elevation_deg')
            k = int(_num({'f': features}, 'f', 24, 2, 3600, 'skyline.features'))
            elev = np.random.default_rng([int(seed), 0x5C7]).uniform(0.0, mx, k)
            self.random = {'max_elevation_deg': mx, 'features': k}
        self.elevation_deg = elev
        self.tan_elev = np.tan(np.radians(elev))
        self.ground_radiance = _num(
            {'g': ground_radiance}, 'g', 0.2, 0.0, 1e3, 'skyline.ground_radiance'
        )

    def elevation_at(self, azimuth_deg) -> np.ndarray:
        """
        Return the skyline elevation at azimuths, as the kernel interpolates it.

        Parameters
        ----------
        azimuth_deg : float or array_like
            Azimuth [deg], clockwise from North (any value; taken modulo 360).

        Returns
        -------
        numpy.ndarray
            Skyline elevation [deg], the shape of ``azimuth_deg``.

        """
        a = np.mod(np.asarray(azimuth_deg, dtype=float), 360.0)
        m = self.tan_elev.size
        pos = a / 360.0 * m
        j = np.minimum(np.floor(pos).astype(int), m - 1)
        f = pos - j
        t = self.tan_elev[j] * (1 - f) + self.tan_elev[(j + 1) % m] * f
        return np.degrees(np.arctan(t))

    def params(self) -> dict:
        """
        Return the skyline's parameters, as a scene's ``atmosphere.skyline`` mapping writes them.

        Returns
        -------
        dict
            ``ground_radiance`` and either ``max_elevation_deg`` and ``features`` (random
            skyline) or ``elevation_deg`` as a list [deg].

        """
        p = {'ground_radiance': self.ground_radiance}
        if self.random:
            p.update(self.random)
        else:
            p['elevation_deg'] = [float(v) for v in self.elevation_deg]
        return p

    def apply(self, R_enu_cam, rays_cam, aop, dop, intensity, valid) -> None:
        """
        Mask what lies below the skyline in the flat arrays, in place.

        Pixels below the skyline become invalid with aop = dop = 0 and the ground's radiance.

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU (``v_enu = R_enu_cam @ v_cam``), e.g.
            :func:`~polarization_compass.conventions.R_enu_cam_from_attitude`.
        rays_cam : numpy.ndarray, shape (3, N), float32
            Unit viewing rays in the camera frame, contiguous.
        aop : numpy.ndarray, shape (N,), float32
            Angle of polarization [rad]; set to 0 where a pixel becomes invalid.
        dop : numpy.ndarray, shape (N,), float32
            Degree of polarization [0, 1]; modified in place.
        intensity : numpy.ndarray, shape (N,), float32
            Radiance relative to the clear zenith; modified in place.
        valid : numpy.ndarray, shape (N,), bool
            Pixel validity; cleared in place where a pixel becomes invalid.

        """
        R = np.ascontiguousarray(R_enu_cam, dtype=np.float64)
        rays_cam = kernel_array(rays_cam)  # one argument type: the kernels compile once
        flag = np.empty(rays_cam.shape[1], np.bool_)
        _skyline_candidates_kernel(
            rays_cam,
            R[0].copy(),
            R[1].copy(),
            R[2].copy(),
            float(max(self.tan_elev.max(), 0.0)),
            flag,
        )
        idx = np.flatnonzero(flag)
        if idx.size:
            _skyline_kernel(
                idx, rays_cam, R, self.tan_elev, self.ground_radiance, aop, dop, intensity, valid
            )


# ----------------------------------------------------------------------------------------------
# all
class Atmosphere:
    """
    The declared atmosphere stages of a scene, applied in the order haze, clouds, skyline, ground.

    Parameters
    ----------
    cfg : dict
        A scene's ``atmosphere`` mapping with optional ``clouds``, ``haze``, ``skyline`` and
        ``ground`` mappings (module docstring); a missing or None stage is not built.
    seed : int, default 0
        The scene's seed; the cloud field and a random skyline derive from it.

    Raises
    ------
    AtmosphereError
        ``cfg`` or a stage is not a mapping, has an unknown key, or a stage rejects a value.

    """

    def __init__(self, cfg: dict, seed: int = 0):
        _keys(cfg, {'clouds', 'haze', 'skyline', 'ground'}, '')
        self.clouds = self.haze = self.skyline = self.ground = None
        if cfg.get('haze') is not None:
            h = cfg['haze']
            _keys(h, {'turbidity'}, 'haze')
            self.haze = Haze(**h)
        if cfg.get('clouds') is not None:
            c = cfg['clouds']
            _keys(
                c,
                {
                    'coverage',
                    'scale_m',
                    'height_m',
                    'optical_thickness',
                    'brightness',
                    'softness',
                    'wind_mps',
                },
                'clouds',
            )
            self.clouds = CloudLayer(**c, seed=(int(seed) * 2654435761 + 1) & 0x7FFFFFFF)
        if cfg.get('skyline') is not None:
            s = cfg['skyline']
            _keys(
                s, {'elevation_deg', 'max_elevation_deg', 'features', 'ground_radiance'}, 'skyline'
            )
            self.skyline = Skyline(**s, seed=seed)
        if cfg.get('ground') is not None:
            from .ground import Ground, GroundError

            g = cfg['ground']
            _keys(g, {'albedo', 'specular'}, 'ground')
            try:
                self.ground = Ground(**g)
            except GroundError as exc:
                raise AtmosphereError(str(exc)) from None

    @property
    def stages(self) -> list[str]:
        """Return the names of the declared stages in the order they are applied."""
        return [n for n in ('haze', 'clouds', 'skyline', 'ground') if getattr(self, n) is not None]

    def params(self) -> dict:
        """
        Return the parameters of each declared stage.

        Returns
        -------
        dict
            Stage name -> that stage's ``params()``.

        """
        return {n: getattr(self, n).params() for n in self.stages}

    def apply(
        self,
        R_enu_cam,
        rays_cam,
        aop,
        dop,
        valid,
        intensity,
        min_dop: float,
        dt_s: float,
        instr,
        block_shape=None,
        sky_at=None,
        has_ray=None,
    ):
        """
        Apply the declared stages to flat clear-sky arrays.

        The arrays are modified in place and returned; each stage runs inside an instrumentation
        stage named ``atmosphere.<stage>``.

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU (``v_enu = R_enu_cam @ v_cam``).
        rays_cam : array_like, shape (3, N)
            Unit viewing rays in the camera frame (converted to contiguous float32).
        aop : numpy.ndarray, shape (N,), float32
            Clear-sky angle of polarization [rad].
        dop : numpy.ndarray, shape (N,), float32
            Clear-sky degree of polarization [0, 1].
        valid : numpy.ndarray, shape (N,), bool
            Clear-sky pixel validity.
        intensity : numpy.ndarray, shape (N,), float32
            Writable radiance relative to the clear zenith (the radiance model's, or uniform 1).
        min_dop : float
            Minimum DoP; pixels that fall below it become invalid.
        dt_s : float
            Time since the scene's ``time_utc`` [s] (moves the clouds).
        instr : module or object
            Instrumentation with a ``stage(name)`` context manager, normally
            :mod:`polarization_compass.instrumentation`.
        block_shape : tuple of int or None, default None
            (H, W) when the pixels are a contiguous block in row-major order (see
            :meth:`CloudLayer.apply`), else None.
        sky_at : callable or None, default None
            ``sky_at(rays_cam) -> (aop, dop, radiance)``: the clear sky (and base radiance, as
            ``intensity`` got it) along other (3, M) float32 camera-frame rays, every ray valid;
            needed by a declared ``ground`` (the sky it reflects), unused otherwise.
        has_ray : numpy.ndarray, shape (N,), bool, or None, default None
            False for pixels the lens does not see through (the ground leaves them alone).

        Returns
        -------
        aop, dop : numpy.ndarray, shape (N,), float32
            The same arrays, after the stages.
        valid : numpy.ndarray, shape (N,), bool
            The same array, after the stages.
        intensity : numpy.ndarray, shape (N,), float32
            The same array, after the stages.

        Raises
        ------
        AtmosphereError
            A declared ``ground`` without ``sky_at``.

        """
        rays = np.ascontiguousarray(rays_cam, dtype=np.float32)
        if self.haze is not None:
            with instr.stage('atmosphere.haze'):
                self.haze.apply(dop, valid, aop, min_dop)
        if self.clouds is not None:
            with instr.stage('atmosphere.clouds'):
                self.clouds.apply(
                    R_enu_cam, rays, aop, dop, intensity, valid, min_dop, dt_s, block_shape
                )
        if self.skyline is not None:
            with instr.stage('atmosphere.skyline'):
                self.skyline.apply(R_enu_cam, rays, aop, dop, intensity, valid)
        if self.ground is not None:
            if sky_at is None:
                raise AtmosphereError('atmosphere.ground needs the sky along the mirror rays')
            with instr.stage('atmosphere.ground'):
                self.ground.apply(
                    R_enu_cam,
                    rays,
                    has_ray,
                    aop,
                    dop,
                    intensity,
                    valid,
                    self._seen_sky(R_enu_cam, sky_at, dt_s),
                )
        return aop, dop, valid, intensity

    def _seen_sky(self, R_enu_cam, sky_at, dt_s):
        """
        Wrap ``sky_at`` with the declared haze, clouds and skyline (what the ground reflects).

        The clouds are evaluated per ray (no grid) and nothing is invalidated (min_dop 0).
        """

        def seen(rays_cam):
            r = np.ascontiguousarray(rays_cam, dtype=np.float32)
            aop, dop, inten = sky_at(r)
            ok = np.ones(r.shape[1], np.bool_)
            if self.haze is not None:
                self.haze.apply(dop, ok, aop, 0.0)
            if self.clouds is not None:
                self.clouds.apply(R_enu_cam, r, aop, dop, inten, ok, 0.0, dt_s, None)
            if self.skyline is not None:
                self.skyline.apply(R_enu_cam, r, aop, dop, inten, ok)
            return aop, dop, inten

        return seen
