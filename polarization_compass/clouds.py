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
A seeded cloud layer drifting with the wind: a stage of :mod:`polarization_compass.atmosphere`.

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
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba import njit, prange
import numpy as np

from .atmosphere_checks import _num, AtmosphereError
from .fastmath import exp_nonpos

__all__ = [
    'CloudGrid',
    'CloudParams',
    'CloudLayer',
    'cloud_light',
    'cloud_transmission_at',
    'cloud_over',
    'cloud_transmission',
    'grid_row_to_columns',
]


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


class CloudParams(NamedTuple):
    """
    Hold the cloud layer's parameters for one frame, as the kernels read them.

    Built by :meth:`CloudLayer.frame_params`.

    Attributes
    ----------
    height_over_scale : float
        Cloud height over the feature size.
    off_x, off_y : float
        Wind offset east and north since the scene's time [feature sizes].
    seed : int
        Noise seed.
    threshold : float
        Noise threshold of a cloud.
    inv_softness : float
        1 / softness of the cloud edges.
    overcast : bool
        Whether the sky is covered everywhere (coverage 1).
    tau_max : float
        Optical thickness of a cloud.

    """

    height_over_scale: float
    off_x: float
    off_y: float
    seed: int
    threshold: float
    inv_softness: float
    overcast: bool
    tau_max: float


@njit(parallel=True, cache=True)
def _cloud_kernel(rays, R, cp, bright, aop, dop, inten, min_dop, valid):  # pragma: no cover
    """Composite the clouds over rays ``rays`` (any selection), ``cp`` a :class:`CloudParams`."""
    height_over_scale, off_x, off_y, seed = cp.height_over_scale, cp.off_x, cp.off_y, cp.seed
    thr, inv_soft, overcast, tau_max = cp.threshold, cp.inv_softness, cp.overcast, cp.tau_max
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
    cp : CloudParams
        The layer's parameters for the frame (:meth:`CloudLayer.frame_params`).

    Returns
    -------
    float
        T in (0, 1].

    """
    u = R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
    e = R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
    nn = R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
    k = cp.height_over_scale / max(u, 0.02)
    v = _fbm(e * k - cp.off_x, nn * k - cp.off_y, cp.seed)
    d = 1.0 if cp.overcast else min(max((v - cp.threshold) * cp.inv_softness, 0.0), 1.0)
    t = exp_nonpos(-cp.tau_max * d)
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
        dp = dop[o : o + W]
        it = inten[o : o + W]
        if min_dop <= zero:
            # no pixel can fall below the minimum DoP: AoP and validity are not touched (a third
            # less memory traffic; the DoP of a valid pixel stays >= 0)
            for j in range(W):
                t = cloud_transmission(u0[j], u1[j], fy)
                dp[j], it[j] = cloud_over(it[j], t, dp[j], bright)
            continue
        ap = aop[o : o + W]
        vd = valid[o : o + W]
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


class CloudGrid(NamedTuple):
    """
    The cloud layer's grid over a pixel block for one frame, as the kernels read it.

    Built by :meth:`CloudLayer.grid`.

    Attributes
    ----------
    grays : numpy.ndarray, shape (3, Gy * Gx), float32
        Camera-frame rays of the grid points, row-major.
    R : numpy.ndarray, shape (3, 3), float64
        Rotation from the camera frame to ENU.
    rk, rk1 : numpy.ndarray, shape (H,), int64
        The grid rows below and above each pixel row.
    rf : numpy.ndarray, shape (H,), float32
        Each pixel row's fraction between them.
    cols : numpy.ndarray, shape (Gx,), int64
        The grid's pixel columns.
    cf : numpy.ndarray, shape (W,), float32
        Each pixel column's fraction between its two grid columns.

    """

    grays: np.ndarray
    R: np.ndarray
    rk: np.ndarray
    rk1: np.ndarray
    rf: np.ndarray
    cols: np.ndarray
    cf: np.ndarray


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

        It is the (1 - coverage) quantile of the field sampled at 40 000 seeded points over 200 x
        200 features.
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
        Return the interpolation grid of a pixel block, or None.

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
        CloudGrid or None
            The grid's rays, the rotation and the interpolation indices and fractions, or None;
            the layer's parameters for the frame are :meth:`frame_params`.

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
        R = np.ascontiguousarray(R_enu_cam, dtype=np.float64)
        return CloudGrid(grays, R, rk, rk1, rf, cols, cf)

    def frame_params(self, dt_s: float) -> CloudParams:
        """
        Return the layer's parameters for a frame, as the kernels read them.

        Parameters
        ----------
        dt_s : float
            Time since the scene's ``time_utc`` [s] (moves the clouds with the wind).

        Returns
        -------
        CloudParams
            Height, wind offsets, seed, threshold, softness, overcast and thickness.

        """
        return CloudParams(
            self.height_m / self.scale_m,
            self.wind_mps[0] * dt_s / self.scale_m,
            self.wind_mps[1] * dt_s / self.scale_m,
            self.seed,
            self.threshold,
            1.0 / self.softness,
            self.overcast,
            self.optical_thickness,
        )

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
        grays, R, rk, rk1, rf, cols, cf = g
        tu = np.empty((int(rk1[-1]) + 1, block_shape[1]), np.float32)
        _cloud_transmission_grid_kernel(grays, R, self.frame_params(dt_s), cols, cf, tu)
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
        _cloud_kernel(
            rays_cam,
            R,
            self.frame_params(dt_s),
            self.brightness,
            aop,
            dop,
            intensity,
            float(min_dop),
            valid,
        )
