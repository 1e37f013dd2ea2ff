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
Simulated photodiode-array readings under a single-scattering Rayleigh sky (paper eqs 11-19).

Each unit integrates the sky over a cone of full angle ``acceptance_deg`` about its axis (a fixed
polar quadrature, cos-weighted like a flat photodiode): averaging Stokes vectors of differently
polarized directions lowers the DoP the unit sees, and for wide cones shifts its angle slightly.
Then each channel reads ``gain * (S0 + S1 cos 2 theta + S2 sin 2 theta) / 2`` with the E-vector of
each direction projected on the unit's polarizer plane
(:func:`~..conventions.unit_angle_from_evector_body_rad`), plus optional Gaussian noise.
"""

from __future__ import annotations

import math

import numpy as np

from .stokes import design_matrix
from ..conventions import (
    unit_angle_from_evector_body_rad,
    unit_axis_body,
    unit_polarizer_frame_body,
)
from ..mount import sun_sensor

__all__ = ['sun_body', 'simulate_unit_stokes', 'simulate_readings', 'ArraySensor']


def sun_body(
    sun_azimuth_deg, sun_altitude_deg, bearing_deg, pitch_deg=0.0, roll_deg=0.0
) -> np.ndarray:
    """
    Return the sun direction in the body frame of a body with a given attitude.

    Parameters
    ----------
    sun_azimuth_deg : float
        Sun azimuth [deg], clockwise from true North.
    sun_altitude_deg : float
        Sun altitude [deg].
    bearing_deg : float
        True bearing of the body's front [deg].
    pitch_deg : float, optional
        Paper's pitch [deg] (about the default-mounted camera's x = body right).
    roll_deg : float, optional
        Paper's roll [deg] (about camera y = body front).

    Returns
    -------
    numpy.ndarray
        (3,) unit sun vector in the REP-103 body frame.

    """
    b, p, r = float(bearing_deg), float(pitch_deg), float(roll_deg)
    return sun_sensor(sun_azimuth_deg, sun_altitude_deg, b, p, r, None)


def _cone_quadrature(acceptance_deg: float, rings: int = 6, per_ring: int = 24):
    """Offsets (theta, phi) and weights of a cos-weighted cone quadrature (midpoint in theta)."""
    half = math.radians(acceptance_deg) / 2.0
    th = (np.arange(rings) + 0.5) * half / rings
    ph = np.arange(per_ring) * 2 * math.pi / per_ring
    T, P = np.meshgrid(th, ph, indexing='ij')
    w = np.sin(T) * np.cos(T)  # solid angle x Lambert cosine
    return T.ravel(), P.ravel(), (w / w.sum()).ravel()


def simulate_unit_stokes(
    geometry, s_body, dop_max: float = 1.0, integrate: bool = True
) -> np.ndarray:
    """
    Return the Stokes vector each unit sees under a Rayleigh sky.

    Parameters
    ----------
    geometry : ArrayGeometry
        Units (axes, acceptance cones) and convention.
    s_body : array_like
        (3,) sun direction in the sensor's frame (the units' description; the body frame when the
        geometry has no mount).
    dop_max : float, optional
        Rayleigh maximum degree of polarization.
    integrate : bool, optional
        Integrate the acceptance cone (else the axis direction only).

    Returns
    -------
    numpy.ndarray
        (U, 3) (S0, S1, S2), S0 relative (Rayleigh radiance ~ 1 + cos^2 gamma), angles in each
        unit's convention.

    References
    ----------
    The paper's eqs 11-19 (Rayleigh sky).

    """
    s = np.asarray(s_body, dtype=float)
    out = np.zeros((geometry.n_units, 3))
    for u, unit in enumerate(geometry.units):
        axis = unit_axis_body(unit.azimuth_deg, unit.elevation_deg)
        zero, quarter = unit_polarizer_frame_body(
            unit.azimuth_deg, unit.elevation_deg, geometry.angle_zero, geometry.angle_sense
        )
        if integrate:
            T, P, W = _cone_quadrature(unit.acceptance_deg)
            dirs = np.cos(T)[:, None] * axis + np.sin(T)[:, None] * (
                np.cos(P)[:, None] * zero + np.sin(P)[:, None] * quarter
            )
        else:
            dirs, W = axis[None, :], np.ones(1)
        cos_g = np.clip(dirs @ s, -1.0, 1.0)
        e = np.cross(s, dirs)  # eq 18 up to scale
        norm = np.linalg.norm(e, axis=1)
        dop = dop_max * (1.0 - cos_g**2) / (1.0 + cos_g**2)
        phi = unit_angle_from_evector_body_rad(
            e / np.maximum(norm, 1e-300)[:, None],
            unit.azimuth_deg,
            unit.elevation_deg,
            geometry.angle_zero,
            geometry.angle_sense,
        )
        # an E-vector along the axis (off-axis rays only) projects to nothing: weight it by its
        # projected share
        proj = np.hypot(e @ zero, e @ quarter) / np.maximum(norm, 1e-300)
        s0 = 1.0 + cos_g**2
        out[u, 0] = np.sum(
            W * s0 * (1.0 - dop * (1.0 - proj**2))
        )  # the E component along the axis is lost
        out[u, 1] = np.sum(W * s0 * dop * proj**2 * np.cos(2 * phi))
        out[u, 2] = np.sum(W * s0 * dop * proj**2 * np.sin(2 * phi))
    return out


def simulate_readings(
    geometry,
    sun_azimuth_deg: float,
    sun_altitude_deg: float,
    bearings_deg,
    pitch_deg=0.0,
    roll_deg=0.0,
    dop_max: float = 0.7,
    brightness: float = 1000.0,
    noise_rel: float = 0.0,
    integrate: bool = True,
    rng=None,
) -> np.ndarray:
    """
    Simulate the readings of a body turning through a list of bearings.

    Parameters
    ----------
    geometry : ArrayGeometry
        Units, channels, gains and convention.
    sun_azimuth_deg : float
        Sun azimuth [deg].
    sun_altitude_deg : float
        Sun altitude [deg].
    bearings_deg : array_like
        (S,) true bearings of the body's front [deg].
    pitch_deg : float or array_like, optional
        The body's pitch [deg], scalar or (S,) (the geometry's mount is composed with it).
    roll_deg : float or array_like, optional
        The body's roll [deg], scalar or (S,).
    dop_max : float, optional
        Rayleigh maximum degree of polarization.
    brightness : float, optional
        Scale of S0 [counts].
    noise_rel : float, optional
        Gaussian noise sigma per channel, relative to ``brightness``.
    integrate : bool, optional
        Integrate each unit's acceptance cone.
    rng : numpy.random.Generator, optional
        Noise source (default: seeded 0).

    Returns
    -------
    numpy.ndarray
        (S, U, C) readings.

    """
    b = np.atleast_1d(np.asarray(bearings_deg, dtype=float))
    p = np.broadcast_to(np.asarray(pitch_deg, dtype=float), b.shape)
    r = np.broadcast_to(np.asarray(roll_deg, dtype=float), b.shape)
    C = geometry.n_channels
    out = np.zeros((b.size, geometry.n_units, C))
    for i in range(b.size):
        st = simulate_unit_stokes(
            geometry,
            sun_sensor(sun_azimuth_deg, sun_altitude_deg, b[i], p[i], r[i], geometry.mount),
            dop_max,
            integrate,
        )
        for u, unit in enumerate(geometry.units):
            n = unit.n_channels
            out[i, u, :n] = (
                brightness * np.asarray(unit.gains) * (design_matrix(unit.channels_deg) @ st[u])
            )
    if noise_rel > 0:
        rng = np.random.default_rng(0) if rng is None else rng
        out += rng.normal(0.0, noise_rel * brightness, out.shape)
    return out


class ArraySensor:
    """
    A photodiode-array sensor declared in a scene (``photodiode_array:``), read by the renderer.

    Config keys: ``geometry`` (a sensor description mapping, or a path to its YAML), ``brightness``
    (counts of S0, > 0, default 1000), ``noise_rel`` (Gaussian noise sigma per channel relative to
    ``brightness``, [0, 1], default 0), ``integrate`` (acceptance-cone integration, default true).
    The array is mounted like the default camera (camera +y = body front), so the scene's attitude
    is the body's.
    """

    KEYS = ('geometry', 'brightness', 'noise_rel', 'integrate')

    def __init__(
        self,
        geometry,
        brightness: float = 1000.0,
        noise_rel: float = 0.0,
        integrate: bool = True,
    ):
        self.geometry = geometry
        self.brightness = float(brightness)
        self.noise_rel = float(noise_rel)
        self.integrate = bool(integrate)

    @staticmethod
    def from_config(cfg) -> 'ArraySensor':
        """
        Validate a scene's ``photodiode_array`` mapping and build the sensor.

        Parameters
        ----------
        cfg : dict
            ``geometry`` (mapping or YAML path), ``brightness``, ``noise_rel``, ``integrate``.

        Returns
        -------
        ArraySensor
            The sensor.

        Raises
        ------
        ArrayGeometryError
            A key that is missing, unknown or out of range (one line).

        """
        from .geometry import ArrayGeometryError, geometry_from_dict, load_array_geometry

        if not isinstance(cfg, dict):
            raise ArrayGeometryError(
                "photodiode_array must be a mapping with 'geometry' (a mapping or a YAML path)"
            )
        unknown = sorted(set(map(str, cfg)) - set(ArraySensor.KEYS))
        if unknown:
            raise ArrayGeometryError(
                f'photodiode_array: unknown key(s) {", ".join(unknown)}; '
                f'known: {", ".join(ArraySensor.KEYS)}'
            )
        if 'geometry' not in cfg:
            raise ArrayGeometryError(
                'photodiode_array: missing geometry (a mapping or a YAML path)'
            )
        g = cfg['geometry']
        geometry = (
            load_array_geometry(g)
            if isinstance(g, str)
            else geometry_from_dict(g, 'photodiode_array.geometry')
        )

        def num(key, default, lo, hi):
            v = cfg.get(key, default)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float))
                or not math.isfinite(v)
                or not lo <= v <= hi
            ):
                raise ArrayGeometryError(
                    f'photodiode_array.{key} must be a number in [{lo:g}, {hi:g}], got {v!r}'
                )
            return float(v)

        integrate = cfg.get('integrate', True)
        if not isinstance(integrate, bool):
            raise ArrayGeometryError(
                f'photodiode_array.integrate must be true or false, got {integrate!r}'
            )
        b = num('brightness', 1000.0, 1e-9, 1e12)
        return ArraySensor(geometry, b, num('noise_rel', 0.0, 0.0, 1.0), integrate)

    def params(self) -> dict:
        """
        Return what a frame's metadata records about the sensor.

        Returns
        -------
        dict
            Units, convention, brightness, noise and integration.

        """
        return {
            'units': self.geometry.n_units,
            'angle_zero': self.geometry.angle_zero,
            'angle_sense': self.geometry.angle_sense,
            'brightness': self.brightness,
            'noise_rel': self.noise_rel,
            'integrate': self.integrate,
        }

    def read(self, s_body, dop_max: float, rng=None) -> np.ndarray:
        """
        Read one sample for the sun at ``s_body``.

        Parameters
        ----------
        s_body : array_like
            (3,) sun direction in the body frame.
        dop_max : float
            Rayleigh maximum degree of polarization.
        rng : numpy.random.Generator, optional
            Noise source (used when ``noise_rel`` > 0; default seeded 0).

        Returns
        -------
        numpy.ndarray
            (U, C) readings.

        """
        st = simulate_unit_stokes(
            self.geometry, self.geometry.sensor_from_body(s_body), dop_max, self.integrate
        )
        out = np.zeros((self.geometry.n_units, self.geometry.n_channels))
        for u, unit in enumerate(self.geometry.units):
            out[u, : unit.n_channels] = (
                self.brightness
                * np.asarray(unit.gains)
                * (design_matrix(unit.channels_deg) @ st[u])
            )
        if self.noise_rel > 0:
            rng = np.random.default_rng(0) if rng is None else rng
            out += rng.normal(0.0, self.noise_rel * self.brightness, out.shape)
        return out
