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
The sky, its clouds and the lens effects in one pass over a pixel block (issue 16, "Speed").

Rendered stage by stage, a frame with clouds and lens effects moves the image through memory three
times: the sky model writes AoP, DoP and validity, the cloud layer reads and rewrites the DoP and
the radiance, the lens reads the rays and rewrites them again (~80 MB per stage on a 2448 x 2048
frame, where the arithmetic is cheap). For a contiguous pixel block (the full frame or a stride-1
region) :class:`SkyEffects` evaluates, band by band of rows, the cloud layer on its grid
(:meth:`~polarization_compass.clouds.CloudLayer.grid`), then row by row the sky model, the
cloud composite and vignetting with the sun's disk and glare, in one parallel region, and writes
AoP, DoP, validity and radiance once; the lens-flare ghosts are then added over their bounding
boxes only.

The per-pixel formulas are the stages' own, inlined (:func:`~polarization_compass.sky.
rayleigh_pixel`, :func:`~polarization_compass.sky_bdl.bdl_pixel`, :func:`~polarization_compass.
clouds_kernels.cloud_transmission`, :func:`~polarization_compass.clouds_kernels.cloud_light`,
:func:`~polarization_compass.optics_kernels.lens_light`), applied in the stages' order (sky, clouds
with the minimum-DoP cut, lens); the DoP factors of the clouds and the lens (and the glare's own
ratio) share one division. A frame equals the staged one up to float32 rounding (a few 1e-7,
relative), and its AoP equals the ideal render's bit for bit: the sky kernels and this pass are
compiled with the project's fast-math flags :data:`~polarization_compass.fastmath.FM` (no
reciprocal estimates), so a pixel gets the same bits in a vectorised loop body and in a scalar
remainder. The float64 references of ``test/test_sky_effects_reference.py`` check both paths.

The renderer uses the pass when the scene declares clouds or lens effects and nothing the pass
does not evaluate (a radiance model, haze, a skyline, another sky model, a scattered or strided
selection): those scenes run stage by stage. A scene without clouds and lens effects never builds
it (its ideal sky kernel is unchanged). Measured on the 2448 x 2048 frame (docs/real-skies.md,
"Speed"): clouds, sun glare, flare and vignetting cost about 2x the ideal frame, where the three
stages cost 4.5x.
"""

from __future__ import annotations

from numba import njit, prange
import numpy as np

from .clouds import CloudGrid
from .clouds_kernels import (
    cloud_light,
    cloud_transmission,
    cloud_transmission_at,
    CloudParams,
    grid_row_to_columns,
)
from .fastmath import FM
from .optics_kernels import lens_light, LensParams
from .sky import rayleigh_pixel, RayleighSky
from .sky_bdl import bdl_pixel, BerryDennisLeeSky

__all__ = ['SkyEffects']

#: Sky models the pass evaluates, by class: the ``model`` number of :func:`_sky_effects_row`.
_MODELS = {RayleighSky: 0, BerryDennisLeeSky: 1}
#: Pixel rows per band of the pass (8 cloud-grid intervals: 9 grid rows, one shared with the next
#: band, evaluated by both).
_BAND = 64


@njit(inline='always', cache=True, fastmath=FM, error_model='numpy')
def _sky_effects_row(
    model, square, sp, lens, rx, ry, rz, u0, u1, fy, bright, min_dop, xcol, yi, ap, dp, vd, it
):  # pragma: no cover - compiled
    """
    Evaluate the sky, the clouds and the lens over one pixel row, writing each output once.

    ``model`` (0 Rayleigh, 1 BDL) and ``square`` (glare exponent 2) must be constants at the call
    site, so that each variant is a plain loop that vectorises (the other model's branch is pruned
    before typing: ``sp`` is that model's :class:`~polarization_compass.sky.RayleighParams` or
    :class:`~polarization_compass.sky_bdl.BdlParams`). Without clouds the transmission
    rows ``u0``, ``u1`` are 1 (radiance 1 and T = 1 leave the DoP as it is); without lens effects
    the lens parameters switch vignetting and the sun off (V = 1, G = 0).
    """
    one = np.float32(1.0)
    zero = np.float32(0.0)
    for c in range(rx.size):
        if model == 0:
            a, d, ok = rayleigh_pixel(rx[c], ry[c], rz[c], sp)
        else:
            a, d, ok = bdl_pixel(rx[c], ry[c], rz[c], sp)
        # clouds over a clear sky of radiance 1 (W transmitted, I1 in all), the minimum DoP on the
        # DoP under the clouds, d W / I1 (as a product: invalid pixels hold DoP 0, so the cut
        # leaves them as they are; valid = valid and not drop as a comparison of bools)
        w, i1 = cloud_light(one, cloud_transmission(u0[c], u1[c], fy), bright)
        drop = d * w < min_dop * i1
        a = zero if drop else a
        ok = ok > drop
        # the lens: I = I1 V + G with G = gn / gd, DoP d (W / I1) (I1 V / I) = d W V / I. One
        # division for both: with den = I1 V gd + gn = I gd and r = 1 / (gd den), G = gn den r and
        # d W V / I = d W V gd^2 r. A pixel that gets no light at all (V = 0, no sun) keeps its
        # DoP d W / I1, as the lens stage leaves it (V taken as 1 in the DoP factor only).
        v, gn, gd = lens_light(rx[c], ry[c], rz[c], xcol[c], yi, lens, square)
        i1v = i1 * v
        dark = i1v * gd + gn <= zero
        vd_ = one if dark else v
        den = i1 * vd_ * gd + gn
        r = one / (gd * den)
        i = i1v + gn * den * r
        d = zero if drop else d * w * (vd_ * gd * gd * r)
        ap[c] = a
        dp[c] = d
        vd[c] = ok
        it[c] = i


@njit(inline='always', cache=True, fastmath=FM, error_model='numpy')
def _sky_effects_pass(
    model, square, sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out
):  # pragma: no cover - compiled
    """
    Render a row-major pixel block: cloud grid, sky, clouds and lens per band of rows, one launch.

    Each band of ``_BAND`` pixel rows first evaluates the cloud layer on the grid rows it lies
    between (:func:`~polarization_compass.clouds_kernels.cloud_transmission_at`, the grid row
    shared by two bands evaluated by both) and interpolates them to every pixel column, into a
    buffer that stays in the cache; then :func:`_sky_effects_row` runs over each row's slices of
    the rays and the outputs (per-row slices: a flat index r * W + c kept such loops scalar,
    measured). One parallel region for the whole frame: on a shared machine each extra one waits
    for its slowest thread. Without clouds the band's T rows are 1. ``model`` and ``square`` are
    constants: each of :data:`_KERNELS` inlines this body with its own pair, so that the row loops
    vectorise. ``grid`` is a :class:`~polarization_compass.clouds.CloudGrid` (``cp`` the layer's
    :class:`~polarization_compass.clouds_kernels.CloudParams`: an argument of its own, as numba's
    parallel lowering finds a named tuple used in a ``prange`` body only from an argument or a
    constructor call, not from a field of another tuple), ``lens`` a
    :class:`~polarization_compass.optics_kernels.LensParams` and ``out`` the (aop, dop, valid,
    intensity) arrays, written.
    """
    aop, dop, valid, inten = out
    grays, R, rk, rk1, rf, cols, cf = grid
    W = xcol.size
    H = yrow.size
    one = np.float32(1.0)
    gx = grays.shape[1] // (rk1[H - 1] + 1) if clouds else 1
    for b in prange((H + _BAND - 1) // _BAND):
        r0 = b * _BAND
        r1 = min(r0 + _BAND, H)
        k0 = rk[r0] if clouds else 0
        nk = rk1[r1 - 1] - k0 + 1 if clouds else 1
        tu = np.empty((nk, W), np.float32)
        if clouds:
            tg = np.empty(gx, np.float32)
            for k in range(nk):
                g0 = (k0 + k) * gx
                for j in range(gx):
                    tg[j] = cloud_transmission_at(
                        grays[0, g0 + j], grays[1, g0 + j], grays[2, g0 + j], R, cp
                    )
                grid_row_to_columns(tg, cols, cf, tu[k])
        else:
            tu[:] = one
        for r in range(r0, r1):
            u0 = tu[rk[r] - k0] if clouds else tu[0]
            u1 = tu[rk1[r] - k0] if clouds else tu[0]
            fy = rf[r] if clouds else np.float32(0.0)
            o = r * W
            rx = rays[0, o : o + W]
            ry = rays[1, o : o + W]
            rz = rays[2, o : o + W]
            ap = aop[o : o + W]
            dp = dop[o : o + W]
            vd = valid[o : o + W]
            it = inten[o : o + W]
            yi = yrow[r]
            _sky_effects_row(
                model, square, sp, lens, rx, ry, rz, u0, u1, fy, bright, min_dop, xcol, yi, ap,
                dp, vd, it,
            )  # fmt: skip


# The pass compiled for each (sky model, glare exponent 2) pair, as optics' block kernel per glare
# law: numba.literally would specialise one kernel on its arguments but re-dispatches every call
# (~0.1 s, measured); run-time flags leave branches in the row loops.
@njit(parallel=True, cache=True, fastmath=FM, error_model='numpy')
def _rayleigh_square_kernel(
    sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out
):  # pragma: no cover - compiled
    """Run :func:`_sky_effects_pass` for a Rayleigh sky and the exponent-2 glare."""
    _sky_effects_pass(0, True, sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out)


@njit(parallel=True, cache=True, fastmath=FM, error_model='numpy')
def _rayleigh_power_kernel(
    sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out
):  # pragma: no cover - compiled
    """Run :func:`_sky_effects_pass` for a Rayleigh sky and another glare exponent."""
    _sky_effects_pass(0, False, sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out)


@njit(parallel=True, cache=True, fastmath=FM, error_model='numpy')
def _bdl_square_kernel(
    sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out
):  # pragma: no cover - compiled
    """Run :func:`_sky_effects_pass` for a Berry-Dennis-Lee sky and the exponent-2 glare."""
    _sky_effects_pass(1, True, sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out)


@njit(parallel=True, cache=True, fastmath=FM, error_model='numpy')
def _bdl_power_kernel(
    sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out
):  # pragma: no cover - compiled
    """Run :func:`_sky_effects_pass` for a Berry-Dennis-Lee sky and another glare exponent."""
    _sky_effects_pass(1, False, sp, rays, clouds, grid, cp, bright, min_dop, xcol, yrow, lens, out)


#: The pass's kernel by (sky ``model`` number, glare exponent is 2).
_KERNELS = {
    (0, True): _rayleigh_square_kernel,
    (0, False): _rayleigh_power_kernel,
    (1, True): _bdl_square_kernel,
    (1, False): _bdl_power_kernel,
}


class SkyEffects:
    """
    The one-pass render of a scene's sky, clouds and lens effects over a pixel block.

    Build it with :meth:`for_renderer`, which answers None for a scene the pass does not cover
    (module docstring); :meth:`render` then replaces the renderer's sky, atmosphere and optics
    stages for a frame. Each declared stage is still counted in
    :mod:`polarization_compass.instrumentation` (``sky.<model>``, ``atmosphere.clouds``,
    ``optics.<effect>``), and the pass itself as ``sky_effects``.

    Parameters
    ----------
    sky : RayleighSky or BerryDennisLeeSky
        The scene's sky model.
    clouds : CloudLayer or None
        The scene's cloud layer.
    optics : Optics or None
        The scene's lens effects.
    pixels : SelectedPixels
        The selected pixels: a 2-D row-major block (full frame or a stride-1 region).

    """

    def __init__(self, sky, clouds, optics, pixels):
        self.sky = sky
        self.model = _MODELS[type(sky)]
        self.clouds = clouds
        self.optics = optics
        self.pixels = pixels
        self.rays = np.ascontiguousarray(pixels.rays_cam, dtype=np.float32)
        self.xcol = np.ascontiguousarray(pixels.x_px[0], np.float32)
        self.yrow = np.ascontiguousarray(pixels.y_px[:, 0], np.float32)
        f32 = np.float32
        # a lens that adds nothing: no vignetting (mode 0), no sun (do_sun False), exponent 2
        self._no_lens = LensParams(
            0,
            f32(0.0),
            f32(0.0),
            f32(0.0),
            f32(0.0),
            f32(0.0),
            f32(0.0),
            False,
            f32(0.0),
            f32(0.0),
            f32(1.0),
            f32(0.0),
            f32(0.0),
            f32(0.0),
            f32(2.0),
        )
        # no clouds: placeholders (the kernel does not read them), T = 1
        z64 = np.zeros(1, np.int64)
        z32 = np.zeros(1, np.float32)
        self._no_clouds = CloudGrid(
            np.zeros((3, 1), np.float32),
            np.eye(3),
            z64,
            z64,
            z32,
            z64,
            z32,
        )
        self._no_cloud_params = CloudParams(1.0, 0.0, 0.0, 0, 0.0, 1.0, False, 0.0)

    @classmethod
    def for_renderer(cls, renderer) -> 'SkyEffects | None':
        """
        Return the one-pass render of a renderer's scene, or None when the pass does not cover it.

        Covered: a Rayleigh or Berry-Dennis-Lee sky, no radiance model, an atmosphere with clouds
        only (or none), any lens effects, at least one of clouds and lens effects, and a full frame
        or stride-1 region (larger than the cloud grid's step in both directions when clouds are
        declared).

        Parameters
        ----------
        renderer : Renderer
            A renderer, after its stages are built.

        Returns
        -------
        SkyEffects or None
            The pass, or None (the renderer then runs stage by stage).

        """
        atm, opt = renderer.atmosphere, renderer.optics
        sel, px = renderer.selection, renderer.pixels
        clouds = None if atm is None else atm.clouds
        if atm is not None and atm.stages != ['clouds']:
            return None
        if (clouds is None and opt is None) or renderer.radiance is not None:
            return None
        if type(renderer.sky) not in _MODELS:
            return None
        if sel.mode not in ('full', 'region') or sel.stride != 1 or len(px.shape) != 2:
            return None
        if clouds is not None:
            from .clouds_kernels import GRID_STEP

            if min(px.shape) <= 2 * GRID_STEP:
                return None
        return cls(renderer.sky, clouds, opt, px)

    def render(self, R_enu_cam, sun_cam, zenith_cam, limits, dt_s: float, instr):
        """
        Render the block's AoP, DoP, validity and radiance in one pass.

        Parameters
        ----------
        R_enu_cam : array_like, shape (3, 3)
            Rotation from the camera frame to ENU (the frame's attitude, eq 21).
        sun_cam, zenith_cam : array_like, shape (3,)
            Unit sun and zenith (ENU up) vectors in the camera frame.
        limits : tuple of float
            (cosine of the sun-exclusion radius, sine of the minimum altitude, minimum DoP).
        dt_s : float
            Time since the scene's ``time_utc`` [s] (moves the clouds).
        instr : module or object
            Instrumentation with ``stage(name)`` and ``count(name)``, normally
            :mod:`polarization_compass.instrumentation`.

        Returns
        -------
        aop : numpy.ndarray, shape (N,), float32
            AoP [rad], eq 28 convention, [-pi/2, pi/2); 0 where invalid.
        dop : numpy.ndarray, shape (N,), float32
            DoP [0, 1]; 0 where invalid.
        valid : numpy.ndarray, shape (N,), bool
            Validity (the scene's limits, the minimum DoP after the clouds).
        intensity : numpy.ndarray, shape (N,), float32
            Radiance relative to the clear zenith, after clouds and lens.

        """
        f32 = np.float32
        instr.count('sky.' + self.sky.name)
        sp = self.sky.pixel_params(sun_cam, zenith_cam, limits)
        grid, cp = self._no_clouds, self._no_cloud_params
        bright = f32(1.0)
        if self.clouds is not None:
            instr.count('atmosphere.clouds')
            grid = self.clouds.grid(R_enu_cam, self.rays, dt_s, self.pixels.shape)
            cp = self.clouds.frame_params(dt_s)
            bright = f32(self.clouds.brightness)
        lens, square, ghosts = self._no_lens, True, None
        if self.optics is not None:
            lens, square, ghosts = self.optics.frame_params(sun_cam, instr)
        n = self.rays.shape[1]
        aop = np.empty(n, np.float32)
        dop = np.empty(n, np.float32)
        valid = np.empty(n, np.bool_)
        inten = np.empty(n, np.float32)
        with instr.stage('sky_effects'):
            _KERNELS[self.model, bool(square)](
                sp,
                self.rays,
                self.clouds is not None,
                grid,
                cp,
                bright,
                f32(limits[2]),
                self.xcol,
                self.yrow,
                lens,
                (aop, dop, valid, inten),
            )
        if ghosts is not None:
            self.optics.add_ghosts(ghosts, self.xcol, self.yrow, dop, inten)
        return aop, dop, valid, inten
