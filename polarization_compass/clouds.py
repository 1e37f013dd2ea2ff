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
A single cloud layer at ``height_m`` above the camera. A viewing ray with ENU direction (e, n, u),
u > 0, meets it at the horizontal point ``height_m * (e, n) / u`` (metres); the layer moves with
the wind, so the point sampled at scene time t (s since the scene's ``time_utc``) is that minus
``wind_mps * t``. The density there is a seeded value-noise fBm (4 octaves, feature size
``scale_m``) thresholded so that a fraction ``coverage`` of the layer is cloudy, with a linear ramp
of width ``softness`` (in noise units) at the cloud edges: density d in [0, 1], optical thickness
tau = ``optical_thickness`` * d; ``coverage: 1`` is an overcast layer of uniform thickness.

Light through the cloud (single-layer two-stream picture): the clear-sky light of that direction is
transmitted with T = exp(-tau), polarization unchanged, and the cloud adds its own unpolarized
radiance ``brightness`` (1 - T) (relative to the clear zenith)::

    I = I_clear T + B (1 - T),    DoP = DoP_clear I_clear T / I,    AoP = AoP_clear.

So thin clouds raise the radiance and lower the DoP but keep the clear-sky AoP, as measured by
Pomozi, Horvath & Wehner (2001), "How the clear-sky angle of polarization pattern continues
underneath clouds", J. Exp. Biol. 204:2933-2942; thick clouds (tau >> 1) depolarize (DoP -> 0; the
residual AoP of overcast skies still follows the clear-sky pattern at DoP of a few per cent,
Hegedus, Akesson & Horvath (2007), J. Opt. Soc. Am. A 24:2347-2356). Pixels whose DoP falls below
the scene's ``validity.min_dop`` become invalid.

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

from .errors import CompassError
from .fastmath import exp_nonpos

__all__ = [
    'AtmosphereError',
    'Atmosphere',
    'CloudLayer',
    'Haze',
    'Skyline',
    'cloud_light',
    'cloud_transmission_at',
    'cloud_over',
    'cloud_transmission',
    'grid_row_to_columns',
    'haze_dop_factor',
]


class AtmosphereError(CompassError):
    """A scene's ``atmosphere`` mapping that cannot be used; the message names the key."""


def _num(d: dict, key: str, default, lo, hi, where: str) -> float:
    v = d.get(key, default)
    if isinstance(v, bool):
        raise AtmosphereError(f'atmosphere.{where}.{key} must be a number, got {v!r}')
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise AtmosphereError(f'atmosphere.{where}.{key} must be a number, got {v!r}') from None
    if not math.isfinite(f) or not (lo <= f <= hi):
        raise AtmosphereError(
            f'atmosphere.{where}.{key} must be finite and in [{lo}, {hi}], got {v!r}'
        )
    return f


def _keys(d, allowed, where):
    if not isinstance(d, dict):
        raise AtmosphereError(f'atmosphere.{where} must be a mapping, got {type(d).__name__}')
    unknown = set(d) - set(allowed)
    if unknown:
        raise AtmosphereError(
            f'unknown key(s) {sorted(unknown)} in atmosphere.{where}; allowed: {sorted(allowed)}'
        )


# ----------------------------------------------------------------------------------------------
# noise
_OCTAVES = 4  # written out in _fbm


@njit(inline='always', cache=True)
def _hash01(ix, iy, seed):  # pragma: no cover - compiled
    """Hash (ix, iy, seed) on a lattice to [0, 1) (integer mixing, wraps mod 2^32)."""
    h = (ix * 374761393 + iy * 668265263 + seed * 1442695041) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h = h ^ (h >> 16)
    return (h & 0xFFFFFF) / 16777216.0


