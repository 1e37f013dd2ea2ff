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

from numba import njit, prange
import numpy as np

from .errors import CompassError
from .fastmath import axial_atan2_f32

__all__ = [
    'SensorError',
    'MosaicLayout',
    'IMX250MZR_LAYOUT',
    'IMX250MZR_POL45',
    'parse_layout',
    'layout_from_mapping',
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
#: Sony IMX250MZR, top-left 2 x 2 block, row by row.
IMX250MZR_LAYOUT = ((90, 45), (135, 0))
DEMOSAIC_METHODS = ('superpixel', 'bilinear')
_POL45 = ('+x+y', '+x-y')
#: The image direction of the IMX250MZR's 45 deg polarizer as real cameras deliver the image (no
#: ReverseX/ReverseY): towards +x-y, up and to the right on the displayed image (Sony's drawing,
#: whose angles run counter-clockwise with the image's y axis up). Measured on real sky frames (two
#: independent sources, ``test/data/real-sky``; ``polarization-compass check-polarizer``). A
#: readout flipped in one axis (ReverseX or ReverseY) mirrors the image and turns this into +x+y
#: (and moves the 2 x 2 phase); flipped in both it stays +x-y (a 180 deg rotation keeps polarizer
#: angles).
IMX250MZR_POL45 = '+x-y'

# fastmath without 'nnan'/'ninf': the kernels rely on NaN comparisons being false.
_FM = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}
_PI32 = np.float32(math.pi)
_HALF_PI32 = np.float32(math.pi / 2)


class SensorError(CompassError):
    """Bad sensor configuration or unusable raw image (the message says which value and why)."""


@dataclass(frozen=True)
class MosaicLayout:
    """
    Hold a validated 2 x 2 polarizer layout of a DoFP mosaic.

    Parameters
    ----------
    angles_deg : tuple of tuple of int, default ((90, 45), (135, 0))
        ``angles_deg[r][c]`` is the polarizer angle [deg] at row r, column c of the mosaic's
        top-left 2 x 2 block (0, 45, 90 and 135 once each; IMX250MZR by default).
    pol45_toward : {"+x-y", "+x+y"}, default "+x-y"
        Image direction of the 45 deg polarizer from +x_cam (columns): towards +y_cam (down the
        rows) or -y_cam (up); see the module docstring.

    """

    angles_deg: tuple = IMX250MZR_LAYOUT
    pol45_toward: str = IMX250MZR_POL45

    @property
    def camera_angles_deg(self) -> np.ndarray:
        """
        Return the (2, 2) polarizer angles from +x_cam towards +y_cam (deg).

        Each is the physical angle, or minus it, as ``pol45_toward`` says.
        """
        a = np.asarray(self.angles_deg, dtype=float)
        return a if self.pol45_toward == '+x+y' else -a

    def shifted(self, dy: int, dx: int) -> 'MosaicLayout':
        """
        Return the layout seen by a block whose top-left pixel is (dy, dx) into this pattern.

        Parameters
        ----------
        dy, dx : int
            Offset [px] of the block's top-left pixel from the pattern's, along rows and columns
            (only the parities matter).

        Returns
        -------
        MosaicLayout
            The same polarizers, rolled by (dy, dx), with the same ``pol45_toward``.

        """
        a = self.angles_deg
        return MosaicLayout(
            tuple(tuple(a[(r + dy) % 2][(c + dx) % 2] for c in range(2)) for r in range(2)),
            self.pol45_toward,
        )

    def stokes_weights(self) -> np.ndarray:
        """
        Return the Stokes weights of the four polarizers of one block.

        ``S1 = sum(w[..., 0] * I)`` and ``S2 = sum(w[..., 1] * I)`` over one block of four.

        Returns
        -------
        numpy.ndarray
            float32 (2, 2, 2): ``w[r, c] = (cos 2phi, sin 2phi)`` of the polarizer at (r, c), phi
            its camera-frame angle (from +x_cam towards +y_cam); exactly 0 or +-1.

        """
        phi = np.radians(self.camera_angles_deg)
        w = np.stack([np.cos(2 * phi), np.sin(2 * phi)], axis=-1)
        return np.rint(w).astype(np.float32)  # exactly 0 or +-1 for 0/45/90/135

    def describe(self) -> dict:
        """
        Return the layout as plain data for logs, JSON and diagnostics.

        Returns
        -------
        dict
            ``{"layout": [[deg, deg], [deg, deg]], "pol45_toward": "+x-y" | "+x+y"}``.

        """
        return {'layout': [list(r) for r in self.angles_deg], 'pol45_toward': self.pol45_toward}


