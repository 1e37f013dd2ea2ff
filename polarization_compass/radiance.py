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
Relative sky radiance (luminance) models, evaluated in the camera frame.

``make_radiance_model(cfg)`` builds a model from a scene's ``radiance`` mapping; the model answers
``radiance(sun_cam, zenith_cam, rays_cam) -> float32 (N,)``, the sky luminance relative to the
zenith (1 at the zenith). Only the sun and zenith directions are used, so any frame works as long
as rays, sun and zenith are in the same one.

CIE standard general sky (ISO 15469:2004 / CIE S 011/E:2003)
------------------------------------------------------------
    L / L_z = f(chi) phi(Z) / (f(Z_s) phi(0))
    gradation   phi(Z)  = 1 + a exp(b / cos Z)
                          (Z: zenith angle of the element)
    indicatrix  f(chi)  = 1 + c (exp(d chi) - exp(d pi / 2)) + e cos^2 chi
                          (chi: angle between element and sun)

with Z_s the sun's zenith angle (chi at the zenith equals Z_s, hence L = 1 there). The 15 standard
types (a, b, c, d, e) are in :data:`CIE_STANDARD_SKIES`; the default is type 12, "CIE standard
clear sky, low luminance turbidity". Below the horizon (cos Z <= 0) the gradation is continued with
its horizon value (phi = 1 for b < 0, as in the standard's phi(90 deg) = 1): finite and continuous;
those pixels are masked by the scene's validity (min altitude) anyway. A sun below the horizon is
accepted (the formula stays finite); the standard itself covers the sun above the horizon.

Scene YAML: ``radiance: {model: cie_clear}`` (type 12), ``{model: cie_clear, type: 13}``, or a
custom ``{model: cie_standard, a: ..., b: ..., c: ..., d: ..., e: ...}``.

"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange
import numpy as np

from .errors import CompassError
from .runtime import kernel_array

__all__ = [
    'RadianceError',
    'CIEStandardSky',
    'CIE_STANDARD_SKIES',
    'PreethamSky',
    'make_radiance_model',
    'MODEL_NAMES',
]


class RadianceError(CompassError):
    """Unknown radiance model or unusable parameters."""


#: CIE standard general sky types: number -> (a, b, c, d, e, description). ISO 15469:2004 Table 1.
CIE_STANDARD_SKIES: dict[int, tuple[float, float, float, float, float, str]] = {
    1: (
        4.0,
        -0.70,
        0.0,
        -1.0,
        0.00,
        'overcast, steep gradation towards zenith, azimuthal uniformity '
        '(CIE standard overcast sky)',
    ),
    2: (
        4.0,
        -0.70,
        2.0,
        -1.5,
        0.15,
        'overcast, steep gradation, slight brightening towards the sun',
    ),
    3: (1.1, -0.80, 0.0, -1.0, 0.00, 'overcast, moderately graded, azimuthal uniformity'),
    4: (
        1.1,
        -0.80,
        2.0,
        -1.5,
        0.15,
        'overcast, moderately graded, slight brightening towards the sun',
    ),
    5: (0.0, -1.00, 0.0, -1.0, 0.00, 'sky of uniform luminance'),
    6: (
        0.0,
        -1.00,
        2.0,
        -1.5,
        0.15,
        'partly cloudy, no gradation towards zenith, slight brightening towards the sun',
    ),
    7: (
        0.0,
        -1.00,
        5.0,
        -2.5,
        0.30,
        'partly cloudy, no gradation towards zenith, brighter circumsolar region',
    ),
    8: (
        0.0,
        -1.00,
        10.0,
        -3.0,
        0.45,
        'partly cloudy, no gradation towards zenith, distinct solar corona',
    ),
    9: (-1.0, -0.55, 2.0, -1.5, 0.15, 'partly cloudy, with the obscured sun'),
    10: (-1.0, -0.55, 5.0, -2.5, 0.30, 'partly cloudy, with brighter circumsolar region'),
    11: (-1.0, -0.55, 10.0, -3.0, 0.45, 'white-blue sky with distinct solar corona'),
    12: (-1.0, -0.32, 10.0, -3.0, 0.45, 'CIE standard clear sky, low luminance turbidity'),
    13: (-1.0, -0.32, 16.0, -3.0, 0.30, 'CIE standard clear sky, polluted atmosphere'),
    14: (-1.0, -0.15, 16.0, -3.0, 0.30, 'cloudless turbid sky with broad solar corona'),
    15: (-1.0, -0.15, 24.0, -2.8, 0.15, 'white-blue turbid sky with broad solar corona'),
}

#: Names accepted in a scene's ``radiance.model`` (``cie_clear``/``cie_standard``: the CIE model;
#: ``preetham``: :class:`PreethamSky`).
MODEL_NAMES = ('cie_clear', 'cie_standard', 'preetham')

_MIN_COS_Z = 1e-4  # b / cos Z with cos Z >= 1e-4: exp underflows to 0 cleanly for b < 0, never inf


class PerezParams(NamedTuple):
    """
    Hold one frame's float32 parameters of the Perez-form luminance kernel (CIE and Preetham).

    Parameters
    ----------
    sx, sy, sz, zx, zy, zz : numpy.float32
        Unit sun and zenith (ENU up) vectors in the camera frame.
    a, b : numpy.float32
        Gradation coefficients.
    c, d, e : numpy.float32
        Indicatrix coefficients.
    exp_d_half_pi : numpy.float32
        The indicatrix's ``exp(d pi / 2)`` term (0 for Preetham's form).
    inv_norm : numpy.float32
        1 / the zenith normaliser, so that the zenith's luminance is 1.

    """

    sx: np.float32
    sy: np.float32
    sz: np.float32
    zx: np.float32
    zy: np.float32
    zz: np.float32
    a: np.float32
    b: np.float32
    c: np.float32
    d: np.float32
    e: np.float32
    exp_d_half_pi: np.float32
    inv_norm: np.float32


def _perez_params(s, z, coefficients, exp_d_half_pi, inv_norm) -> PerezParams:
    """Return :class:`PerezParams` from the sun and zenith, (a, b, c, d, e) and the two terms."""
    f32 = np.float32
    a, b, c, d, e = coefficients
    return PerezParams(
        f32(s[0]),
        f32(s[1]),
        f32(s[2]),
        f32(z[0]),
        f32(z[1]),
        f32(z[2]),
        f32(a),
        f32(b),
        f32(c),
        f32(d),
        f32(e),
        f32(exp_d_half_pi),
        f32(inv_norm),
    )


@njit(parallel=True, cache=True, fastmath=True)
def _cie_kernel(rays, p, out):  # pragma: no cover
    """L/L_z = f(chi) phi(Z) * inv_norm, inv_norm = 1 / (f(Z_s) phi(0)); ``p`` a PerezParams."""
    n = rays.shape[1]
    one = np.float32(1.0)
    min_cz = np.float32(_MIN_COS_Z)
    for i in prange(n):
        px = rays[0, i]
        py = rays[1, i]
        pz = rays[2, i]
        cz = p.zx * px + p.zy * py + p.zz * pz
        cchi = p.sx * px + p.sy * py + p.sz * pz
        cchi = min(max(cchi, -one), one)
        chi = math.acos(cchi)
        # cos Z clamped to 1e-4: below the horizon exp(b / 1e-4) underflows to 0 for b < 0 (phi =
        # 1, the horizon value) and is 1 for b = 0 (phi = 1 + a, constant): the horizon value
        # continued, no inf
        phi = one + p.a * math.exp(p.b / max(cz, min_cz))
        f = one + p.c * (math.exp(p.d * chi) - p.exp_d_half_pi) + p.e * cchi * cchi
        out[i] = f * phi * p.inv_norm


def _gradation(cos_z, a, b):
    """
    Return the gradation phi(Z) in float64 for scalars or arrays.

    phi(Z) in float64 for scalars/arrays (horizon value continued below the horizon, as the
    kernel).
    """
    cz = np.asarray(cos_z, dtype=float)
    with np.errstate(under='ignore'):
        return 1.0 + a * np.exp(b / np.maximum(cz, _MIN_COS_Z))


def _indicatrix(chi_rad, c, d, e):
    chi = np.asarray(chi_rad, dtype=float)
    return 1.0 + c * (np.exp(d * chi) - math.exp(d * math.pi / 2)) + e * np.cos(chi) ** 2


class CIEStandardSky:
    """
    CIE standard general sky (ISO 15469).

    Relative luminance ``L / L_z = f(chi) phi(Z) / (f(Z_s) phi(0))`` (module docstring) with the
    coefficients of one of the 15 standard types or custom ones.

    Parameters
    ----------
    sky_type : int or None, default 12
        Standard sky type 1-15 (:data:`CIE_STANDARD_SKIES`); ignored when a..e are given.
    a, b : float, optional
        Custom gradation coefficients (|value| <= 100, b <= 0); all of a..e or none.
    c, d, e : float, optional
        Custom indicatrix coefficients (|value| <= 100); all of a..e or none.
    name : str, default 'cie_clear'
        Model name reported by :meth:`params` (``cie_clear`` or ``cie_standard``).

    Raises
    ------
    RadianceError
        Only some of a..e given, a non-number or out-of-range coefficient, a sky type that is not
        an integer 1-15, or coefficients that give a non-positive luminance somewhere on the sky.

    References
    ----------
    .. [1] ISO 15469:2004 / CIE S 011/E:2003, "Spatial distribution of daylight -- CIE standard
       general sky", Table 1.

    """

    def __init__(
        self, sky_type: int | None = 12, a=None, b=None, c=None, d=None, e=None, name='cie_clear'
    ):
        self.name = name
        custom = [v is not None for v in (a, b, c, d, e)]
        if any(custom):
            if not all(custom):
                raise RadianceError('a custom CIE sky needs all five parameters a, b, c, d, e')
            vals = []
            for key, v in zip('abcde', (a, b, c, d, e)):
                try:
                    f = float(v)
                except (TypeError, ValueError):
                    raise RadianceError(
                        f'CIE parameter {key} must be a number, got {v!r}'
                    ) from None
                if not math.isfinite(f) or abs(f) > 100:
                    raise RadianceError(
                        f'CIE parameter {key} must be finite and |{key}| <= 100, got {v!r}'
                    )
                vals.append(f)
            if vals[1] > 0:
                raise RadianceError(
                    f'CIE parameter b must be <= 0 (the gradation diverges at the horizon '
                    f'otherwise), got {vals[1]!r}'
                )
            self.sky_type = None
            self.description = 'custom CIE general sky'
        else:
            if isinstance(sky_type, bool) or sky_type is None:
                raise RadianceError(f'CIE sky type must be an integer 1-15, got {sky_type!r}')
            try:
                t = int(sky_type)
            except (TypeError, ValueError):
                raise RadianceError(
                    f'CIE sky type must be an integer 1-15, got {sky_type!r}'
                ) from None
            if t != sky_type or t not in CIE_STANDARD_SKIES:
                raise RadianceError(f'CIE sky type must be an integer 1-15, got {sky_type!r}')
            *vals, self.description = CIE_STANDARD_SKIES[t]
            self.sky_type = t
        self.a, self.b, self.c, self.d, self.e = (float(v) for v in vals)
        # the luminance must be positive over the whole sky and for any sun position
        chi = np.linspace(0.0, math.pi, 721)
        cz = np.cos(np.linspace(0.0, math.pi / 2, 361))
        f_min = float(_indicatrix(chi, self.c, self.d, self.e).min())
        phi_min = float(_gradation(cz, self.a, self.b).min())
        phi_below = float(_gradation(-1.0, self.a, self.b))
        if f_min <= 0 or phi_min <= 0 or phi_below <= 0:
            raise RadianceError(
                f'CIE parameters give a non-positive luminance (min indicatrix {f_min:.3g}, '
                f'min gradation {min(phi_min, phi_below):.3g})'
            )

    def params(self) -> dict:
        """
        Return the model's parameters and description.

        Returns
        -------
        dict
            ``model``, ``type`` (None for a custom sky), the coefficients ``a``..``e`` and the
            sky type's ``description``.

        """
        return {
            'model': self.name,
            'type': self.sky_type,
            'a': self.a,
            'b': self.b,
            'c': self.c,
            'd': self.d,
            'e': self.e,
            'description': self.description,
        }

    def zenith_normaliser(self, sun_zenith_rad: float) -> float:
        """
        Return f(Z_s) phi(0), the luminance at the zenith in the formula's units.

        Parameters
        ----------
        sun_zenith_rad : float
            Zenith angle of the sun Z_s [rad] (the angle chi between the zenith and the sun).

        Returns
        -------
        float
            Zenith luminance in the formula's (relative) units, float64; positive for every
            accepted set of coefficients.

        References
        ----------
        .. [1] ISO 15469:2004 / CIE S 011/E:2003, "Spatial distribution of daylight -- CIE standard
           general sky", Table 1.

        """
        return float(
            _indicatrix(sun_zenith_rad, self.c, self.d, self.e) * _gradation(1.0, self.a, self.b)
        )

    def radiance(self, sun_cam, zenith_cam, rays_cam):
        """
        Return the relative luminance L/L_z of unit rays.

        Any frame works as long as the rays, sun and zenith share it; below the horizon the
        gradation keeps its horizon value.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Sun direction (normalised here), in the frame of ``rays_cam``.
        zenith_cam : array_like, shape (3,)
            Zenith (up) direction (normalised here), in the same frame.
        rays_cam : array_like, shape (3, N)
            Unit viewing rays (converted to contiguous float32).

        Returns
        -------
        numpy.ndarray, shape (N,), float32
            Luminance L/L_z relative to the zenith (1 at the zenith), dimensionless and positive.

        References
        ----------
        .. [1] ISO 15469:2004 / CIE S 011/E:2003, "Spatial distribution of daylight -- CIE standard
           general sky", Table 1.

        """
        rays = kernel_array(rays_cam, np.float32)  # one argument type: the kernel compiles once
        s = np.asarray(sun_cam, dtype=np.float64).reshape(3)
        z = np.asarray(zenith_cam, dtype=np.float64).reshape(3)
        s = s / np.linalg.norm(s)
        z = z / np.linalg.norm(z)
        zs = math.acos(min(1.0, max(-1.0, float(np.dot(s, z)))))
        inv_norm = 1.0 / self.zenith_normaliser(zs)
        out = np.empty(rays.shape[1], np.float32)
        coefficients = (self.a, self.b, self.c, self.d, self.e)
        exp_d_half_pi = math.exp(self.d * math.pi / 2)
        _cie_kernel(rays, _perez_params(s, z, coefficients, exp_d_half_pi, inv_norm), out)
        return out


class PreethamSky:
    """
    The Preetham, Shirley & Smits (1999) daylight luminance model.

    Appendix A.2 of the paper (see References): the Perez luminance distribution with coefficients
    linear in the turbidity T (2 <= T <= 10),

        Y / Y_z = F(theta, gamma) / F(0, theta_s),
        F = (1 + A exp(B / cos theta)) (1 + C exp(D gamma) + E cos^2 gamma)
        A = 0.1787 T - 1.4630, B = -0.3554 T + 0.4275, C = -0.0227 T + 5.3251,
        D = 0.1206 T - 2.5771, E = -0.0670 T + 0.3703

    (theta: zenith angle of the element, gamma: its angle from the sun). Written from the paper; no
    maintained PyPI package provides it. The Perez indicatrix is the CIE one without the
    ``exp(d pi / 2)`` offset, so the CIE kernel evaluates it with that offset set to 0.
    Scene YAML: ``radiance: {model: preetham, turbidity: 3}``.

    Parameters
    ----------
    turbidity : float, default 3.0
        Atmospheric turbidity T, in [2, 10].
    name : str, default 'preetham'
        Model name reported by :meth:`params`.

    Raises
    ------
    RadianceError
        ``turbidity`` is not a number in [2, 10].

    References
    ----------
    .. [1] A. J. Preetham, P. Shirley and B. Smits, "A practical analytic model for daylight",
       SIGGRAPH 1999, appendix A.2.

    """

    def __init__(self, turbidity=3.0, name='preetham'):
        try:
            t = float(turbidity)
        except (TypeError, ValueError):
            raise RadianceError(
                f'Preetham turbidity must be a number in [2, 10], got {turbidity!r}'
            ) from None
        if isinstance(turbidity, bool) or not (math.isfinite(t) and 2.0 <= t <= 10.0):
            raise RadianceError(
                f'Preetham turbidity must be a number in [2, 10], got {turbidity!r}'
            )
        self.name = name
        self.turbidity = t
        self.a = 0.1787 * t - 1.4630
        self.b = -0.3554 * t + 0.4275
        self.c = -0.0227 * t + 5.3251
        self.d = 0.1206 * t - 2.5771
        self.e = -0.0670 * t + 0.3703

    def params(self) -> dict:
        """
        Return the model's parameters and its Perez coefficients.

        Returns
        -------
        dict
            ``model``, ``turbidity`` and the Perez coefficients ``A``..``E`` derived from it.

        """
        return {
            'model': self.name,
            'turbidity': self.turbidity,
            'A': self.a,
            'B': self.b,
            'C': self.c,
            'D': self.d,
            'E': self.e,
        }

    def zenith_normaliser(self, sun_zenith_rad: float) -> float:
        """
        Return F(0, theta_s), the Perez function at the zenith.

        Parameters
        ----------
        sun_zenith_rad : float
            Zenith angle of the sun theta_s [rad] (at the zenith gamma = theta_s).

        Returns
        -------
        float
            Zenith luminance in the formula's (relative) units, float64.

        References
        ----------
        .. [1] A. J. Preetham, P. Shirley and B. Smits, "A practical analytic model for daylight",
           SIGGRAPH 1999, appendix A.2.

        """
        g = float(sun_zenith_rad)
        return float(
            (1.0 + self.c * math.exp(self.d * g) + self.e * math.cos(g) ** 2)
            * _gradation(1.0, self.a, self.b)
        )

    def radiance(self, sun_cam, zenith_cam, rays_cam):
        """
        Return the relative luminance Y/Y_z of unit rays.

        Any frame works as long as the rays, sun and zenith share it; below the horizon the
        gradation keeps its horizon value.

        Parameters
        ----------
        sun_cam : array_like, shape (3,)
            Sun direction (normalised here), in the frame of ``rays_cam``.
        zenith_cam : array_like, shape (3,)
            Zenith (up) direction (normalised here), in the same frame.
        rays_cam : array_like, shape (3, N)
            Unit viewing rays (converted to contiguous float32).

        Returns
        -------
        numpy.ndarray, shape (N,), float32
            Luminance Y/Y_z relative to the zenith (1 at the zenith), dimensionless and positive.

        References
        ----------
        .. [1] A. J. Preetham, P. Shirley and B. Smits, "A practical analytic model for daylight",
           SIGGRAPH 1999, appendix A.2.

        """
        rays = kernel_array(rays_cam, np.float32)  # one argument type: the kernel compiles once
        s = np.asarray(sun_cam, dtype=np.float64).reshape(3)
        z = np.asarray(zenith_cam, dtype=np.float64).reshape(3)
        s = s / np.linalg.norm(s)
        z = z / np.linalg.norm(z)
        zs = math.acos(min(1.0, max(-1.0, float(np.dot(s, z)))))
        out = np.empty(rays.shape[1], np.float32)
        coefficients = (self.a, self.b, self.c, self.d, self.e)
        inv_norm = 1.0 / self.zenith_normaliser(zs)
        _cie_kernel(rays, _perez_params(s, z, coefficients, 0.0, inv_norm), out)
        return out


def make_radiance_model(cfg: dict | None):
    """
    Build a radiance model from a mapping like ``{"model": "cie_clear", "type": 12}``.

    Parameters
    ----------
    cfg : dict or None
        A scene's ``radiance`` mapping: ``model`` (one of :data:`MODEL_NAMES`, default
        ``cie_clear``) and either ``type`` (1-15) or custom ``a``..``e`` for the CIE models, or
        ``turbidity`` for ``preetham``. None means the CIE clear sky, type 12. Not modified.

    Returns
    -------
    CIEStandardSky or PreethamSky
        The model.

    Raises
    ------
    RadianceError
        ``cfg`` is not a mapping, the model name is unknown, a key is not allowed for the model,
        both a type and custom coefficients are given, or the model rejects its parameters.

    """
    if cfg is None:
        cfg = {'model': 'cie_clear'}
    if not isinstance(cfg, dict):
        raise RadianceError(
            f'radiance must be a mapping such as {{model: cie_clear}}, got {type(cfg).__name__}'
        )
    d = dict(cfg)
    name = d.pop('model', 'cie_clear')
    if name not in MODEL_NAMES:
        raise RadianceError(f'unknown radiance model {name!r}; known: {", ".join(MODEL_NAMES)}')
    if name == 'preetham':
        if set(d) - {'turbidity'}:
            raise RadianceError(
                f"unknown key(s) {sorted(set(d) - {'turbidity'})} for radiance model 'preetham'; "
                "allowed: ['turbidity']"
            )
        return PreethamSky(d.get('turbidity', 3.0))
    allowed = {'type', 'a', 'b', 'c', 'd', 'e'}
    unknown = set(d) - allowed
    if unknown:
        raise RadianceError(
            f'unknown key(s) {sorted(unknown)} for radiance model {name!r}; '
            f'allowed: {sorted(allowed)}'
        )
    custom = {k: d[k] for k in 'abcde' if k in d}
    if custom and 'type' in d:
        raise RadianceError('give either a CIE sky type or custom a, b, c, d, e, not both')
    if custom:
        return CIEStandardSky(None, name=name, **{k: custom.get(k) for k in 'abcde'})
    return CIEStandardSky(d.get('type', 12), name=name)
