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
Sensor effects: a rendered (ideal) frame through a division-of-focal-plane camera and back.

:class:`SensorPipeline` turns the ideal AoP/DoP (and relative radiance, if the scene has one) of a
contiguous pixel block into the raw mosaic a polarization camera would record, then demosaics it
back into the *measured* AoP/DoP that estimators see. It runs only when a scene declares sensor
effects, and each effect runs only if declared.

Scene schema (``sensor:`` mapping, validated by :mod:`polarization_compass.sensor_config`; every
key optional, defaults are a Sony IMX250MZR)::

    sensor:
      mosaic: {layout: [[90, 45], [135, 0]], pol45_toward: "+x-y"}   # or "+x+y"; see ``demosaic``
      exposure: {full_well_e: 10500, fill: 0.5}
      shot_noise: {gaussian_above_e: 20}      # Poisson photon noise; {} for the default
      read_noise: {sigma_e: 2.3}              # Gaussian read noise, electrons rms
      quantization: {bits: 12}                # 8, 10, 12, 14 or 16
      extinction_ratio: {value: 100}          # finite polarizer extinction ratio (> 1)
      calibration: {angle_error_deg: 0.5, extinction_ratio_spread: 0.2, gain_rms: 0.01,
                    crosstalk: 0.02, seed: 0}  # per-pixel DoFP calibration errors (fixed pattern)
      demosaic: bilinear                      # or superpixel
      ifov_check: {k_sigma: 4}                # 0 = off; see ``demosaic`` ("IFOV check")

``{}`` or null parameters mean the defaults shown. Once any key is declared the mosaic and the
demosaic always run (IMX250MZR layout if ``mosaic`` is absent). Each other effect is a stage of its
own that runs only if declared; its arithmetic exists only in the kernels of that stage
(``_IMPLEMENTS``):

- ``mosaic``: Malus's law per pixel behind ideal polarizers (``_mean_electrons_kernel``);
- ``extinction_ratio``: the same with leaky polarizers (``_mean_electrons_er_kernel`` replaces it);
- ``shot_noise`` / ``read_noise``: ``_shot_noise_kernel``, ``_read_noise_kernel``, or both fused in
  ``_shot_read_noise_kernel`` (one Gaussian draw of the summed variance);
- ``exposure``: the finite well, saturation at ``full_well_e`` (``_saturate_kernel``, fused into
  the DN pass as ``_saturate_quantize_kernel`` when quantised). Without it the well is unlimited:
  nothing saturates. The electron scale ``N0 = fill * full_well_e`` is a parameter of every
  electron-domain stage, not a computation; without ``exposure`` it is the default's 5250 e-;
