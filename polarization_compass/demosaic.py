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
From a division-of-focal-plane (DoFP) mosaic back to Stokes, AoP and DoP.

A DoFP sensor (Sony IMX250MZR) puts a wire-grid polarizer over every pixel, in a repeating 2 x 2
pattern of 0, 45, 90 and 135 deg. ``layout`` gives that pattern for the mosaic's own top-left 2 x 2
block, row by row (IMX250MZR: ``[[90, 45], [135, 0]]``). Polarizer angles are measured from the
camera +x axis (image columns) towards ``pol45_toward``: ``"+x+y"`` (the 45 deg polarizer lies
between +x and +y, i.e. towards the lower right of the image, since +y points down the rows) or
``"+x-y"`` (towards the upper right). Which one a real camera has must be checked once with a
known linear polarizer; both are supported.

Conventions of the outputs
--------------------------
``S0, S1, S2`` are **camera-frame** Stokes parameters: angles from +x_cam towards +y_cam whatever
``pol45_toward`` is, so ``S1 = I(0) - I(90)`` and ``S2 = I(+45 cam) - I(135 cam)``; with
``pol45_toward="+x-y"`` the physical 45 deg pixel measures the camera's 135 deg, so S2 changes
sign. ``S0 = (I0 + I45 + I90 + I135) / 2`` in the input's units.

The angle of linear polarization from +x_cam is ``AoLP_x = 0.5 atan2(S2, S1)``; the paper's AoP
(eq 28: from +y_cam towards +x_cam, see ``conventions``) is ``pi/2 - AoLP_x``, computed as
``AoP = 0.5 * atan2(S2, -S1)`` (no subtraction of angles), folded to [-pi/2, pi/2).
``DoP = sqrt(S1^2 + S2^2) / S0`` clipped to [0, 1].

Validity (never NaN out): a pixel is invalid, with aop = dop = 0 and S0 = S1 = S2 = 0, when any raw
sample its estimate uses is saturated (``>= saturation_level``; default the dtype's maximum for
integer input, none for float input) or not finite (float input), when ``S0 <= 0`` (DoP undefined:
all-zero input), or when ``S1 = S2 = 0`` (AoP undefined: unpolarized, or a uniformly saturated
image).

Methods
-------
``superpixel``  each non-overlapping 2 x 2 block gives one output (half resolution, no
                interpolation; a trailing odd row/column is dropped). Output pixel (k, l) sits at
                the centre of input pixels (2k..2k+1, 2l..2l+1).