@njit(inline='always', cache=True)
def _value_noise(x, y, seed):  # pragma: no cover - compiled
    x0 = math.floor(x)
    y0 = math.floor(y)
    fx = x - x0
    fy = y - y0
    ix = np.int64(x0)
    iy = np.int64(y0)
    sx = fx * fx * (3.0 - 2.0 * fx)
    sy = fy * fy * (3.0 - 2.0 * fy)
    a = _hash01(ix, iy, seed)
    b = _hash01(ix + 1, iy, seed)
    c = _hash01(ix, iy + 1, seed)
    d = _hash01(ix + 1, iy + 1, seed)
    return (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy


@njit(inline='always', cache=True)
def _fbm(x, y, seed):  # pragma: no cover - compiled
    """
    Return the fBm of 4 octaves of value noise at (x, y): sum of 2^-(o+1) noise_o over 0.9375.

    Written out octave by octave (amplitudes 0.5, 0.25, 0.125, 0.0625, their sum 0.9375, all
    exact): as a loop over the octaves the caller's loop over points stayed scalar; unrolled it
    vectorises (6x faster, measured), with the same values bit for bit.
    """
    s = 0.5 * _value_noise(x, y, seed)
    x = 2.0 * x + 17.3
    y = 2.0 * y - 5.1
    s += 0.25 * _value_noise(x, y, seed + 7919)
    x = 2.0 * x + 17.3
    y = 2.0 * y - 5.1
    s += 0.125 * _value_noise(x, y, seed + 2 * 7919)
    x = 2.0 * x + 17.3
    y = 2.0 * y - 5.1
    s += 0.0625 * _value_noise(x, y, seed + 3 * 7919)
    return s / 0.9375


@njit(parallel=True, cache=True)
def _noise_at(x, y, seed, out):  # pragma: no cover - compiled
    for i in prange(x.size):
        out[i] = _fbm(x[i], y[i], seed)


@njit(parallel=True, cache=True)
def _cloud_kernel(
    rays,
    R,
    height_over_scale,
    off_x,
    off_y,
    seed,
    thr,
    inv_soft,
    overcast,
    tau_max,
    bright,
    aop,
    dop,
    inten,
    min_dop,
    valid,
):  # pragma: no cover - compiled
    n = rays.shape[1]
    for i in prange(n):
        px = rays[0, i]
        py = rays[1, i]
        pz = rays[2, i]
        e = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
        nn = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
        u = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
        if u <= 0.0:
            continue  # below the horizon: no cloud layer there
        k = height_over_scale / max(u, 0.02)
        if overcast:
            d = 1.0
        else:
            v = _fbm(e * k - off_x, nn * k - off_y, seed)
            d = min(max((v - thr) * inv_soft, 0.0), 1.0)
        if d <= 0.0:
            continue
        t = math.exp(-tau_max * d)
        i_clear = inten[i]
        i_tot = i_clear * t + bright * (1.0 - t)
        dop[i] = np.float32(dop[i] * i_clear * t / i_tot)
        inten[i] = np.float32(i_tot)
        if dop[i] < min_dop and valid[i]:
            valid[i] = False
            aop[i] = np.float32(0.0)
            dop[i] = np.float32(0.0)


@njit(inline='always', cache=True, error_model='numpy')
def cloud_transmission_at(px, py, pz, R, cp):  # pragma: no cover - compiled
    """
    Return T = exp(-tau) of the cloud layer along one ray (1 below the horizon or between clouds).

    The cases are selects (exp(-0) = 1 between clouds), with the branch-free
    :func:`~polarization_compass.fastmath.exp_nonpos`, so that a loop over rays vectorises (the
    nested branches and the libm exp of a first version ran it ~10x slower, measured). Compiled,
    inlined.

    Parameters
    ----------
    px, py, pz : float
        Unit viewing ray in the camera frame.
    R : numpy.ndarray, shape (3, 3), float64
        Rotation from the camera frame to ENU.
    cp : tuple
        (height / scale, wind offset x and y [feature sizes], seed, noise threshold,
        1 / softness, overcast, optical thickness) from :meth:`CloudLayer.grid`.

    Returns
    -------
    float
        T in (0, 1].

    """
    height_over_scale, off_x, off_y, seed, thr, inv_soft, overcast, tau_max = cp
    u = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
    e = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
    nn = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
    k = height_over_scale / max(u, 0.02)
    v = _fbm(e * k - off_x, nn * k - off_y, seed)
    d = 1.0 if overcast else min(max((v - thr) * inv_soft, 0.0), 1.0)
    t = exp_nonpos(-tau_max * d)
    return t if u > 0.0 else 1.0


@njit(inline='always', cache=True, fastmath=True)
def grid_row_to_columns(tg, cols, cf, out):  # pragma: no cover - compiled
    """
    Interpolate one grid row of T linearly to every pixel column (compiled, inlined).

    ``out[j] = tg[g] (1 - cf[j]) + tg[g + 1] cf[j]`` for ``cols[g] <= j < cols[g + 1]``: the
    horizontal half of the bilinear interpolation, done once per grid row (8x fewer than per pixel
    row), so that a pixel row's T is a blend of two such rows (:func:`cloud_transmission`), a
    contiguous loop that vectorises. A segment of ``GRID_STEP`` pixels uses its fractions k / 8 as
    constants (exact in float32, the values of ``cf``): a fixed 8-wide loop, 2x faster than a
    gather per pixel (measured).

    Parameters
    ----------
    tg : numpy.ndarray, shape (Gx,), float32
        T at the grid row's points.
    cols : numpy.ndarray, shape (Gx,), int64
        The grid's pixel columns, increasing, the last one W - 1.
    cf : numpy.ndarray, shape (W,), float32
        Each pixel column's fraction between its two grid columns.
    out : numpy.ndarray, shape (W,), float32
        Output: T of the grid row at every pixel column.

    """
    one = np.float32(1.0)
    step = np.float32(1.0 / GRID_STEP)
    G = tg.size
    for g in range(G - 1):
        a = tg[g]
        b = tg[g + 1]
        c0 = cols[g]
        if cols[g + 1] - c0 == GRID_STEP:
            for k in range(GRID_STEP):
                f = np.float32(k) * step
                out[c0 + k] = a * (one - f) + b * f
        else:
            for j in range(c0, cols[g + 1]):
                out[j] = a * (one - cf[j]) + b * cf[j]
    out[out.size - 1] = tg[G - 1]


@njit(parallel=True, cache=True, error_model='numpy')
def _cloud_transmission_grid_kernel(grays, R, cp, cols, cf, out):  # pragma: no cover
    """T of the layer on each grid row, interpolated to every pixel column (out: (Gy, W))."""
    gx = grays.shape[1] // out.shape[0]
    for g in prange(out.shape[0]):
        tg = np.empty(gx, np.float32)
        for j in range(gx):
            i = g * gx + j
            tg[j] = cloud_transmission_at(grays[0, i], grays[1, i], grays[2, i], R, cp)
        grid_row_to_columns(tg, cols, cf, out[g])


@njit(inline='always', cache=True, fastmath=True)
def cloud_transmission(u0, u1, fy):  # pragma: no cover - compiled
    """
    Return a pixel's cloud transmission from the two grid rows around its row (float32).

    The vertical half of the bilinear interpolation of the layer's T from its grid
    (:meth:`CloudLayer.transmission_grid`): ``u0 (1 - fy) + u1 fy``, with ``u0``, ``u1`` the
    pixel's column of the grid rows below and above, already interpolated along the row, and ``fy``
    the row's fraction between them. Compiled, inlined into the composite loops.

    Parameters
    ----------
    u0, u1 : float32
        T of the grid rows below and above at the pixel's column.
    fy : float32
        Fraction of the way from the row below to the row above, [0, 1].

    Returns
    -------
    float32
        T at the pixel, (0, 1].

    """
    return u0 * (np.float32(1.0) - fy) + u1 * fy


@njit(inline='always', cache=True, fastmath=True)
def cloud_light(i_clear, t, bright):  # pragma: no cover - compiled
    """
    Return the transmitted clear-sky light and the total radiance under the cloud layer (float32).

    ``W = I_clear T`` (polarized as the clear sky) and ``I = W + B (1 - T)`` (the cloud's own light
    is unpolarized), so the DoP under the cloud is ``DoP_clear W / I`` (module docstring;
    :func:`cloud_over`). Compiled, inlined.

    Parameters
    ----------
    i_clear : float32
        Clear-sky radiance relative to the clear zenith.
    t : float32
        Transmission exp(-tau) of the layer along the ray, (0, 1].
    bright : float32
        The cloud's own radiance B relative to the clear zenith.

    Returns
    -------
    w : float32
        Transmitted clear-sky radiance.
    radiance : float32
        Radiance under the cloud.

    References
    ----------
    .. [1] I. Pomozi, G. Horvath and R. Wehner, "How the clear-sky angle of polarization pattern
       continues underneath clouds", J. Exp. Biol. 204:2933-2942, 2001.

    """
    w = i_clear * t
    return w, w + bright * (np.float32(1.0) - t)


@njit(inline='always', cache=True, fastmath=True)
def cloud_over(i_clear, t, dop, bright):  # pragma: no cover - compiled
    """
    Return the DoP and radiance of clear-sky light seen through the cloud layer (float32).

    ``I = I_clear T + B (1 - T)`` and ``DoP = DoP_clear I_clear T / I`` (:func:`cloud_light`).
    T = 1 leaves the pixel as it is. Compiled, inlined into the composite loops.

    Parameters
    ----------
    i_clear : float32
        Clear-sky radiance relative to the clear zenith.
    t : float32
        Transmission exp(-tau) of the layer along the ray, (0, 1].
    dop : float32
        Clear-sky DoP [0, 1].
    bright : float32
        The cloud's own radiance B relative to the clear zenith.

    Returns
    -------
    dop : float32
        DoP under the cloud.
    radiance : float32
        Radiance under the cloud.

    """
    w, i_tot = cloud_light(i_clear, t, bright)
    return dop * w / i_tot, i_tot


@njit(parallel=True, cache=True, fastmath=True)
def _cloud_composite_grid_kernel(
    tu, rk, rk1, rf, bright, aop, dop, inten, min_dop, valid
):  # pragma: no cover - compiled
    """
    Composite the clouds with the transmission interpolated bilinearly from the grid.

    Pixel row i lies between grid rows rk[i] and rk1[i] at fraction rf[i]; ``tu`` holds T of the
    grid rows at every pixel column (:meth:`CloudLayer.transmission_grid`).
    """
    H = rk.size
    W = tu.shape[1]
    zero = np.float32(0.0)
    for i in prange(H):
        # per-row slices: the composite is a plain loop that vectorises (a per-pixel gather and a
        # flat index i * W + j kept it scalar, measured)
        u0 = tu[rk[i]]
        u1 = tu[rk1[i]]
        fy = rf[i]
        o = i * W
        dp = dop[o:o + W]
        it = inten[o:o + W]
        if min_dop <= zero:
            # no pixel can fall below the minimum DoP: AoP and validity are not touched (a third
            # less memory traffic; the DoP of a valid pixel stays >= 0)
            for j in range(W):
                t = cloud_transmission(u0[j], u1[j], fy)
                dp[j], it[j] = cloud_over(it[j], t, dp[j], bright)
            continue
        ap = aop[o:o + W]
        vd = valid[o:o + W]
        for j in range(W):
            # branch-free (t = 1 leaves the pixel as it is); invalid pixels hold DoP 0, so "drop"
            # leaves them as they are; valid = valid and not drop as a comparison of bools (2x
            # faster than & and ~, measured)
            d, it[j] = cloud_over(it[j], cloud_transmission(u0[j], u1[j], fy), dp[j], bright)
            drop = d < min_dop
            dp[j] = zero if drop else d
            ap[j] = zero if drop else ap[j]
            vd[j] = vd[j] > drop


def _grid_axis(n: int, step: int):
    """
    Return the grid indices of an axis and each pixel's grid neighbours and fraction.

    Grid indices (every ``step``-th and the last) of an axis of n pixels, and per pixel its two
    grid neighbours and the fraction between them (float32).
    """
    idx = np.unique(np.minimum(np.arange(0, n - 1 + step, step), n - 1))
    k = np.minimum(np.searchsorted(idx, np.arange(n), side='right') - 1, idx.size - 1)
    k1 = np.minimum(k + 1, idx.size - 1)
    span = (idx[k1] - idx[k]).astype(float)
    f = np.where(span > 0, (np.arange(n) - idx[k]) / np.where(span > 0, span, 1.0), 0.0)
    return idx, k.astype(np.int64), k1.astype(np.int64), f.astype(np.float32)


#: A contiguous block is clouded from T on every GRID_STEP-th pixel, interpolated (see
#: CloudLayer.apply).
GRID_STEP = 8


class CloudLayer:
    """
    A procedural cloud layer (see the module docstring for the model and its references).

    Parameters
    ----------
    coverage : float, default 0.5
        Fraction of the layer that is cloudy, [0, 1]; 1 is a uniform overcast layer.
    scale_m : float, default 800.0
        Feature size of the cloud field [m], [1, 1e6].
    height_m : float, default 2000.0
        Cloud base above the camera [m], [1, 2e4].
    optical_thickness : float, default 3.0
        Optical thickness tau of a full-density cloud, [0, 200].
    brightness : float, default 1.5
        Radiance of an optically thick cloud relative to the clear zenith, [1e-3, 1e3].
    softness : float, default 0.08
        Width of the cloud-edge ramp in noise units, [1e-4, 1].
    wind_mps : sequence of 2 float, default (0.0, 0.0)
        Layer velocity (east, north) [m/s], each |v| <= 200.
    seed : int, default 0
        Seed of the cloud field (derived from the scene's).

    Raises
    ------
    AtmosphereError
        A parameter is not a number, not finite or out of its range (the message names the key).

    References
    ----------
    .. [1] I. Pomozi, G. Horvath and R. Wehner, "How the clear-sky angle of polarization pattern
       continues underneath clouds", J. Exp. Biol. 204:2933-2942, 2001.
    .. [2] R. Hegedus, S. Akesson and G. Horvath, J. Opt. Soc. Am. A 24:2347-2356, 2007.

    """

    def __init__(
        self,
        coverage=0.5,
        scale_m=800.0,
        height_m=2000.0,
        optical_thickness=3.0,
        brightness=1.5,
        softness=0.08,
        wind_mps=(0.0, 0.0),
        seed=0,
    ):
        d = {
            'coverage': coverage,
            'scale_m': scale_m,
            'height_m': height_m,
            'optical_thickness': optical_thickness,
            'brightness': brightness,
            'softness': softness,
        }
        self.coverage = _num(d, 'coverage', 0.5, 0.0, 1.0, 'clouds')
        self.scale_m = _num(d, 'scale_m', 800.0, 1.0, 1e6, 'clouds')
        self.height_m = _num(d, 'height_m', 2000.0, 1.0, 2e4, 'clouds')
        self.optical_thickness = _num(d, 'optical_thickness', 3.0, 0.0, 200.0, 'clouds')
        self.brightness = _num(d, 'brightness', 1.5, 1e-3, 1e3, 'clouds')
        self.softness = _num(d, 'softness', 0.08, 1e-4, 1.0, 'clouds')
        try:
            w = [float(v) for v in wind_mps]
        except (TypeError, ValueError):
            raise AtmosphereError(
                f'atmosphere.clouds.wind_mps must be [east, north] in m/s, got {wind_mps!r}'
            ) from None
        if len(w) != 2 or not all(math.isfinite(v) and abs(v) <= 200 for v in w):
            raise AtmosphereError(
                'atmosphere.clouds.wind_mps must be [east, north], |v| <= 200 m/s, got '
                f'{wind_mps!r}'
            )
        self.wind_mps = (w[0], w[1])
        self.seed = int(seed) & 0x7FFFFFFF
        self.overcast = self.coverage >= 1.0
        self.threshold = self._threshold()

    def _threshold(self) -> float:
        """
        Return the noise level above which a fraction ``coverage`` of the layer is cloudy.

        The noise level above which a fraction ``coverage`` of the layer is cloudy: the (1 -
        coverage) quantile of the field sampled at 40 000 seeded points over 200 x 200 features.
        """
        if self.overcast:
            return -1.0
        if self.coverage <= 0.0:
            return 2.0
        rng = np.random.default_rng([self.seed, 0xC10D])
        x = rng.uniform(-100.0, 100.0, 40000)
        y = rng.uniform(-100.0, 100.0, 40000)
        v = np.empty_like(x)
        _noise_at(x, y, self.seed, v)
        return float(np.quantile(v, 1.0 - self.coverage))

    def params(self) -> dict:
        """
        Return the layer's parameters, as a scene's ``atmosphere.clouds`` mapping writes them.

        Returns
        -------
        dict
            ``coverage``, ``scale_m`` [m], ``height_m`` [m], ``optical_thickness``,
            ``brightness``, ``softness`` and ``wind_mps`` [m/s] as a list (east, north).

        """
        return {
            'coverage': self.coverage,
            'scale_m': self.scale_m,
            'height_m': self.height_m,
            'optical_thickness': self.optical_thickness,
            'brightness': self.brightness,
            'softness': self.softness,
            'wind_mps': list(self.wind_mps),
        }

    def density_at(self, east_m, north_m, dt_s: float = 0.0) -> np.ndarray:
        """
        Return the cloud density in [0, 1] at horizontal points of the layer.

        The layer has moved by ``wind_mps * dt_s`` since the scene's time; the density is the
        thresholded, edge-ramped noise field (module docstring).

        Parameters
        ----------
        east_m, north_m : array_like
            Horizontal position in the layer [m] east and north of the camera (flattened).
        dt_s : float, default 0.0
            Time since the scene's ``time_utc`` [s].

        Returns
        -------
        numpy.ndarray, shape (N,), float64
            Density d in [0, 1] (all ones for an overcast layer).

        """
        e = np.asarray(east_m, dtype=float).ravel()
        n = np.asarray(north_m, dtype=float).ravel()
        if self.overcast:
            return np.ones_like(e)
        x = (e - self.wind_mps[0] * dt_s) / self.scale_m
        y = (n - self.wind_mps[1] * dt_s) / self.scale_m
        v = np.empty_like(x)
        _noise_at(x, y, self.seed, v)
        return np.clip((v - self.threshold) / self.softness, 0.0, 1.0)

    def grid(self, R_enu_cam, rays_cam, dt_s: float, block_shape):
        """
        Return the interpolation grid of a pixel block and the layer's parameters, or None.

        With ``block_shape`` (H, W) of a contiguous pixel block (full frame or a stride-1 region,
        both sides longer than ``2 GRID_STEP``) T = exp(-tau) is evaluated on every
        ``GRID_STEP``-th row and column (and the last ones) and interpolated bilinearly: along
        each grid row to every pixel column (:func:`grid_row_to_columns`), then between the two
        grid rows around a pixel row (:func:`cloud_transmission`). Any other selection gives None.

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU.
        rays_cam : numpy.ndarray, shape (3, H * W), float32
            Unit viewing rays of the block in the camera frame, row-major, contiguous.
        dt_s : float
            Time since the scene's ``time_utc`` [s] (moves the layer with the wind).
        block_shape : tuple of int or None
            (H, W) of the block, or None.

        Returns
        -------
        tuple or None
            (grays (3, Gy * Gx) float32 rays of the grid points, row-major; R (3, 3) float64; cp,
            the parameters of :func:`cloud_transmission_at`; rk, rk1 (H,) int64 the grid rows
            below and above each pixel row; rf (H,) float32 the fraction between them; cols
            (Gx,) int64 the grid's pixel columns; cf (W,) float32 each pixel column's fraction
            between its two grid columns), or None.

        """
        if block_shape is None or min(block_shape) <= 2 * GRID_STEP:
            return None
        H, W = block_shape
        key = (id(rays_cam), H, W)
        if getattr(self, '_grid_key', None) != key:
            rows, rk, rk1, rf = _grid_axis(H, GRID_STEP)
            cols, _, _, cf = _grid_axis(W, GRID_STEP)
            grays = np.ascontiguousarray(
                rays_cam.reshape(3, H, W)[:, rows][:, :, cols].reshape(3, -1)
            )
            self._grid = (grays, rk, rk1, rf, cols.astype(np.int64), cf)
            self._grid_key = key
            self._grid_rays = rays_cam  # keep it alive so that its id stays its own
        grays, rk, rk1, rf, cols, cf = self._grid
        cp = (
            self.height_m / self.scale_m,
            self.wind_mps[0] * dt_s / self.scale_m,
            self.wind_mps[1] * dt_s / self.scale_m,
            self.seed,
            self.threshold,
            1.0 / self.softness,
            self.overcast,
            self.optical_thickness,
        )
        R = np.ascontiguousarray(R_enu_cam, dtype=np.float64)
        return grays, R, cp, rk, rk1, rf, cols, cf

    def transmission_grid(self, R_enu_cam, rays_cam, dt_s: float, block_shape):
        """
        Return the layer's transmission on the grid rows of a pixel block, or None.

        T on the grid rows of :meth:`grid`, interpolated to every pixel column.

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU.
        rays_cam : numpy.ndarray, shape (3, H * W), float32
            Unit viewing rays of the block in the camera frame, row-major, contiguous.
        dt_s : float
            Time since the scene's ``time_utc`` [s] (moves the layer with the wind).
        block_shape : tuple of int or None
            (H, W) of the block, or None.

        Returns
        -------
        tuple or None
            (tu (Gy, W) float32 T of the grid rows at every pixel column, rk, rk1 (H,) int64 the
            grid rows below and above each pixel row, rf (H,) float32 the fraction between them),
            or None (see :meth:`grid`).

        """
        g = self.grid(R_enu_cam, rays_cam, dt_s, block_shape)
        if g is None:
            return None
        grays, R, cp, rk, rk1, rf, cols, cf = g
        tu = np.empty((int(rk1[-1]) + 1, block_shape[1]), np.float32)
        _cloud_transmission_grid_kernel(grays, R, cp, cols, cf, tu)
        return tu, rk, rk1, rf

    def apply(
        self,
        R_enu_cam,
        rays_cam,
        aop,
        dop,
        intensity,
        valid,
        min_dop: float,
        dt_s: float,
        block_shape=None,
    ) -> None:
        """
        Apply the clouds to the flat clear-sky arrays, in place.

        Each ray is attenuated by T = exp(-tau) and gains the cloud's unpolarized radiance
        ``brightness (1 - T)``; the AoP is kept (module docstring). With ``block_shape`` (H, W) of
        a contiguous pixel block (full frame or a stride-1 region) the layer's transmission is
        evaluated on every ``GRID_STEP``-th row and column (and the last ones) and interpolated
        bilinearly, 64x fewer noise evaluations (the field changes over many pixels: cloud edges
        are smoothed over a few pixels, and pixels just below the horizon next to a cloud get part
        of it -- they are not sky anyway); any other selection is evaluated at every pixel.

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
        min_dop : float
            Minimum DoP; pixels whose DoP falls below it become invalid (aop = dop = 0).
        dt_s : float
            Time since the scene's ``time_utc`` [s] (moves the layer with the wind).
        block_shape : tuple of int or None, default None
            (H, W) of a contiguous pixel block in row-major order, or None for any other
            selection.

        """
        grid = self.transmission_grid(R_enu_cam, rays_cam, dt_s, block_shape)
        if grid is not None:
            _cloud_composite_grid_kernel(
                *grid,
                np.float32(self.brightness),
                aop,
                dop,
                intensity,
                np.float32(min_dop),
                valid,
            )
            return
        R = np.ascontiguousarray(R_enu_cam, dtype=np.float64)
        off_x = self.wind_mps[0] * dt_s / self.scale_m
        off_y = self.wind_mps[1] * dt_s / self.scale_m
        _cloud_kernel(
            rays_cam,
            R,
            self.height_m / self.scale_m,
            off_x,
            off_y,
            self.seed,
            self.threshold,
            1.0 / self.softness,
            self.overcast,
            self.optical_thickness,
            self.brightness,
            aop,
            dop,
            intensity,
            float(min_dop),
            valid,
        )


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
        return [
            n for n in ('haze', 'clouds', 'skyline', 'ground') if getattr(self, n) is not None
        ]

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