def parse_layout(layout=IMX250MZR_LAYOUT, pol45_toward: str = IMX250MZR_POL45) -> MosaicLayout:
    """
    Validate a 2 x 2 layout holding 0, 45, 90, 135 once each, and the 45 deg direction.

    Parameters
    ----------
    layout : array_like of shape (2, 2) or MosaicLayout, default ((90, 45), (135, 0))
        Polarizer angles [deg] of the mosaic's top-left block, row by row; a
        :class:`MosaicLayout` is returned as it is.
    pol45_toward : {"+x-y", "+x+y"}, default "+x-y"
        Image direction of the 45 deg polarizer (see the module docstring).

    Returns
    -------
    MosaicLayout
        The validated layout, angles as int.

    Raises
    ------
    SensorError
        ``pol45_toward`` is neither value, the layout is not 2 x 2, holds an angle other than
        0/45/90/135 (or a bool), or does not hold each of them once.

    """
    if isinstance(layout, MosaicLayout):
        return layout
    if pol45_toward not in _POL45:
        raise SensorError(f"pol45_toward must be '+x+y' or '+x-y', got {pol45_toward!r}")
    try:
        rows = [list(r) for r in layout]
        ok_shape = len(rows) == 2 and all(len(r) == 2 for r in rows)
    except TypeError:
        ok_shape = False
    if not ok_shape:
        raise SensorError(
            f'mosaic layout must be 2 x 2, e.g. [[90, 45], [135, 0]], got {layout!r}'
        )
    vals = []
    for v in (x for r in rows for x in r):
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float, np.integer, np.floating))
            or v not in (0, 45, 90, 135)
        ):
            raise SensorError(f'mosaic layout angles must be 0, 45, 90 or 135 deg, got {v!r}')
        vals.append(int(v))
    if sorted(vals) != [0, 45, 90, 135]:
        raise SensorError(f'mosaic layout must hold 0, 45, 90 and 135 once each, got {rows}')
    return MosaicLayout(((vals[0], vals[1]), (vals[2], vals[3])), pol45_toward)


def layout_from_mapping(mosaic) -> MosaicLayout:
    """
    Return the layout of a ``mosaic`` mapping such as a scene's ``sensor.mosaic``.

    Also the form of a topic map's ``mosaic:`` entry.

    Parameters
    ----------
    mosaic : mapping or None
        ``layout`` (2 x 2 angles [deg]) and ``pol45_toward``, each defaulting to the IMX250MZR's
        when missing (None means both defaults).

    Returns
    -------
    MosaicLayout
        The validated layout (see :func:`parse_layout`, whose :class:`SensorError` propagates).

    """
    mos = mosaic or {}
    return parse_layout(
        mos.get('layout', IMX250MZR_LAYOUT), mos.get('pol45_toward', IMX250MZR_POL45)
    )


# ------------------------------------------------------------------------------------------------
# Kernels
# ------------------------------------------------------------------------------------------------
@njit(inline='always', fastmath=_FM, cache=True)
def _finish(s0, s1, s2, ok):  # pragma: no cover - compiled
    """(aop, dop, valid) from camera-frame Stokes; branch-free so that row loops vectorise."""
    c = -s1
    ax = axial_atan2_f32(s2, c)  # atan2(S2, -S1) folded to [-pi/2, pi/2)
    full = ax + (_PI32 if ax <= np.float32(0.0) else -_PI32)
    # unfold to (-pi, pi]; on the c = 0 line the fold gives -pi/2 for both signs of S2, so S2 > 0
    # (true angle +pi/2, AoP +45 deg) unfolds too
    unfold = (c < np.float32(0.0)) | ((c == np.float32(0.0)) & (s2 > np.float32(0.0)))
    ax = full if unfold else ax
    a = np.float32(0.5) * ax
    a = -_HALF_PI32 if a >= _HALF_PI32 else a
    lin = math.sqrt(s1 * s1 + s2 * s2)
    ok = ok & (s0 > np.float32(0.0)) & (lin > np.float32(0.0))
    d = min(lin / max(s0, np.float32(1e-30)), np.float32(1.0))
    return (a if ok else np.float32(0.0)), (d if ok else np.float32(0.0)), ok


@njit(inline='always', fastmath=_FM, cache=True)
def _good(v, sat):  # pragma: no cover - compiled
    """Finite (NaN/inf comparisons are false) and below saturation."""
    return (v < sat) & (v > np.float32(-np.inf))


@njit(inline='always', fastmath=_FM, cache=True)
def _u(w, r, c):  # pragma: no cover - compiled
    """Redundancy weight cos(4 phi) (+1 for 0/90, -1 for 45/135) from the Stokes weights."""
    return w[r, c, 0] * w[r, c, 0] - w[r, c, 1] * w[r, c, 1]


