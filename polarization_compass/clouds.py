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

import numpy as np

from .atmosphere_checks import _num, AtmosphereError
from .clouds_kernels import (
    _cloud_composite_grid_kernel,
    _cloud_kernel,
    _cloud_transmission_grid_kernel,
    _noise_at,
    CloudParams,
    GRID_STEP,
)
from .runtime import kernel_array

__all__ = [
    'CloudGrid',
    'CloudLayer',
]


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
            kernel_array(rays_cam),  # one argument type: the kernel compiles once
            R,
            self.frame_params(dt_s),
            self.brightness,
            aop,
            dop,
            intensity,
            float(min_dop),
            valid,
        )