- ``quantization``: electrons to DN (``_quantize_kernel``); the ADC range clips at 2^bits - 1.
- ``calibration``: the calibration errors of a real division-of-focal-plane sensor, a fixed pattern
  per pixel drawn once from ``calibration.seed`` over the whole sensor (so a region render sees the
  same pixels' errors as a full one): polarizer angle error delta ~ N(0, ``angle_error_deg``) added
  to the pixel's nominal angle; extinction ratio ER exp(``extinction_ratio_spread`` z), z ~ N(0, 1)
  (needs ``extinction_ratio``); gain 1 + ``gain_rms`` z (photo-response non-uniformity); then
  crosstalk: each pixel passes a fraction ``crosstalk`` of its electrons to each of its 4
  neighbours (edge pixels keep what would leave the block). ``_mean_electrons_cal_kernel`` replaces
  the Malus kernels and ``_crosstalk_kernel`` follows it. The per-pixel model of angle, extinction
  and gain is that of Powell & Gruev (2013), "Calibration methods for division-of-focal-plane
  polarimeters", Opt. Express 21:21039; crosstalk between neighbouring micro-polarizers as
  discussed there and by York & Gruev (2012), "Characterization of a visible spectrum
  division-of-focal-plane polarimeter", Appl. Opt. 51:5392.

Each kernel run counts, in :mod:`instrumentation`, ``sensor.<effect>`` for every effect the kernel
implements and ``sensor.kernel.<kernel>``; the demosaic counts ``sensor.demosaic.<method>``. A
stage that is not declared is neither run nor counted (tests replace its kernels by ones that
raise).

Physics
-------
A pixel behind a polarizer at camera-frame angle ``phi`` (from +x_cam towards +y_cam) sees
``I = (S0 / 2) (1 + d DoP cos 2(phi - AoLP_x))`` with ``d = (ER - 1) / (ER + 1)`` (d = 1 without
``extinction_ratio``) and ``AoLP_x = pi/2 - AoP`` (paper convention, physics notes 1), i.e.
``I = (S0 / 2) (1 - d DoP (cos 2phi cos 2AoP - sin 2phi sin 2AoP))``. S0 is the frame's relative
radiance (``frame.intensity``) or 1 for a uniform sky.

Mean photo-electrons: ``lambda = 2 I N0 = N0 S0 (1 + ...)`` with ``N0 = fill * full_well_e``, the
electrons of an unpolarized S0 = 1 pixel. Shot noise: exact Poisson (Knuth's product method) where
``lambda < gaussian_above_e``, else Gaussian with the same mean and variance (at 20 e- the Poisson
skewness 1/sqrt(20) = 0.22 is the only difference; it falls as 1/sqrt(lambda)). Read noise:
Gaussian ``sigma_e``; with shot noise in the Gaussian regime both are one draw of variance ``lambda
+ sigma_e^2`` (independent Gaussians add). With ``exposure`` the signal is then clipped at
``full_well_e`` (saturation; clipped pixels read exactly full scale and the demosaic marks them
invalid). Without ``quantization`` the mosaic is float32 electrons (read noise can make it slightly
negative); with it, ``DN = round(e * (2^bits - 1) / full_well_e)`` clipped to [0, 2^bits - 1],
uint8 for 8 bits else uint16. The demosaic does not correct for ``d`` (like an uncalibrated
camera): measured DoP = d * DoP.

Random numbers: a counter-based SplitMix64 stream (pixel (i, j) of a W-wide block owns counters
``(i W + j) * 1024 ...``, keyed by one 64-bit draw from the frame's ``numpy.random.Generator``)
feeding a 256-layer ziggurat (Marsaglia & Tsang 2000; tables solved at import) for normals
(:mod:`polarization_compass.rng`), in a numba kernel parallel over rows whose fast path (98.5 % of
draws) is branch-free and vectorises.
The same seed gives the same mosaic bit for bit, whatever the thread count. Measured single-core
for 5 Mpixels: shot + read noise ~24 ms, against 50-67 ms for
``Generator.standard_normal(dtype=float32)`` alone; the whole mosaic + shot + read noise + 12-bit
stage ~30 ms (up to ~50 ms while the machine was shared).

Output geometry (``frame`` is modified in place)
------------------------------------------------
``frame.aop_ideal_rad``/``frame.dop_ideal`` keep the noise-free values; ``frame.mosaic`` is the raw
image of the rendered pixel block (its 2 x 2 phase follows the block's position on the full sensor,
whose pixel (1, 1) carries ``layout[0][0]``); ``aop_rad``/``dop``/``valid`` become the measured
values.

- ``bilinear`` (default): same shape and pixels. A measured pixel is valid only if its whole 3 x 3
  neighbourhood was valid in the ideal render (sun disk, horizon, fisheye edge) and the demosaic
  says so (no saturation, S0 > 0, AoP defined).
- ``superpixel``: half resolution. ``frame.pixels`` is replaced by the 2 x 2 block centres
  (x_px/y_px at half-pixel positions, rays from the camera model, cached); ``intensity`` becomes
  the block mean; the ideal AoP/DoP become those of the block's mean ideal Stokes vector (what a
  perfect co-located superpixel measures); valid needs all four ideal pixels valid. An odd trailing
  row/column is dropped.

Sensor effects need a contiguous block of pixels (``pixels.mode`` full or region with stride 1).

"""

from __future__ import annotations

from functools import lru_cache

from numba import njit, prange
import numpy as np

from . import instrumentation as instr
from .camera import CameraModel
from .camera_pixels import SelectedPixels
from .demosaic import polarization_from_mosaic
from .demosaic_kernels import _finish
from .fastmath import sincos32
from .mosaic import MosaicLayout, SensorError
from .rng import standard_normal_f32
from .sensor_calibration import calibration_maps
from .sensor_config import (
    EFFECTS,
    parse_sensor_config,
    sensor_config_for_encoding,
    SensorConfig,
)
from .sensor_kernels import (
    _count,
    _crosstalk_kernel,
    _FM,
    _mean_electrons_cal_kernel,
    _mean_electrons_er_kernel,
    _mean_electrons_kernel,
    _quantize_kernel,
    _read_noise_kernel,
    _saturate_kernel,
    _saturate_quantize_kernel,
    _shot_noise_kernel,
    _shot_read_noise_kernel,
)

__all__ = [
    'SensorError',
    'SensorPipeline',
    'EFFECTS',
    'standard_normal_f32',
    'simulate_mosaic',
    'superpixel_pixels',
    'sensor_config_for_encoding',
]


def simulate_mosaic(
    aop_rad,
    dop,
    s0,
    cfg: SensorConfig,
    layout: MosaicLayout,
    rng: np.random.Generator,
    block_origin: tuple[int, int] = (0, 0),
):
    """
    Return the raw image of a pixel block (electrons or DN).

    ``aop_rad``/``dop``/``s0`` (or ``s0=None`` for S0 = 1): 2-D float arrays of the block;
    ``layout`` already shifted to the block's top-left pixel, ``block_origin`` that pixel's 0-based
    (row, col) on the full sensor (where the calibration pattern is read). Only the kernels of
    declared effects run; each run is counted in ``instrumentation`` (see ``_IMPLEMENTS``).

    Parameters
    ----------
    aop_rad : numpy.ndarray
        2-D AoP [rad] of the block in the paper's eq 28 convention.
    dop : numpy.ndarray
        2-D DoP in [0, 1] of the block.
    s0 : numpy.ndarray or None
        2-D relative radiance S0 of the block; None for S0 = 1.
    cfg : SensorConfig
        Validated sensor parameters.
    layout : MosaicLayout
        Mosaic layout shifted to the block's top-left pixel.
    rng : numpy.random.Generator
        Source of the one 64-bit key of the frame's noise stream.
    block_origin : tuple of int, default (0, 0)
        0-based (row, col) of the block's top-left pixel on the full sensor.

    Returns
    -------
    numpy.ndarray
        The mosaic, the block's shape: float32 electrons without quantisation, else uint8 (8
        bits) or uint16 DN.

    Raises
    ------
    SensorError
        When the AoP, DoP and S0 are not 2-D images of one shape.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28 (AoP convention).
    .. [2] S. B. Powell and V. Gruev, "Calibration methods for division-of-focal-plane
       polarimeters", Opt. Express 21: 21039, 2013.

    """
    aop = np.ascontiguousarray(aop_rad, dtype=np.float32)
    dp = np.ascontiguousarray(dop, dtype=np.float32)
    has_s0 = s0 is not None
    s0a = np.ascontiguousarray(s0, dtype=np.float32) if has_s0 else np.empty((1, 1), np.float32)
    if aop.ndim != 2 or dp.shape != aop.shape or (has_s0 and s0a.shape != aop.shape):
        raise SensorError(
            f'aop, dop and intensity must be 2-D images of one shape, got {aop.shape}, {dp.shape}'
            + (f', {s0a.shape}' if has_s0 else '')
        )
    e = _mean_electrons(aop, dp, s0a, has_s0, cfg, layout, block_origin)
    _add_noise(e, cfg, rng)
    return _raw(e, cfg)


def _mean_electrons(aop, dp, s0a, has_s0, cfg, layout, block_origin):
    """Return the mean photo-electrons behind the polarizers (Malus; calibration, crosstalk)."""
    phi = np.radians(layout.camera_angles_deg)
    pq = np.rint(np.stack([np.cos(2 * phi), np.sin(2 * phi)], axis=-1)).reshape(2, 2, 2)
    e = np.empty(aop.shape, np.float32)
    if cfg.calibration is not None:
        phi_map, dmap, gain = calibration_maps(cfg, layout, aop.shape, *block_origin)
        two_phi = 2.0 * phi_map.astype(np.float64)
        pmap, qmap = np.cos(two_phi).astype(np.float32), np.sin(two_phi).astype(np.float32)
        if cfg.extinction_ratio is not None:
            instr.count('sensor.extinction_ratio')  # the calibration kernel applies it per pixel
        _count('_mean_electrons_cal_kernel')
        _mean_electrons_cal_kernel(aop, dp, s0a, has_s0, pmap, qmap, dmap, gain, cfg.n0_e, e)
        if cfg.calibration['crosstalk'] > 0:
            e2 = np.empty_like(e)
            _count('_crosstalk_kernel')
            _crosstalk_kernel(e, cfg.calibration['crosstalk'], e2)
            e = e2
    elif cfg.extinction_ratio is None:
        _count('_mean_electrons_kernel')
        _mean_electrons_kernel(aop, dp, s0a, has_s0, pq, cfg.n0_e, e)
    else:
        _count('_mean_electrons_er_kernel')
        _mean_electrons_er_kernel(aop, dp, s0a, has_s0, pq, cfg.n0_e, cfg.d, e)
    return e


def _add_noise(e, cfg, rng) -> None:
    """Add the declared shot and/or read noise to ``e`` in place, keyed by one draw of ``rng``."""
    shot, read = cfg.shot_gaussian_above_e, cfg.read_sigma_e
    if shot is not None or read is not None:
        key = np.uint64(int(rng.integers(0, 2**63, dtype=np.int64)))
        if read is None:
            _count('_shot_noise_kernel')
            _shot_noise_kernel(e, key, shot)
        elif shot is None:
            _count('_read_noise_kernel')
            _read_noise_kernel(e, key, read)
        else:
            _count('_shot_read_noise_kernel')
            _shot_read_noise_kernel(e, key, shot, read)


def _raw(e, cfg):
    """Return the raw mosaic: ``e`` saturated if declared, quantised to DN if declared."""
    if cfg.bits is None:
        if cfg.saturates:
            _count('_saturate_kernel')
            _saturate_kernel(e, cfg.full_well_e)
        return e
    out = np.empty(e.shape, np.uint8 if cfg.bits <= 8 else np.uint16)
    gain = np.float32(cfg.max_dn / cfg.full_well_e)
    if cfg.saturates:
        _count('_saturate_quantize_kernel')
        _saturate_quantize_kernel(e, cfg.full_well_e, gain, cfg.max_dn, out)
    else:
        _count('_quantize_kernel')
        _quantize_kernel(e, gain, cfg.max_dn, out)
    return out


# ------------------------------------------------------------------------------------------------
# Superpixel geometry and the ideal values at superpixels
# ------------------------------------------------------------------------------------------------
@lru_cache(maxsize=16)
def superpixel_pixels(
    camera: CameraModel, x0_px: float, y0_px: float, rows: int, cols: int
) -> SelectedPixels:
    """
    Return the centres and rays of the 2 x 2 blocks of a pixel block (cached).

    Centres of the 2 x 2 blocks of a ``rows`` x ``cols`` block whose top-left pixel is (x0, y0),
    1-based: ``x = x0 + 2l + 0.5``, ``y = y0 + 2k + 0.5``; rays from the camera model. Cached.

    Parameters
    ----------
    camera : CameraModel
        Camera whose rays the centres get.
    x0_px, y0_px : float
        1-based column and row of the block's top-left pixel (eq 20 pixel coordinates).
    rows, cols : int
        Size of the block [pixels]; an odd trailing row or column is dropped.

    Returns
    -------
    SelectedPixels
        (rows // 2, cols // 2) read-only centres [px] and unit rays in the camera optical frame.

    """
    xs = float(x0_px) + 0.5 + 2.0 * np.arange(cols // 2)
    ys = float(y0_px) + 0.5 + 2.0 * np.arange(rows // 2)
    xg, yg = np.meshgrid(xs, ys)
    rays, ok = camera.rays_from_pixels(xg, yg)
    p = SelectedPixels(
        xg.shape, xg, yg, np.ascontiguousarray(rays.astype(np.float32)), ok.reshape(xg.shape)
    )
    for a in (p.x_px, p.y_px, p.rays_cam, p.has_ray):
        a.setflags(write=False)
    return p


@njit(inline='always', fastmath=_FM, cache=True)
def _ideal_stokes(a, p, sv):  # pragma: no cover - compiled
    """
    Return the camera-frame Stokes vector (S0, S1, S2) of an ideal pixel.

    Camera-frame (S0, S1, S2) of an ideal pixel: S1 = -S0 P cos 2a, S2 = S0 P sin 2a (float32).
    """
    sa, ca = sincos32(a)
    sp = sv * p
    return sv, -sp * (ca * ca - sa * sa), sp * (np.float32(2.0) * sa * ca)


@njit(inline='always', fastmath=_FM, cache=True)
def _ideal_block(aop, dop, valid, i, j, w0, w1, w2, w3):  # pragma: no cover - compiled
    """
    Return AoP, DoP, validity and mean S0 of the ideal block at (i, j).

    (aop, dop, valid, mean S0) of the mean ideal Stokes vector of the block at (i, j), S0 = w0..w3.
    """
    a0, b0, c0 = _ideal_stokes(aop[i, j], dop[i, j], w0)
    a1, b1, c1 = _ideal_stokes(aop[i, j + 1], dop[i, j + 1], w1)
    a2, b2, c2 = _ideal_stokes(aop[i + 1, j], dop[i + 1, j], w2)
    a3, b3, c3 = _ideal_stokes(aop[i + 1, j + 1], dop[i + 1, j + 1], w3)
    ok = valid[i, j] & valid[i, j + 1] & valid[i + 1, j] & valid[i + 1, j + 1]
    q = np.float32(0.25)
    t0 = q * ((a0 + a1) + (a2 + a3))
    a, d, ok = _finish(t0, q * ((b0 + b1) + (b2 + b3)), q * ((c0 + c1) + (c2 + c3)), ok)
    t0 = t0 if (t0 >= np.float32(0.0)) & (t0 < np.float32(np.inf)) else np.float32(0.0)  # NaN -> 0
    return a, d, ok, t0


@njit(parallel=True, fastmath=_FM, cache=True)
def _ideal_superpixel_kernel(
    aop, dop, valid, s0, has_s0, out_aop, out_dop, out_valid, out_s0
):  # pragma: no cover
    """
    Compute block means of the ideal Stokes vectors and their AoP/DoP.

    The AoP/DoP are those of the mean (float32); a block is valid if all four pixels are;
    ``out_s0`` is the block mean of S0 (1 without a radiance model).
    """
    H2, W2 = out_aop.shape
    one = np.float32(1.0)
    for k in prange(H2):
        i = 2 * k
        if has_s0:
            for col in range(W2):
                j = 2 * col
                out_aop[k, col], out_dop[k, col], out_valid[k, col], out_s0[k, col] = _ideal_block(
                    aop, dop, valid, i, j, s0[i, j], s0[i, j + 1], s0[i + 1, j], s0[i + 1, j + 1]
                )
        else:
            for col in range(W2):
                out_aop[k, col], out_dop[k, col], out_valid[k, col], out_s0[k, col] = _ideal_block(
                    aop, dop, valid, i, 2 * col, one, one, one, one
                )


# ------------------------------------------------------------------------------------------------
# The pipeline
# ------------------------------------------------------------------------------------------------
def _eroded_3x3(valid):
    """Return ``valid`` eroded by a 3 x 3 square (edges reflected): whole neighbourhoods valid."""
    import cv2

    return cv2.erode(
        valid.view(np.uint8),
        np.ones((3, 3), np.uint8),
        borderType=cv2.BORDER_REFLECT_101,
    ).view(np.bool_)


class SensorPipeline:
    """
    Declared sensor effects for one camera.

    Build with :meth:`from_config`; call :meth:`apply`.
    """

    def __init__(self, config: SensorConfig, camera: CameraModel):
        self.config = config
        self.camera = camera

    @staticmethod
    def from_config(sensor_cfg: dict, camera: CameraModel) -> 'SensorPipeline':
        """
        Validate a scene's ``sensor:`` mapping.

        Raises :class:`SensorError` naming the bad value.

        Parameters
        ----------
        sensor_cfg : dict or None
            The scene's ``sensor:`` mapping (see :func:`parse_sensor_config`).
        camera : CameraModel
            The camera whose pixel blocks the pipeline mosaics.

        Returns
        -------
        SensorPipeline
            The pipeline of the declared effects.

        Raises
        ------
        SensorError
            For an invalid mapping, or a camera smaller than 2 x 2 pixels.

        """
        cfg = parse_sensor_config(sensor_cfg)
        if camera.width_px < 2 or camera.height_px < 2:
            raise SensorError('a polarization mosaic needs a camera of at least 2 x 2 pixels')
        return SensorPipeline(cfg, camera)

    def params(self) -> dict:
        """
        Return the pipeline's parameters for a frame's metadata.

        Returns
        -------
        dict
            :meth:`SensorConfig.describe` of its configuration.

        """
        return self.config.describe()

    def _block_origin(self, frame):
        """1-based (x0, y0) of a contiguous, unit-stride pixel block; SensorError otherwise."""
        p = frame.pixels
        if len(p.shape) != 2 or p.shape[0] < 2 or p.shape[1] < 2:
            raise SensorError(
                f'sensor effects need a 2-D block of at least 2 x 2 pixels, got shape {p.shape}'
            )
        x, y = p.x_px, p.y_px
        if not (x[0, 1] - x[0, 0] == 1.0 and y[1, 0] - y[0, 0] == 1.0):
            raise SensorError(
                'sensor effects need contiguous pixels (pixels.mode full, or region with stride '
                '1): '
                'a mosaic has no meaning on a strided subset'
            )
        return float(x[0, 0]), float(y[0, 0])

    def apply(self, frame, rng: np.random.Generator) -> None:
        """
        Apply the mosaic, the declared noise and quantisation, and the demosaic to a frame.

        In place: the frame's AoP, DoP and validity become the measured ones, the noise-free values
        move to ``aop_ideal_rad``/``dop_ideal`` and the raw image to ``mosaic``; with the
        superpixel demosaic the frame's pixels become the 2 x 2 block centres (see the module
        docstring).

        Parameters
        ----------
        frame : Frame
            A rendered frame of a contiguous, unit-stride block of at least 2 x 2 pixels; AoP
            [rad, eq 28], DoP [0, 1], validity and optional relative radiance.
        rng : numpy.random.Generator
            Source of the frame's noise key.

        Raises
        ------
        SensorError
            When the frame's pixels are not a contiguous 2-D block of at least 2 x 2 pixels.

        """
        cfg = self.config
        x0, y0 = self._block_origin(frame)
        dy, dx = int(round(y0 - 1)) % 2, int(round(x0 - 1)) % 2
        layout = cfg.layout.shifted(dy, dx)
        frame.aop_ideal_rad = frame.aop_rad
        frame.dop_ideal = frame.dop
        frame.mosaic = simulate_mosaic(
            frame.aop_rad,
            frame.dop,
            frame.intensity,
            cfg,
            layout,
            rng,
            (int(round(y0 - 1)), int(round(x0 - 1))),
        )
        sat = cfg.saturation_level
        with instr.stage('sensor.demosaic.' + cfg.demosaic):
            aop, dop, valid = polarization_from_mosaic(
                frame.mosaic,
                layout,
                layout.pol45_toward,
                cfg.demosaic,
                saturation_level=sat,
                ifov_k=cfg.ifov_check_k,
            )
        ideal_valid = np.ascontiguousarray(frame.valid)
        if cfg.demosaic == 'bilinear':
            valid &= _eroded_3x3(ideal_valid)
        else:
            valid &= self._to_superpixels(frame, ideal_valid, x0, y0)
        invalid = ~valid
        np.copyto(aop, np.float32(0.0), where=invalid)
        np.copyto(dop, np.float32(0.0), where=invalid)
        frame.aop_rad, frame.dop, frame.valid = aop, dop, valid

    def _to_superpixels(self, frame, ideal_valid, x0, y0):
        """
        Replace a frame's pixels and ideal values by those of its 2 x 2 superpixels.

        Returns the superpixels' ideal validity (all four pixels valid, and a ray through the
        block centre); the frame's pixels, ideal AoP/DoP and radiance become the blocks'.
        """
        rows, cols = frame.aop_rad.shape
        shape = (rows // 2, cols // 2)
        ia, idp, iv, is0 = (
            np.empty(shape, np.float32),
            np.empty(shape, np.float32),
            np.empty(shape, np.bool_),
            np.empty(shape, np.float32),
        )
        has_s0 = frame.intensity is not None
        s0 = (
            np.ascontiguousarray(frame.intensity, dtype=np.float32)
            if has_s0
            else np.empty((1, 1), np.float32)
        )
        _ideal_superpixel_kernel(
            np.ascontiguousarray(frame.aop_rad, dtype=np.float32),
            np.ascontiguousarray(frame.dop, dtype=np.float32),
            ideal_valid,
            s0,
            has_s0,
            ia,
            idp,
            iv,
            is0,
        )
        frame.pixels = superpixel_pixels(self.camera, x0, y0, rows, cols)
        iv &= frame.pixels.has_ray
        frame.aop_ideal_rad, frame.dop_ideal = ia, idp
        if has_s0:
            frame.intensity = is0
        return iv