@njit(inline='always', fastmath=_FM, cache=True)
def _consistent(ok, s0, r, lim):  # pragma: no cover - compiled
    """
    Apply the redundancy check ``(r - mu S0)^2 <= A S0 + B + C S0^2``, ``lim = (A, B, C, mu)``.

    ``lim = (inf, inf, inf, 0)`` switches it off (a NaN ``r`` comes only from a sample already
    invalid).
    """
    e = r - lim[3] * s0
    return ok & (e * e <= (lim[0] * s0 + lim[1]) + lim[2] * (s0 * s0))


@njit(inline='always', fastmath=_FM, cache=True)
def _superpixel_pixel(m, i, j, w, sat):  # pragma: no cover - compiled
    """
    Compute the Stokes vector of the 2 x 2 block whose top-left sample is (i, j).

    Stokes of the 2 x 2 block whose top-left sample is (i, j); ``w`` (2, 2, 2) Stokes weights.
    """
    a = np.float32(m[i, j])
    b = np.float32(m[i, j + 1])
    c = np.float32(m[i + 1, j])
    d = np.float32(m[i + 1, j + 1])
    ok = _good(a, sat) & _good(b, sat) & _good(c, sat) & _good(d, sat)
    s0 = np.float32(0.5) * ((a + b) + (c + d))
    s1 = (w[0, 0, 0] * a + w[0, 1, 0] * b) + (w[1, 0, 0] * c + w[1, 1, 0] * d)
    s2 = (w[0, 0, 1] * a + w[0, 1, 1] * b) + (w[1, 0, 1] * c + w[1, 1, 1] * d)
    # redundancy (I0 + I90) - (I45 + I135): weight cos(4 phi) = cos^2(2 phi) - sin^2(2 phi)
    r = (_u(w, 0, 0) * a + _u(w, 0, 1) * b) + (_u(w, 1, 0) * c + _u(w, 1, 1) * d)
    return s0, s1, s2, ok, r


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _superpixel_kernel(m, w, sat, lim, aop, dop, valid):  # pragma: no cover - compiled
    """One (aop, dop, valid) per 2 x 2 block."""
    H2, W2 = aop.shape
    for k in prange(H2):
        for col in range(W2):
            s0, s1, s2, ok, r = _superpixel_pixel(m, 2 * k, 2 * col, w, sat)
            ok = _consistent(ok, s0, r, lim)
            aop[k, col], dop[k, col], valid[k, col] = _finish(s0, s1, s2, ok)


@njit(inline='always', fastmath=_FM, cache=True)
def _stokes_or_zero(s0, s1, s2, ok):  # pragma: no cover - compiled
    """
    Return the Stokes output (S0, S1, S2) of one pixel, or zeros when unusable.

    The Stokes output of one pixel: (S0, S1, S2) when its samples are usable (``ok``), S0 > 0 and
    S1, S2 not both 0; else zeros. Branch-free (selects), so that row loops vectorise.
    """
    z = np.float32(0.0)
    ok = ok & (s0 > z) & ((s1 != z) | (s2 != z))
    return (s0 if ok else z), (s1 if ok else z), (s2 if ok else z)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _superpixel_stokes_kernel(m, w, sat, lim, s0o, s1o, s2o):  # pragma: no cover - compiled
    """One Stokes vector per 2 x 2 block; zeros where invalid."""
    H2, W2 = s0o.shape
    for k in prange(H2):
        for col in range(W2):
            s0, s1, s2, ok, r = _superpixel_pixel(m, 2 * k, 2 * col, w, sat)
            ok = _consistent(ok, s0, r, lim)
            s0o[k, col], s1o[k, col], s2o[k, col] = _stokes_or_zero(s0, s1, s2, ok)