``bilinear``    full resolution: each channel is bilinearly interpolated on its 2-pixel lattice,
                i.e. at a pixel the own channel is taken as is, the horizontal/vertical neighbours'
                channels as the mean of two samples and the diagonal channel as the mean of four
                (kernel ``[.5 1 .5] x [.5 1 .5]``). Image borders mirror without repeating the edge
                (OpenCV's BORDER_REFLECT_101), which keeps the 2 x 2 phase. A pixel's estimate uses
                its 3 x 3 neighbourhood. Needs at least 2 rows and 2 columns.

IFOV check (``ifov_k``)
-----------------------
A DoFP superpixel measures the total intensity twice: ``I0 + I90`` and ``I45 + I135`` (for the
bilinear method: of the interpolated channels at the pixel). Their difference, the redundancy
``r = (I0 + I90) - (I45 + I135)`` (weights ``cos 4 phi``), is zero for an ideal sensor on a
uniform patch whatever the polarization. It is not zero where the four pixels see different
radiances -- the instantaneous-field-of-view (IFOV) error of a microgrid polarimeter at an edge
(Ratliff, LaCasse & Tyo 2009, Opt. Express 17:9112), such as a cloud's -- or
where a pixel is defective. Under shot noise ``var r ~ gain x S0``, so ``r / sqrt(S0)`` has one
spread over the frame; :func:`redundancy_noise` estimates it from the frame itself (median and
MAD over at most 64 x 64 outputs; unknown gain is fine), with the quantisation floor of integer
samples. With ``ifov_k > 0`` an output whose ``|r - mu S0|`` exceeds ``ifov_k`` of those sigmas is
invalid (false-alarm rate ``erfc(k / sqrt 2)`` on a clear sky: 1e-3 at 3.29, 6e-5 at 4, the front
ends' default :data:`IFOV_K_DEFAULT`); 0 is off (the default of the functions here).

What it cannot see: with 0 and 90 deg on one diagonal of the block (the IMX250MZR), ``r`` is the
block's mixed second difference ``d^2 I / dx dy``. A linear brightness gradient leaks into S1 and
S2 (the superpixel error of a coarse camera under the sky's own gradient) with ``r = 0``, and an
edge along the rows or columns shows in ``r`` only through its polarized part (``DoP x`` the
step). Sharp, curved or diagonal edges are what it catches.

Implementation: fused numba kernels (parallel over rows) from the raw samples straight to AoP, DoP
and validity: one pass, no full-frame temporaries; the interior loop is branch-free and LLVM
vectorises it (8-wide AVX2, checked in the assembly), using the float32 polynomial
``axial_atan2_f32`` of ``fastmath`` (numpy's float32 ``arctan2`` alone costs ~75 ms single-core on
a 5 Mpixel frame here). Measured single-core (``tools/bench_sensor.py``, 2448 x 2048 uint16):
bilinear ~21-23 ms, superpixel ~6-10 ms. The OpenCV route for the bilinear case (three ``filter2D``
passes on sign-modulated copies, then :func:`aop_dop_from_stokes`) took ~28 ms and three 20 MB
Stokes temporaries, and has no saturation check, so it is not used; OpenCV serves the 3 x 3 erosion
of validity masks in :mod:`sensor` and the independent per-channel reference in the tests.

"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math

import numpy as np

from .demosaic_kernels import (
    _bilinear_kernel,
    _bilinear_stokes_kernel,
    _redundancy_samples,
    _stokes_to_aop_kernel,
    _superpixel_kernel,
    _superpixel_stokes_kernel,
)
from .mosaic import (
    _bilinear_weights,
    _prepare,
    IMX250MZR_LAYOUT,
    IMX250MZR_POL45,
    MosaicLayout,
    parse_layout,
    SensorError,
)

__all__ = [
    'stokes_from_mosaic',
    'aop_dop_from_stokes',
    'polarization_from_mosaic',
    'DEMOSAIC_METHODS',
    'IFOV_K_DEFAULT',
    'RedundancyNoise',
    'redundancy_noise',
    'check_ifov_k',
]

#: Default threshold [sigmas] of the IFOV check in the front ends (module docstring); measured.
IFOV_K_DEFAULT = 4.0
DEMOSAIC_METHODS = ('superpixel', 'bilinear')


# ------------------------------------------------------------------------------------------------
# Public functions
# ------------------------------------------------------------------------------------------------
def check_ifov_k(k) -> float:
    """
    Validate the IFOV check's threshold.

    Parameters
    ----------
    k : float
        Threshold [noise sigmas] of the redundancy check (module docstring, "IFOV check"); 0 = off.

    Returns
    -------
    float
        ``k`` as a float.

    Raises
    ------
    SensorError
        ``k`` is not a number (or is a bool), is NaN or inf, negative, or in (0, 1) (a threshold
        inside the noise would reject most of a clear sky).

    """
    if isinstance(k, bool) or not isinstance(k, (int, float, np.integer, np.floating)):
        raise SensorError(f'ifov_check_k must be a number of sigmas (0 = off), got {k!r}')
    k = float(k)
    if not math.isfinite(k) or k < 0.0 or 0.0 < k < 1.0:
        raise SensorError(
            f'ifov_check_k must be 0 (off) or a finite number of sigmas >= 1, got {k!r}'
        )
    return k


@dataclass(frozen=True)
class RedundancyNoise:
    """
    Noise model of a frame's DoFP redundancy ``r = (I0 + I90) - (I45 + I135)``.

    ``r ~ mu S0 + N(0, sigma^2 S0 + quant)``: ``mu`` a channel-gain offset (dimensionless),
    ``sigma`` [sqrt(input units)] the shot-noise-like spread per sqrt(S0), ``quant``
    [input units^2] the quantisation floor, ``count`` the outputs it was estimated from.
    """

    mu: float
    sigma: float
    quant: float
    count: int


#: outputs per axis sampled by :func:`redundancy_noise` (at most 64 x 64 = 4096)
_NOISE_SAMPLES = 64
#: relative float32 rounding floor of r / S0
_REL_FLOOR = 1e-6


def redundancy_noise(
    mosaic,
    layout=IMX250MZR_LAYOUT,
    pol45_toward: str = IMX250MZR_POL45,
    method: str = 'superpixel',
    saturation_level=None,
) -> RedundancyNoise:
    """
    Estimate the noise of the DoFP redundancy of a frame from the frame itself.

    Every 2 x 2 superpixel (or bilinear 3 x 3 neighbourhood) measures the total intensity twice,
    ``I0 + I90`` and ``I45 + I135``; their difference ``r`` is zero for an ideal sensor on a
    uniform patch, Gaussian with variance ~ gain x S0 under shot noise (so ``r / sqrt(S0)`` has
    one spread over the frame whatever the gain), and large where the channels see different
    radiances (the IFOV error at an edge, Ratliff et al. 2009) or a pixel is defective. Estimated
    robustly on a regular sample of at most 64 x 64 of the method's outputs (usable ones, S0 at
    least a tenth of the sample's 90th percentile): ``mu`` the median of ``r / S0``, ``sigma``
    1.4826 x the median absolute deviation of ``(r - mu S0) / sqrt(S0)`` (a Gaussian's sigma;
    robust to the edges, which are a small fraction of a sky).

    Parameters
    ----------
    mosaic : numpy.ndarray
        2-D raw image [counts or any intensity unit].
    layout, pol45_toward, method, saturation_level
        As :func:`polarization_from_mosaic`.

    Returns
    -------
    RedundancyNoise
        ``mu``, ``sigma`` [sqrt(input units)], ``quant`` (the variance of ``r`` from rounding
        integer samples, ``sum(weights^2) / 12``; 0 for float input) and ``count``; mu = sigma = 0
        when fewer than 16 outputs are usable.

    Raises
    ------
    SensorError
        As :func:`stokes_from_mosaic`.

    References
    ----------
    .. [1] B. M. Ratliff, C. F. LaCasse and J. S. Tyo, "Interpolation strategies for reducing
       IFOV artifacts in microgrid polarimeter imagery", Opt. Express 17, 9112 (2009).

    """
    lay = parse_layout(layout, pol45_toward)
    if method not in DEMOSAIC_METHODS:
        raise SensorError(f'demosaic method must be one of {DEMOSAIC_METHODS}, got {method!r}')
    m, sat = _prepare(mosaic, saturation_level, read_once=True)  # a sample: no float32 copy
    if m.shape[0] < 2 or m.shape[1] < 2:
        raise SensorError(f'a mosaic needs at least 2 x 2 pixels, got {m.shape[0]} x {m.shape[1]}')
    return _noise_of(m, sat, lay, method, np.asarray(mosaic).dtype.kind in 'ui')


@lru_cache(maxsize=16)
def _sample_weights(lay: MosaicLayout):
    """(superpixel, bilinear) Stokes weights of a layout, cached (read-only)."""
    w, rw = lay.stokes_weights(), _bilinear_weights(lay)
    w.setflags(write=False)
    rw.setflags(write=False)
    return w, rw


def _noise_of(m, sat, lay, method, integer) -> RedundancyNoise:
    """Return :func:`redundancy_noise` of a prepared mosaic (``integer``: the raw samples were)."""
    H, W = m.shape
    superpixel = method == 'superpixel'
    if superpixel:
        lo_r, hi_r, lo_c, hi_c = 0, H // 2 - 1, 0, W // 2 - 1
    else:  # interior rows (the sampler reads rows i - 1 and i + 1 as they are)
        lo_r, hi_r, lo_c, hi_c = 1, H - 2, 0, W - 1
    quant = (4.0 if superpixel else 2.25) / 12.0 if integer else 0.0
    if hi_r < lo_r:  # a 2-row mosaic has no interior row
        return RedundancyNoise(0.0, 0.0, quant, 0)
    rows = np.unique(np.linspace(lo_r, hi_r, _NOISE_SAMPLES).round().astype(np.int64))
    cols = np.unique(np.linspace(lo_c, hi_c, _NOISE_SAMPLES).round().astype(np.int64))
    s0 = np.empty((rows.size, cols.size), np.float32)
    r = np.empty_like(s0)
    ok = np.empty(s0.shape, np.bool_)
    _redundancy_samples(m, *_sample_weights(lay), sat, superpixel, rows, cols, s0, r, ok)
    s0, r = s0[ok].astype(np.float64), r[ok].astype(np.float64)
    if s0.size >= 16:
        p90 = np.partition(s0, int(0.9 * (s0.size - 1)))[int(0.9 * (s0.size - 1))]
        keep = s0 >= 0.1 * p90
        s0, r = s0[keep], r[keep]
    if s0.size < 16:
        return RedundancyNoise(0.0, 0.0, quant, int(s0.size))
    mu = float(np.median(r / s0))
    z = (r - mu * s0) / np.sqrt(s0)
    sigma = 1.4826 * float(np.median(np.abs(z - np.median(z))))
    return RedundancyNoise(mu, sigma, quant, int(s0.size))


def _limits(k: float, noise) -> np.ndarray:
    """Return the kernels' ``lim = (A, B, C, mu)`` for threshold ``k`` sigmas (all inf: off)."""
    if k == 0.0:
        return np.array([np.inf, np.inf, np.inf, 0.0], np.float32)
    k2 = k * k
    return np.array(
        [k2 * noise.sigma**2, k2 * noise.quant, k2 * _REL_FLOOR**2, noise.mu], np.float32
    )


def _run(
    mosaic, layout, pol45_toward, method, saturation_level, stokes_out, ifov_k=0.0, noise=None
):
    lay = parse_layout(layout, pol45_toward)
    if method not in DEMOSAIC_METHODS:
        raise SensorError(f'demosaic method must be one of {DEMOSAIC_METHODS}, got {method!r}')
    k = check_ifov_k(ifov_k)
    m, sat = _prepare(mosaic, saturation_level, read_once=method == 'superpixel')
    H, W = m.shape
    if H < 2 or W < 2:
        raise SensorError(f'a mosaic needs at least 2 x 2 pixels, got {H} x {W}')
    if k > 0.0 and noise is None:
        noise = _noise_of(m, sat, lay, method, np.asarray(mosaic).dtype.kind in 'ui')
    lim = _limits(k, noise)
    shape = (H // 2, W // 2) if method == 'superpixel' else (H, W)
    out = (
        tuple(np.empty(shape, np.float32) for _ in range(2)) + (np.empty(shape, np.bool_),)
        if not stokes_out
        else tuple(np.empty(shape, np.float32) for _ in range(3))
    )
    if method == 'superpixel':
        (_superpixel_stokes_kernel if stokes_out else _superpixel_kernel)(
            m, lay.stokes_weights(), sat, lim, *out
        )
    else:
        (_bilinear_stokes_kernel if stokes_out else _bilinear_kernel)(
            m, _bilinear_weights(lay), sat, lim, *out
        )
    return out


def stokes_from_mosaic(
    mosaic,
    layout=IMX250MZR_LAYOUT,
    pol45_toward: str = IMX250MZR_POL45,
    method: str = 'superpixel',
    saturation_level=None,
    ifov_k: float = 0.0,
    ifov_noise: 'RedundancyNoise | None' = None,
):
    """
    Compute the camera-frame Stokes images ``(S0, S1, S2)`` of a raw DoFP image.

    ``S1 = I(0) - I(90)``, ``S2 = I(45) - I(135)`` with angles from +x_cam towards +y_cam and
    ``S0 = (I0 + I45 + I90 + I135) / 2``. Invalid pixels (a saturated or non-finite sample,
    ``S0 <= 0`` or ``S1 = S2 = 0``) hold S0 = S1 = S2 = 0, never NaN. See the module docstring.

    Parameters
    ----------
    mosaic : numpy.ndarray
        2-D raw image, unsigned/signed integer, float32 or float64 [counts or any intensity unit].
    layout : array_like of shape (2, 2) or MosaicLayout, default ((90, 45), (135, 0))
        Polarizer angles [deg] of the mosaic's top-left 2 x 2 block.
    pol45_toward : {"+x-y", "+x+y"}, default "+x-y"
        Image direction of the 45 deg polarizer.
    method : {"superpixel", "bilinear"}, default "superpixel"
        Output of shape ``(H // 2, W // 2)`` (one per 2 x 2 block) or ``(H, W)`` (bilinear
        interpolation of each channel).
    saturation_level : float, optional
        Samples ``>=`` this are saturated [input units]; default the dtype's maximum for integer
        input, none for float input.
    ifov_k : float, default 0
        IFOV check (module docstring): an output whose redundancy ``(I0 + I90) - (I45 + I135)``
        is more than ``ifov_k`` noise sigmas from its expectation is invalid; 0 = off.
    ifov_noise : RedundancyNoise, optional
        The redundancy's noise model; default :func:`redundancy_noise` of this mosaic (pass the
        full frame's when demosaicing a part of it, so that every part is judged alike).

    Returns
    -------
    s0, s1, s2 : numpy.ndarray
        float32 Stokes images in the input's units.

    Raises
    ------
    SensorError
        A bad layout, ``pol45_toward`` or ``method``, a mosaic that is not 2-D, has an
        unsupported dtype or fewer than 2 x 2 pixels, a NaN ``saturation_level`` or a bad
        ``ifov_k`` (:func:`check_ifov_k`).

    """
    return _run(mosaic, layout, pol45_toward, method, saturation_level, True, ifov_k, ifov_noise)


def aop_dop_from_stokes(s0, s1, s2):
    """
    Compute the AoP, DoP and validity from camera-frame Stokes arrays of equal shape.

    ``AoP = 0.5 atan2(S2, -S1)`` folded to [-pi/2, pi/2) (the paper's AoP, from +y_cam towards
    +x_cam) and ``DoP = hypot(S1, S2) / S0`` clipped to [0, 1].

    Parameters
    ----------
    s0, s1, s2 : array_like
        Camera-frame Stokes parameters (angles from +x_cam towards +y_cam), any one intensity
        unit, equal shapes.

    Returns
    -------
    aop_rad : numpy.ndarray
        float32 angle of polarization [rad] in [-pi/2, pi/2); 0 where invalid.
    dop : numpy.ndarray
        float32 degree of linear polarization in [0, 1]; 0 where invalid.
    valid : numpy.ndarray
        bool: False where S0 <= 0, S1 = S2 = 0 or an input is NaN/inf.

    Raises
    ------
    SensorError
        The three arrays do not have the same shape.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28 (the AoP's
       reference direction).

    """
    a0 = np.ascontiguousarray(s0, dtype=np.float32)
    a1 = np.ascontiguousarray(s1, dtype=np.float32)
    a2 = np.ascontiguousarray(s2, dtype=np.float32)
    if not (a0.shape == a1.shape == a2.shape):
        raise SensorError(
            f'S0, S1, S2 must have the same shape, got {a0.shape}, {a1.shape}, {a2.shape}'
        )
    aop = np.empty(a0.shape, np.float32)
    dop = np.empty(a0.shape, np.float32)
    valid = np.empty(a0.shape, np.bool_)
    # flat views (the kernel reads them flat): one argument type for any image shape
    _stokes_to_aop_kernel(*(a.reshape(-1) for a in (a0, a1, a2, aop, dop, valid)))
    return aop, dop, valid


def polarization_from_mosaic(
    mosaic,
    layout=IMX250MZR_LAYOUT,
    pol45_toward: str = IMX250MZR_POL45,
    method: str = 'superpixel',
    saturation_level=None,
    ifov_k: float = 0.0,
    ifov_noise: 'RedundancyNoise | None' = None,
):
    """
    Compute ``(aop_rad, dop, valid)`` straight from a raw DoFP image (no Stokes images).

    The fused fast path: same conventions, validity and numbers as :func:`stokes_from_mosaic`
    followed by :func:`aop_dop_from_stokes`.

    Parameters
    ----------
    mosaic : numpy.ndarray
        2-D raw image, unsigned/signed integer, float32 or float64 [counts or any intensity unit].
    layout : array_like of shape (2, 2) or MosaicLayout, default ((90, 45), (135, 0))
        Polarizer angles [deg] of the mosaic's top-left 2 x 2 block.
    pol45_toward : {"+x-y", "+x+y"}, default "+x-y"
        Image direction of the 45 deg polarizer.
    method : {"superpixel", "bilinear"}, default "superpixel"
        Half-resolution blocks or full-resolution bilinear interpolation.
    saturation_level : float, optional
        Samples ``>=`` this are saturated [input units]; default the dtype's maximum for integer
        input, none for float input.
    ifov_k : float, default 0
        IFOV check (module docstring): an output whose redundancy ``(I0 + I90) - (I45 + I135)``
        is more than ``ifov_k`` noise sigmas from its expectation is invalid; 0 = off.
    ifov_noise : RedundancyNoise, optional
        The redundancy's noise model; default :func:`redundancy_noise` of this mosaic (pass the
        full frame's when demosaicing a part of it, so that every part is judged alike).

    Returns
    -------
    aop_rad : numpy.ndarray
        float32 AoP [rad] in [-pi/2, pi/2), from +y_cam towards +x_cam (eq 28); 0 where invalid.
    dop : numpy.ndarray
        float32 DoP in [0, 1]; 0 where invalid.
    valid : numpy.ndarray
        bool validity (see :func:`stokes_from_mosaic`).

    Raises
    ------
    SensorError
        As :func:`stokes_from_mosaic`.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28.

    """
    return _run(mosaic, layout, pol45_toward, method, saturation_level, False, ifov_k, ifov_noise)