@njit(inline='always', fastmath=_FM, cache=True)
def _bilinear_pixel(m, rows, cols, w, v, sat):  # pragma: no cover - compiled
    """
    Return the Stokes vector at (i, j) from its 3 x 3 neighbourhood (compiled, inlined).

    ``rows`` = (i - 1, i, i + 1) and ``cols`` = (j - 1, j, j + 1), mirrored at the edges; ``w``
    and ``v`` (4-tuples): the S1 and S2 weights of the channels at the centre, the horizontal
    pair, the vertical pair and the diagonal four.
    """
    im, i, ip = rows
    jm, j, jp = cols
    w0, w1, w2, w3 = w
    v0, v1, v2, v3 = v
    vc = np.float32(m[i, j])
    a = np.float32(m[i, jm])
    b = np.float32(m[i, jp])
    c = np.float32(m[im, j])
    d = np.float32(m[ip, j])
    e = np.float32(m[im, jm])
    f = np.float32(m[im, jp])
    g = np.float32(m[ip, jm])
    h = np.float32(m[ip, jp])
    ih = np.float32(0.5) * (a + b)
    iv = np.float32(0.5) * (c + d)
    idg = np.float32(0.25) * ((e + f) + (g + h))
    s0 = np.float32(0.5) * ((vc + ih) + (iv + idg))
    s1 = (w0 * vc + w1 * ih) + (w2 * iv + w3 * idg)
    s2 = (v0 * vc + v1 * ih) + (v2 * iv + v3 * idg)
    # redundancy (I0 + I90) - (I45 + I135) of the interpolated channels, weights cos(4 phi)
    r = ((w0 * w0 - v0 * v0) * vc + (w1 * w1 - v1 * v1) * ih) + (
        (w2 * w2 - v2 * v2) * iv + (w3 * w3 - v3 * v3) * idg
    )
    ok = (
        _good(vc, sat)
        & _good(a, sat)
        & _good(b, sat)
        & _good(c, sat)
        & _good(d, sat)
        & _good(e, sat)
        & _good(f, sat)
        & _good(g, sat)
        & _good(h, sat)
    )
    return s0, s1, s2, ok, r


@njit(inline='always', fastmath=_FM, cache=True)
def _bilinear_at(m, i, im, ip, j, W, r, rw, sat):  # pragma: no cover - compiled
    """Stokes at an edge column j (0 or W - 1), mirrored like BORDER_REFLECT_101."""
    jm = j - 1 if j > 0 else 1
    jp = j + 1 if j < W - 1 else W - 2
    q = j & 1
    w = (rw[r, q, 0], rw[r, q, 1], rw[r, q, 2], rw[r, q, 3])
    v = (rw[r, q, 4], rw[r, q, 5], rw[r, q, 6], rw[r, q, 7])
    return _bilinear_pixel(m, (im, i, ip), (jm, j, jp), w, v, sat)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _bilinear_kernel(m, rw, sat, lim, aop, dop, valid):  # pragma: no cover - compiled
    """
    Full-resolution bilinear demosaic to (aop, dop, valid).

    ``rw`` (2 row parities, 2 column
    parities, 8): S1 and S2 weights of the (centre, horizontal, vertical, diagonal) channels.
    The interior loop is branch-free (selects only) so that LLVM vectorises it; keep it that way.
    """
    H, W = m.shape
    for i in prange(H):
        im = i - 1 if i > 0 else 1  # BORDER_REFLECT_101 keeps the 2 x 2 phase
        ip = i + 1 if i < H - 1 else H - 2
        r = i & 1
        e0, e1, e2, e3 = rw[r, 0, 0], rw[r, 0, 1], rw[r, 0, 2], rw[r, 0, 3]
        f0, f1, f2, f3 = rw[r, 0, 4], rw[r, 0, 5], rw[r, 0, 6], rw[r, 0, 7]
        o0, o1, o2, o3 = rw[r, 1, 0], rw[r, 1, 1], rw[r, 1, 2], rw[r, 1, 3]
        p0, p1, p2, p3 = rw[r, 1, 4], rw[r, 1, 5], rw[r, 1, 6], rw[r, 1, 7]
        for j in range(1, W - 1):
            odd = (j & 1) == 1
            w = (o0 if odd else e0, o1 if odd else e1, o2 if odd else e2, o3 if odd else e3)
            v = (p0 if odd else f0, p1 if odd else f1, p2 if odd else f2, p3 if odd else f3)
            s0, s1, s2, ok, rd = _bilinear_pixel(m, (im, i, ip), (j - 1, j, j + 1), w, v, sat)
            ok = _consistent(ok, s0, rd, lim)
            aop[i, j], dop[i, j], valid[i, j] = _finish(s0, s1, s2, ok)
        for j in (0, W - 1):
            s0, s1, s2, ok, rd = _bilinear_at(m, i, im, ip, j, W, r, rw, sat)
            ok = _consistent(ok, s0, rd, lim)
            aop[i, j], dop[i, j], valid[i, j] = _finish(s0, s1, s2, ok)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _bilinear_stokes_kernel(m, rw, sat, lim, s0o, s1o, s2o):  # pragma: no cover - compiled
    """Full-resolution bilinear Stokes images; zeros where invalid."""
    H, W = m.shape
    for i in prange(H):
        im = i - 1 if i > 0 else 1
        ip = i + 1 if i < H - 1 else H - 2
        r = i & 1
        for j in range(W):
            s0, s1, s2, ok, rd = _bilinear_at(m, i, im, ip, j, W, r, rw, sat)
            ok = _consistent(ok, s0, rd, lim)
            s0o[i, j], s1o[i, j], s2o[i, j] = _stokes_or_zero(s0, s1, s2, ok)


@njit(parallel=True, fastmath=_FM, cache=True, nogil=True)
def _stokes_to_aop_kernel(s0, s1, s2, aop, dop, valid):  # pragma: no cover - compiled
    a0 = s0.reshape(-1)
    a1 = s1.reshape(-1)
    a2 = s2.reshape(-1)
    ao = aop.reshape(-1)
    do = dop.reshape(-1)
    vo = valid.reshape(-1)
    inf = np.float32(np.inf)
    for n in prange(a0.size):
        x0, x1, x2 = a0[n], a1[n], a2[n]
        ok = _good(x0, inf) & _good(x1, inf) & _good(x2, inf)
        x0 = x0 if ok else np.float32(0.0)
        x1 = x1 if ok else np.float32(0.0)
        x2 = x2 if ok else np.float32(0.0)
        ao[n], do[n], vo[n] = _finish(x0, x1, x2, ok)


@njit(fastmath=_FM, cache=True, nogil=True)
def _redundancy_samples(m, w, rw, sat, superpixel, rows, cols, s0o, ro, oko):  # pragma: no cover
    """(S0, redundancy, usable) of the method's outputs at ``rows`` x ``cols`` (output indices)."""
    H, W = m.shape
    for a in range(rows.size):
        i = rows[a]
        for b in range(cols.size):
            j = cols[b]
            if superpixel:
                s0, s1, s2, ok, r = _superpixel_pixel(m, 2 * i, 2 * j, w, sat)
            else:
                s0, s1, s2, ok, r = _bilinear_at(m, i, i - 1, i + 1, j, W, i & 1, rw, sat)
            s0o[a, b], ro[a, b], oko[a, b] = s0, r, ok & (s0 > np.float32(0.0))


# ------------------------------------------------------------------------------------------------
# Public functions
# ------------------------------------------------------------------------------------------------
def _bilinear_weights(layout: MosaicLayout) -> np.ndarray:
    """
    Return the (2, 2, 8) float32 bilinear S1, S2 weights per pixel parity.

    (2, 2, 8) float32: for a pixel of parity (r, c), the S1 then S2 weights of the channel at the
    centre (r, c), the horizontal neighbours (r, 1-c), the vertical (1-r, c) and the diagonal (1-r,
    1-c).
    """
    w = layout.stokes_weights()
    out = np.zeros((2, 2, 8), np.float32)
    for r in range(2):
        for c in range(2):
            roles = [(r, c), (r, 1 - c), (1 - r, c), (1 - r, 1 - c)]
            out[r, c, :4] = [w[y, x, 0] for y, x in roles]
            out[r, c, 4:] = [w[y, x, 1] for y, x in roles]
    return out


def _prepare(mosaic, saturation_level, read_once: bool = False):
    """
    Validate the raw image; float32 copy for the kernels and the float32 saturation threshold.

    ``read_once``: the kernel reads each sample once (superpixels), so an 8- or 16-bit unsigned
    image is passed as it is (the kernel converts each sample to float32 exactly as ``astype``
    would; the copy of a full 2448 x 2048 frame cost 2 ms, a third of the demosaic).
    """
    m = np.asarray(mosaic)
    if m.ndim != 2:
        raise SensorError(f'a mosaic must be a 2-D image, got shape {m.shape}')
    if m.dtype.kind not in 'uif' or m.dtype == np.float16:
        raise SensorError(
            f'mosaic dtype must be unsigned/signed integer, float32 or float64, got {m.dtype}'
        )
    if saturation_level is None:
        sat = float(np.iinfo(m.dtype).max) if m.dtype.kind in 'ui' else math.inf
    else:
        sat = float(saturation_level)
        if math.isnan(sat):
            raise SensorError('saturation_level must be a number, got NaN')
    if read_once and m.dtype in (np.uint8, np.uint16):
        return np.ascontiguousarray(m), np.float32(sat)
    if m.dtype != np.float32:
        # float32 holds every uint16 exactly; converting once is cheaper than converting 9x per
        # pixel. A float64 sample beyond float32's range becomes +-inf, which the kernels treat as
        # invalid.
        with np.errstate(over='ignore'):
            m = m.astype(np.float32)
    return np.ascontiguousarray(m), np.float32(sat)


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
    _stokes_to_aop_kernel(a0, a1, a2, aop, dop, valid)
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
