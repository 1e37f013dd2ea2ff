"""What SM-ASM and Symmetry share: the AoP relative to the local meridian (eqs 29-30) on a disc of
sky centred on the zenith pixel, with a smooth radial taper; mirror-pair weights for an incomplete
sky; and the estimator skeleton both methods run on (:class:`DiscEstimator`).

``xi`` (eq 30, the angle between +y_cam and the local meridian at a pixel) is computed from the pixel's
ray, ``xi = atan2(r_x, r_y)``: for the paper's pinhole with square pixels this is eq 30 exactly
(``atan2(x - cx, y - cy)``, tested), and it stays right for a fisheye or non-square pixels. Both methods
assume a level camera (the paper's premise); under tilt they show the paper's tilt errors.

Why a disc with a smooth edge: both methods find an axis of mirror symmetry of the AOPLM pattern. The
image rectangle is not mirror-symmetric about an arbitrary line through its centre, so its corners
would bias the axis; a disc is symmetric about every such line, and a taper that goes smoothly to zero
keeps the pixel lattice from aliasing at the edge.

Incomplete sky (occluders, invalid pixels, a region that cuts the disc)
-----------------------------------------------------------------------
Both axis fits are unbiased only because the pixels they sum over form a set that is mirror-symmetric
about the true axis. Half a disc is not (unless the cut is perpendicular to the meridian): the fits
were off by 10-20 deg RMS with status ok. So when any pixel of the disc is unusable (invalid or
non-finite) or the view does not cover the disc, each pixel gets the pair weight
``m_i = S(p_i) S(p_i')``, where ``p_i'`` is the pixel's mirror image about the trial axis ``theta``
(a reflection of its sensor-plane offset from the principal point, in millimetres: exact for the
radially symmetric camera models) and ``S`` is a smooth usability map: the indicator of usable pixels
(outside the view: usable beyond the disc, unusable inside it) blurred by a Gaussian of
``MIRROR_BLUR_CELLS`` grid cells, then ``sin^2`` of its rise between the levels ``MIRROR_LEVELS`` (0.5,
0.9), times the indicator itself, bilinear between grid points. An occluded region gets S = 0 with a
smooth edge about 2.5 cells wide; an isolated unusable pixel (NaN, hot pixel) only zeroes S at its own
grid point, so it costs almost no coverage, and the bilinear S(p') takes weight from the pixels paired
with it (without that, 10 % of pixels invalid at random move a noise-free sm_asm heading by 0.1 deg;
with it, < 0.02 deg at stride 16). ``S(p) S(p')`` is exactly mirror-symmetric about ``theta`` and
smooth (no lattice aliasing at the occluder's edge, the same reason as the disc taper), so the fit on
the weighted pixels returns ``theta`` when ``theta`` is the true axis: the axis is a fixed point
``theta = f(theta)`` of "fit the pixels paired about theta". There can be several (the edge of the
occluder is a degenerate one; a thin wedge of pairs elsewhere can balance a fit): :func:`solve_axes`
scans ``h = f(theta) - theta`` on 18 axes with a subsample and refines every sign change by the secant
method (the true axis may attract or repel a plain iteration). Kept are axes with mirror coverage
``>= min_mirror_coverage``, ``|1 - f'| >= MIN_CONDITIONING``, the method's own test (symmetry: the
paired map is symmetric, ``F / sum |a_k|^2 >= 0.95``) and a level-Rayleigh residual at most
``MAX_MIRROR_RESIDUAL_RATIO`` times the plain fit's; of these the one with the smallest residual wins.
When the pair fit about the plain axis agrees with the plain fit within ``MIRROR_AGREEMENT_DEG`` and
pairs at least half the disc (a few or scattered unusable pixels), the plain result stands.

Uncertainty of the fixed point: ``d theta* = d f / (1 - f'(theta*))``: the statistical sigma of the
weighted fit is divided by ``|1 - f'|`` (``f'`` from the last secant step or a finite difference). When
the usable pairs form a thin wedge the fit follows the wedge (``f' -> 1``) and sigma grows accordingly.
Without an acceptable axis the status is ``insufficient_coverage`` with the measured share or the failed
test in the reason. A complete disc is never re-weighted: the plain fit, as before.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from ..camera import CameraModel, PixelSelection
from .base import Estimator, HeadingResult, Observation, Status
from ._common import (Candidate, Knob, KnobbedEstimator, _BadInput, axial_residual_rad, brightness_t_from_stats,
                      check_sun, finish_sigma_deg, level_sun_candidates, rayleigh_aop_rad, resolve_ambiguity,
                      result_from, selection_for, select_view, view_segments)
from ._kernels import acc_brightness
from ._vecmath import FM as _FMV, atan2, exp_nonpos, sincos, sincos_folded

__all__ = ["DISC_KNOBS", "disc_radius", "disc_radius_mm", "disc_selection", "taper", "aoplm_rad", "level_residual",
           "band_pass1", "band_pass2", "ring_pass1", "ring_pass2", "cr1_sigma", "MirrorMap", "mirror_map",
           "NO_MIRROR", "view_covers_disc", "solve_axes", "AxisFit", "level_rss", "DiscEstimator",
           "MIRROR_BLUR_CELLS", "MIRROR_LEVELS", "disc_cells"]

DISC_KNOBS = {
    "disc_fraction": Knob(1.0, "float", 0.05, 1.0,
                          doc="radius of the sky disc used, as a fraction of the largest disc inside the image"),
    "taper_fraction": Knob(0.2, "float", 0.0, 1.0, doc="outer part of the disc over which weights fall to zero"),
    "min_mirror_coverage": Knob(0.1, "float", 0.0, 1.0,
                                doc="part of the disc unusable (occluded, invalid, cut by region): the share of the "
                                    "disc whose mirror image about the axis is also usable must reach this, else "
                                    "status insufficient_coverage"),
}

#: The smooth usability map S: the usable-pixel indicator blurred by a Gaussian of this sigma (grid cells),
#: then S = sin^2 of its rise between these two levels (0 below the first, 1 above the second).
MIRROR_BLUR_CELLS = 2.0
MIRROR_LEVELS = (0.5, 0.9)
#: Pixels per chunk of the vectorised Symmetry passes (their scratch arrays stay in L1/L2).
_RING_CHUNK = 512
#: Secant steps of the refinement of one fixed point before giving up.
MAX_SOLVE_STEPS = 25
#: Trial axes of the coarse scan for fixed points (over 180 deg), and its pixel subsampling.
SCAN_AXES = 18
SCAN_STEP = 8
#: A sign change of h between neighbouring scan axes larger than this (rad) is a jump, not a root.
MAX_BRACKET_JUMP = 0.75
#: A self-consistent axis whose level Rayleigh pattern misses the usable pixels by more than this factor times
#: the plain (occlusion-biased) fit's rms residual, plus 0.01 deg, is not the meridian (the false ones we met
#: were 30-80 deg away, with residuals of 20-40 deg against a few degrees).
MAX_MIRROR_RESIDUAL_RATIO = 1.5
#: Pixel subsampling of the residual passes that compare self-consistent axes.
RESIDUAL_STEP = 3
#: The plain fit is kept when the fit on the mirror pairs about its own axis (with at least half the disc
#: paired) moves it by less than this (deg): the unusable pixels do not bias it.
MIRROR_AGREEMENT_DEG = 0.02
#: |1 - f'| below this: the usable pairs do not determine the axis (insufficient_coverage).
MIN_CONDITIONING = 1e-3


@lru_cache(maxsize=32)
def disc_radius(camera: CameraModel) -> float:
    """hypot(r_x, r_y) of the largest ray circle about the optical axis inside the image."""
    cx, cy = camera.cx_px, camera.cy_px
    xs = np.array([1.0, float(camera.width_px), cx, cx])
    ys = np.array([cy, cy, 1.0, float(camera.height_px)])
    r, ok = camera.rays_from_pixels(xs, ys)
    rho = np.hypot(r[0], r[1])
    return float(rho[ok].min()) if ok.any() else 1.0


def disc_radius_mm(camera: CameraModel, rho_max: float) -> float:
    """Radius on the sensor (mm from the principal point) of the ray circle hypot(r_x, r_y) = rho_max."""
    f = camera.focal_length_mm
    if camera.model == "pinhole":
        return f * math.tan(math.asin(min(rho_max, 1.0)))
    return f * math.asin(min(rho_max, 1.0))


def disc_selection(camera: CameraModel, fraction: float, stride: int) -> PixelSelection:
    """The square of sensor pixels holding the disc (and the stride)."""
    rr = disc_radius_mm(camera, disc_radius(camera) * fraction)
    hx = rr / (camera.pixel_pitch_x_um * 1e-3) + 1.0
    hy = rr / (camera.pixel_pitch_y_um * 1e-3) + 1.0
    x0 = max(1, int(math.floor(camera.cx_px - hx)))
    x1 = min(int(camera.width_px), int(math.ceil(camera.cx_px + hx)))
    y0 = max(1, int(math.floor(camera.cy_px - hy)))
    y1 = min(int(camera.height_px), int(math.ceil(camera.cy_px + hy)))
    # keep the block symmetric about the principal point
    dx = min(camera.cx_px - x0, x1 - camera.cx_px)
    dy = min(camera.cy_px - y0, y1 - camera.cy_px)
    x0, x1 = int(math.ceil(camera.cx_px - dx)), int(math.floor(camera.cx_px + dx))
    y0, y1 = int(math.ceil(camera.cy_px - dy)), int(math.floor(camera.cy_px + dy))
    return PixelSelection.rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1, stride)


def taper(rho, rho_max: float, fraction: float) -> np.ndarray:
    """1 inside ``(1 - fraction) rho_max``, then a cos^2 fall to 0 at ``rho_max`` (C1-smooth)."""
    rho = np.asarray(rho, dtype=float)
    if fraction <= 0.0:
        return (rho <= rho_max).astype(float)
    t = np.clip((rho / rho_max - (1.0 - fraction)) / fraction, 0.0, 1.0)
    return np.cos(0.5 * np.pi * t) ** 2


def aoplm_rad(aop_rad, rays):
    """Eq 29: AoP - xi, folded to [-pi/2, pi/2), with xi = atan2(r_x, r_y) (eq 30 from the ray)."""
    xi = np.arctan2(rays[0], rays[1])
    return axial_residual_rad(aop_rad, xi), xi


def level_residual(psi_rad: float, altitude_deg: float, aop_rad, rays):
    """Residuals of the AoP against the level-camera Rayleigh pattern of heading psi (rad), trying both
    ends of the meridian and keeping the better fit. Returns (residual_rad, sun_cam of the better end)."""
    best = None
    for c in level_sun_candidates(psi_rad, altitude_deg):
        r = axial_residual_rad(aop_rad, rayleigh_aop_rad(c.sun_cam, rays))
        ss = float(np.dot(r, r))
        if best is None or ss < best[0]:
            best = (ss, r, c.sun_cam)
    return best[1], best[2]


# --------------------------------------------------------------------------------------------
# Compiled passes (one loop over the view's pixels each; blocks via segments, see _common.view_segments)
#
# Pass 1 (the plain fit) also counts: cnt = (usable, valid, valid non-finite, unusable pixels inside the
# disc). With unusable pixels, a gather pass compacts the invariant per-pixel terms of the usable pixels
# (times S(p)) once, and each trial axis of the mirror iteration is then a short fit over them with the
# weight S(p'); pass 2 takes the final pair weights (none: ``mg`` of shape (0, 0), bit-identical sums).
# --------------------------------------------------------------------------------------------
@njit(inline="always", cache=True, error_model="numpy")
def _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi):  # pragma: no cover - compiled
    """Load pixel i: (usable, all values finite, ray inside the disc ring [rho_lo, rho_hi], a, p, rx, ry, rz,
    rho, cos 2a, sin 2a). The ring test needs only a finite ray (it holds for invalid pixels too). Branch-free
    (``&`` and selects, not ``and``), so that loops over it can vectorise (:func:`_lane_pixel`)."""
    a = np.float64(aop[i])
    p = np.float64(dop[i])
    rx = np.float64(rays[0, i])
    ry = np.float64(rays[1, i])
    rz = np.float64(rays[2, i])
    rfin = (abs(rx) < 1e6) & (abs(ry) < 1e6) & (abs(rz) < 1e6)
    fin = rfin & (abs(a) < 1e6) & (abs(p) < 1e6)
    rho = math.sqrt(rx * rx + ry * ry)
    rho = rho if rfin else 0.0
    inr = rfin & (rho >= rho_lo) & (rho <= rho_hi) & (rho > 0.0)
    ok = valid[i] & fin & (p >= min_dop) & inr
    sa, ca = sincos_folded(a if fin else 0.0)
    return ok, fin, inr, a, p, rx, ry, rz, rho, ca * ca - sa * sa, 2.0 * sa * ca


@njit(inline="always", cache=True, error_model="numpy")
def _taper1(rho, rho_max, frac):  # pragma: no cover - compiled
    """The taper (:func:`taper`) at rho, branch-free (vectorises)."""
    t = min(max((rho / rho_max - (1.0 - frac)) / frac, 0.0), 1.0)
    c = sincos_folded(0.5 * math.pi * t)[1]
    hard = 1.0 if rho <= rho_max else 0.0
    return c * c if frac > 0.0 else hard


@njit(inline="always", cache=True)
def _bilinear0(g, r, c):  # pragma: no cover - compiled
    """g (2-D) at fractional (row r, column c), bilinear, 0 outside the grid."""
    ny, nx = g.shape
    if not (r > -1.0 and c > -1.0 and r < ny and c < nx):
        return 0.0
    i0 = int(math.floor(r))
    j0 = int(math.floor(c))
    fr = r - i0
    fc = c - j0
    if i0 >= 0 and j0 >= 0 and i0 + 1 < ny and j0 + 1 < nx:            # inside: no per-corner test
        return ((1.0 - fr) * ((1.0 - fc) * g[i0, j0] + fc * g[i0, j0 + 1])
                + fr * ((1.0 - fc) * g[i0 + 1, j0] + fc * g[i0 + 1, j0 + 1]))
    acc = 0.0
    for di in range(2):
        i = i0 + di
        if i < 0 or i >= ny:
            continue
        wr = fr if di else 1.0 - fr
        for dj in range(2):
            j = j0 + dj
            if j < 0 or j >= nx:
                continue
            acc += wr * (fc if dj else 1.0 - fc) * g[i, j]
    return acc


@njit(inline="always", cache=True)
def _mirror_consts(mp):  # pragma: no cover - compiled
    """(sin theta, cos theta, columns per mm, rows per mm, column and row of the principal point) of mp."""
    return (mp[4], mp[5], 1.0 / (mp[2] * mp[7]), 1.0 / (mp[3] * mp[9]), (mp[0] - mp[6]) / mp[7],
            (mp[1] - mp[8]) / mp[9])


@njit(inline="always", cache=True)
def _mirror_s_mm(mg, st, ct, kc, kr, c0, r0, u, v):  # pragma: no cover - compiled
    """S at the mirror image of the sensor offset (u, v) mm (constants from :func:`_mirror_consts`)."""
    d = 2.0 * (u * st + v * ct)
    return _bilinear0(mg, r0 + (d * ct - v) * kr, c0 + (d * st - u) * kc)


@njit(inline="always", cache=True)
def _mirror_weight(mg, mp, x, y):  # pragma: no cover - compiled
    """The pair weight S(p) S(p') of the pixel at sensor position (x, y). ``mp``: cx, cy, pitch_x, pitch_y (mm),
    sin theta, cos theta (the trial axis, from +y_cam towards +x_cam), x0, dx, y0, dy of the S grid; the
    reflection acts on the offset from the principal point in millimetres."""
    st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
    own = _bilinear0(mg, (y - mp[8]) / mp[9], (x - mp[6]) / mp[7])
    return own * _mirror_s_mm(mg, st, ct, kc, kr, c0, r0, (x - mp[0]) * mp[2], (y - mp[1]) * mp[3])


@njit(inline="always", cache=True, error_model="numpy")
def _level_resid(c2a, s2a, rx, ry, rz, s0, s1, s2):  # pragma: no cover - compiled
    """AoP residual (rad, axial) against the Rayleigh E-vector s x r of the sun s = (s0, s1, s2):
    0.5 arg(exp(2ia) conj(u)^2), u = ey + i ex (branch-free atan2)."""
    ex = s1 * rz - s2 * ry
    ey = s2 * rx - s0 * rz
    ur = ey * ey - ex * ex               # u^2 = (ey + i ex)^2
    ui = 2.0 * ex * ey
    qr = c2a * ur + s2a * ui             # exp(2ia) * conj(u^2)
    qi = s2a * ur - c2a * ui
    return 0.5 * atan2(qi, qr)


@njit(inline="always", cache=True)
def _exp2i_aoplm(c2a, s2a, rx, ry, rho):  # pragma: no cover - compiled
    """(Re, Im) of exp(2i AOPLM) = exp(2ia) x^2 with x = (r_y - i r_x) / rho = exp(-i xi)."""
    er = ry / rho
    ei = -rx / rho
    x2r = er * er - ei * ei
    x2i = 2.0 * er * ei
    return c2a * x2r - s2a * x2i, c2a * x2i + s2a * x2r


@njit(inline="always", cache=True, error_model="numpy")
def _ring_t(rho, rho_lo, span, n_rings):  # pragma: no cover - compiled
    """Ring position of radius rho: t in [0, n_rings - 1], rings at the integers (branch-free)."""
    return min(max((rho - rho_lo) / span, 0.0), 1.0) * (n_rings - 1)


@njit(inline="always", cache=True)
def _ring_split(t, n_rings):  # pragma: no cover - compiled
    """Ring index j and the linear split f towards ring j + 1 of a ring position t >= 0 (j + f = t)."""
    j = min(np.int64(t), n_rings - 1)
    return j, t - j


@njit(cache=True, nogil=True)
def _brightness_pass(aop, dop, valid, rays, inten, min_dop, rho_lo, rho_max, stats):  # pragma: no cover - compiled
    """Brightness statistics (:func:`acc_brightness`) of every usable pixel with a finite intensity."""
    for i in range(aop.size):
        ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_max)
        I = np.float64(inten[i])
        if ok and abs(I) < 1e30:
            acc_brightness(stats, 0, I, rx, ry, rz)


@njit(cache=True, nogil=True, fastmath=_FMV, error_model="numpy")
def _band_sums(aop, dop, valid, rays, min_dop, rho_max, taper_frac, inv4tol2, out, cnt):  # pragma: no cover
    """The sums of :func:`band_pass1` (vectorised)."""
    n_ok = n_v = n_bad = n_hole = 0
    Zr = Zi = nrm = 0.0
    for i in range(aop.size):
        ok, v, bad, hole, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(aop, dop, valid, rays, i, min_dop, 0.0, rho_max)
        n_ok += np.int64(ok)
        n_v += np.int64(v)
        n_bad += np.int64(bad)
        n_hole += np.int64(hole)
        cr, ci = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        W = exp_nonpos((-cr - 1.0) * inv4tol2) * p * p * _taper1(rho, rho_max, taper_frac)   # cos 2 delta = -cr
        Zr += W * (ry * ry - rx * rx)
        Zi += W * 2.0 * rx * ry
        nrm += W * rho * rho
    out[0] += Zr
    out[1] += Zi
    out[2] += nrm
    cnt[0] += n_ok
    cnt[1] += n_v
    cnt[2] += n_bad
    cnt[3] += n_hole


@njit(cache=True, nogil=True)
def band_pass1(aop, dop, valid, rays, inten, has_i, min_dop, rho_max, taper_frac, inv4tol2, out, cnt,
               stats):  # pragma: no cover - compiled
    """SM-ASM: out = (Re Z, Im Z, sum W rho^2) with Z = sum W z^2, W = exp((cos 2 delta - 1) / (4 tol^2))
    DoP^2 taper; cnt = (usable, valid, valid non-finite, unusable inside the disc); with ``has_i`` the
    brightness statistics of the usable pixels into ``stats`` (a second, scalar loop)."""
    _band_sums(aop, dop, valid, rays, min_dop, rho_max, taper_frac, inv4tol2, out, cnt)
    if has_i:
        _brightness_pass(aop, dop, valid, rays, inten, min_dop, 0.0, rho_max, stats)


@njit(inline="always", cache=True)
def _gather_pixel(aop, dop, valid, rays, xs, ys, i, min_dop, rho_lo, rho_max, taper_frac, mg, mp,
                  g_uv, n):  # pragma: no cover - compiled
    """Pixel i for a gather: (kept: valid, finite, in the disc and S(p) > 0; usable; taper; S(p); p, rx, ry,
    rho, cos 2a, sin 2a); a kept pixel's offset from the principal point (mm) goes to g_uv[:, n]."""
    ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_max)
    tp = 0.0
    s = 0.0
    if inr and valid[i] and fin:
        tp = _taper1(rho, rho_max, taper_frac)
        s = _bilinear0(mg, (ys[i] - mp[8]) / mp[9], (xs[i] - mp[6]) / mp[7])
    keep = s > 0.0
    if keep:
        g_uv[0, n] = (xs[i] - mp[0]) * mp[2]
        g_uv[1, n] = (ys[i] - mp[1]) * mp[3]
    return keep, ok, tp, s, p, rx, ry, rho, c2a, s2a


@njit(cache=True, nogil=True)
def band_gather(aop, dop, valid, rays, xs, ys, min_dop, rho_max, taper_frac, inv4tol2, mg, mp,
                g_uv, g_val):  # pragma: no cover - compiled
    """SM-ASM with mirror pairs, step 1: every valid finite pixel of the disc with S(p) > 0, compacted:
    g_uv[:, j] = offset from the principal point (mm), g_val[:, j] = (taper S(p), W S(p) z^2 (re, im),
    W S(p) rho^2) (W = 0 below min_dop). Returns the count."""
    n = 0
    for i in range(aop.size):
        keep, ok, tp, s, p, rx, ry, rho, c2a, s2a = _gather_pixel(aop, dop, valid, rays, xs, ys, i, min_dop, 0.0,
                                                                  rho_max, taper_frac, mg, mp, g_uv, n)
        if not keep:
            continue
        W = 0.0
        if ok:
            cr, ci = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
            W = math.exp((-cr - 1.0) * inv4tol2) * p * p * tp * s
        g_val[0, n] = tp * s
        g_val[1, n] = W * (ry * ry - rx * rx)
        g_val[2, n] = W * 2.0 * rx * ry
        g_val[3, n] = W * rho * rho
        n += 1
    return n


@njit(cache=True, nogil=True)
def band_fit(g_uv, g_val, n, step, mg, mp, out):  # pragma: no cover - compiled
    """SM-ASM with mirror pairs, step 2 (per trial axis): out = (Re Z, Im Z, sum W rho^2, coverage numerator
    sum taper S(p) S(p'), usable pixels with a pair weight > 0) over every ``step``-th gathered pixel."""
    st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
    Zr = Zi = nrm = cov = 0.0
    n_pair = 0
    for j in range(0, n, step):
        m = _mirror_s_mm(mg, st, ct, kc, kr, c0, r0, g_uv[0, j], g_uv[1, j])
        if not m > 0.0:
            continue
        cov += g_val[0, j] * m
        Zr += g_val[1, j] * m
        Zi += g_val[2, j] * m
        nrm += g_val[3, j] * m
        n_pair += 1 if g_val[3, j] > 0.0 else 0
    out[0] = Zr
    out[1] = Zi
    out[2] = nrm
    out[3] = cov
    out[4] = n_pair


@njit(inline="always", cache=True, error_model="numpy")
def _lane_pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi):  # pragma: no cover - compiled
    """Pixel i for a vectorised pass: (usable, valid, valid but non-finite, unusable inside the disc ring, p, rx,
    ry, rz, rho, cos 2a, sin 2a) from :func:`_pixel`; an unusable pixel reads as p = 0 on the ray (1, 0, 0), so
    that every value stays finite and its weight is 0 without a branch."""
    ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi)
    v = valid[i]
    p = p if ok else 0.0
    rx = rx if ok else 1.0
    ry = ry if ok else 0.0
    rz = rz if ok else 0.0
    rho = rho if ok else 1.0
    return ok, v, v & ~fin, inr & ~(v & fin), p, rx, ry, rz, rho, c2a, s2a


@njit(cache=True, nogil=True)
def _pair_weights(mg, mp, xs, ys):  # pragma: no cover - compiled
    """S(p) S(p') of every pixel (:func:`_mirror_weight`), or ones without a mirror map (``mg`` empty)."""
    out = np.ones(xs.size)
    if mg.shape[0]:
        for i in range(xs.size):
            out[i] = _mirror_weight(mg, mp, xs[i], ys[i])
    return out


@njit(cache=True, nogil=True)
def _block_sums(t0, t1, seg_start, seg_end, seg_block, block_sum):  # pragma: no cover - compiled
    """block_sum[0|1, block] += the sums of t0|t1 over each segment."""
    for k in range(seg_start.size):
        u = v = 0.0
        for i in range(seg_start[k], seg_end[k]):
            u += t0[i]
            v += t1[i]
        block_sum[0, seg_block[k]] += u
        block_sum[1, seg_block[k]] += v


@njit(cache=True, nogil=True, fastmath=_FMV, error_model="numpy")
def _band_terms(aop, dop, valid, rays, min_dop, rho_max, taper_frac, inv4tol2, Zr, Zi, s1, s2, wm, t0, t1,
                rss):  # pragma: no cover - compiled
    """Per pixel (vectorised): t_j = (d theta / d a) * residual_j (0 if unusable); rss[j] += residual_j^2."""
    modZ2 = Zr * Zr + Zi * Zi
    a0, a1, a2 = s1[0], s1[1], s1[2]
    b0, b1, b2 = s2[0], s2[1], s2[2]
    q0 = q1 = 0.0
    for i in range(aop.size):
        ok, _, _, _, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(aop, dop, valid, rays, i, min_dop, 0.0, rho_max)
        cr, ci = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        W = exp_nonpos((-cr - 1.0) * inv4tol2) * p * p * _taper1(rho, rho_max, taper_frac) * wm[i]
        dW = W * ci * 2.0 * inv4tol2             # dW/da: d(cos 2 delta)/da = -2 sin 2 delta = 2 ci
        z2r = ry * ry - rx * rx
        z2i = 2.0 * rx * ry
        sens = 0.5 * dW * (z2i * Zr - z2r * Zi) / modZ2
        r1 = _level_resid(c2a, s2a, rx, ry, rz, a0, a1, a2)
        r2 = _level_resid(c2a, s2a, rx, ry, rz, b0, b1, b2)
        r1 = r1 if ok else 0.0
        r2 = r2 if ok else 0.0
        t0[i] = sens * r1
        t1[i] = sens * r2
        q0 += r1 * r1
        q1 += r2 * r2
    rss[0] += q0
    rss[1] += q1


@njit(cache=True, nogil=True)
def band_pass2(aop, dop, valid, rays, xs, ys, seg_start, seg_end, seg_block, min_dop, rho_max, taper_frac, inv4tol2,
               mg, mp, Zr, Zi, s1, s2, block_sum, rss):  # pragma: no cover - compiled
    """SM-ASM influence: block_sum[j, b] += (d theta / d a_i) * residual_j(i) for the two candidate suns;
    rss[j] += residual_j^2 (pair weights m = S(p) S(p') when ``mg`` is not empty). The per-pixel terms are
    one vectorised loop (:mod:`._vecmath`), the block sums a second."""
    t0 = np.empty(aop.size)
    t1 = np.empty(aop.size)
    _band_terms(aop, dop, valid, rays, min_dop, rho_max, taper_frac, inv4tol2, Zr, Zi, s1, s2,
                _pair_weights(mg, mp, xs, ys), t0, t1, rss)
    _block_sums(t0, t1, seg_start, seg_end, seg_block, block_sum)


@njit(inline="always", cache=True)
def _ring_add(a_out, K, n_rings, j, f, c, e):  # pragma: no cover - compiled
    """a_out[k + K, ring] += hat * c * e^k (k = -K..K), split linearly between rings j and j + 1."""
    g0 = 1.0 - f
    a_out[K, j] += g0 * c
    if j + 1 < n_rings:
        a_out[K, j + 1] += f * c
    ep = c
    em = c
    ec = e.conjugate()
    for kk in range(1, K + 1):
        ep = ep * e
        em = em * ec
        a_out[K + kk, j] += g0 * ep
        a_out[K - kk, j] += g0 * em
        if j + 1 < n_rings:
            a_out[K + kk, j + 1] += f * ep
            a_out[K - kk, j + 1] += f * em


@njit(cache=True, nogil=True, fastmath=_FMV, error_model="numpy")
def _ring1_terms(aop, dop, valid, rays, o, n, min_dop, rho_lo, rho_max, taper_frac, n_rings, cr, ci, er, ei, tr,
                 cnt):  # pragma: no cover - compiled
    """Pixels o..o+n of :func:`ring_pass1` (vectorised): c = w exp(2i AOPLM) (0 if unusable), e = exp(-i xi),
    ring position tr; counts into cnt."""
    span = max(rho_max - rho_lo, 1e-12)
    n_ok = n_v = n_bad = n_hole = 0
    for q in range(n):
        ok, v, bad, hole, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(aop, dop, valid, rays, o + q, min_dop, rho_lo,
                                                                     rho_max)
        n_ok += np.int64(ok)
        n_v += np.int64(v)
        n_bad += np.int64(bad)
        n_hole += np.int64(hole)
        c_r, c_i = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        w = p * p * _taper1(rho, rho_max, taper_frac)
        cr[q] = c_r * w
        ci[q] = c_i * w
        er[q] = ry / rho
        ei[q] = -rx / rho
        tr[q] = _ring_t(rho, rho_lo, span, n_rings)
    cnt[0] += n_ok
    cnt[1] += n_v
    cnt[2] += n_bad
    cnt[3] += n_hole


@njit(cache=True, nogil=True, error_model="numpy")
def ring_pass1(aop, dop, valid, rays, inten, has_i, min_dop, rho_lo, rho_max, taper_frac, n_rings, K,
               a_out, cnt, stats):  # pragma: no cover - compiled
    """Symmetry: a_out[k + K, ring] += hat * w * c * exp(-i k phi), k = -K..K, c = exp(2i AOPLM),
    w = DoP^2 taper, linear split between neighbouring rings; cnt and stats as :func:`band_pass1`. In chunks:
    the per-pixel terms (vectorised), then the scatter into the rings (scalar)."""
    CH = _RING_CHUNK
    cr = np.empty(CH)
    ci = np.empty(CH)
    er = np.empty(CH)
    ei = np.empty(CH)
    tr = np.empty(CH)
    for o in range(0, aop.size, CH):
        n = min(CH, aop.size - o)
        _ring1_terms(aop, dop, valid, rays, o, n, min_dop, rho_lo, rho_max, taper_frac, n_rings, cr, ci, er, ei, tr,
                     cnt)
        for q in range(n):
            if cr[q] == 0.0 and ci[q] == 0.0:
                continue                            # unusable (or zero weight: adds nothing)
            j, f = _ring_split(tr[q], n_rings)
            _ring_add(a_out, K, n_rings, j, f, complex(cr[q], ci[q]), complex(er[q], ei[q]))
    if has_i:
        _brightness_pass(aop, dop, valid, rays, inten, min_dop, rho_lo, rho_max, stats)


@njit(cache=True, nogil=True)
def ring_gather(aop, dop, valid, rays, xs, ys, min_dop, rho_lo, rho_max, taper_frac, n_rings, K, mg, mp,
                g_uv, g_tp, g_v, g_ring):  # pragma: no cover - compiled
    """Symmetry with mirror pairs, step 1 (see :func:`band_gather`): g_tp = taper S(p), g_v[k + K] = w S(p) c
    exp(-i k phi) for k = -K..K (0 below min_dop), g_ring = ring position (:func:`_ring_t`). Returns the count."""
    span = max(rho_max - rho_lo, 1e-12)
    n = 0
    for i in range(aop.size):
        keep, ok, tp, s, p, rx, ry, rho, c2a, s2a = _gather_pixel(aop, dop, valid, rays, xs, ys, i, min_dop, rho_lo,
                                                                  rho_max, taper_frac, mg, mp, g_uv, n)
        if not keep:
            continue
        e = complex(ry / rho, -rx / rho)
        c = complex(0.0, 0.0)
        if ok:
            c = complex(c2a, s2a) * e * e * (p * p * tp * s)
        g_v[K, n] = c
        ep = c
        em = c
        ec = e.conjugate()
        for kk in range(1, K + 1):
            ep = ep * e
            em = em * ec
            g_v[K + kk, n] = ep
            g_v[K - kk, n] = em
        g_tp[n] = tp * s
        g_ring[n] = _ring_t(rho, rho_lo, span, n_rings)
        n += 1
    return n


@njit(cache=True, nogil=True)
def ring_fit(g_uv, g_tp, g_v, g_ring, n, step, n_rings, K, mg, mp, a_out, out):  # pragma: no cover - compiled
    """Symmetry with mirror pairs, step 2 (per trial axis): the ring coefficients a_out of the gathered pixels
    weighted by S(p'); out = (coverage numerator, usable pixels with a pair weight > 0); every ``step``-th
    gathered pixel."""
    st, ct, kc, kr, c0, r0 = _mirror_consts(mp)
    cov = 0.0
    n_pair = 0
    for q in range(0, n, step):
        m = _mirror_s_mm(mg, st, ct, kc, kr, c0, r0, g_uv[0, q], g_uv[1, q])
        if not m > 0.0:
            continue
        cov += g_tp[q] * m
        if g_v[K, q].real == 0.0 and g_v[K, q].imag == 0.0:
            continue
        n_pair += 1
        j, f = _ring_split(g_ring[q], n_rings)
        w0 = (1.0 - f) * m
        w1 = f * m
        for k in range(2 * K + 1):
            v = g_v[k, q]
            a_out[k, j] += w0 * v
            if j + 1 < n_rings:
                a_out[k, j + 1] += w1 * v
    out[0] = cov
    out[1] = n_pair


@njit(cache=True, nogil=True, fastmath=_FMV, error_model="numpy")
def _ring_terms(aop, dop, valid, rays, o, n, min_dop, rho_lo, rho_max, taper_frac, n_rings, s1, s2, wm,
                cr, ci, xi, tr, r1, r2, rss):  # pragma: no cover - compiled
    """Pixels o..o+n (vectorised): c = w exp(2i AOPLM) (w = DoP^2 taper S S'; 0 if unusable) into cr, ci;
    xi = atan2(r_x, r_y); tr = ring position in [0, n_rings - 1]; the residuals r_j (0 if unusable);
    rss[j] += r_j^2."""
    span = max(rho_max - rho_lo, 1e-12)
    a0, a1, a2 = s1[0], s1[1], s1[2]
    b0, b1, b2 = s2[0], s2[1], s2[2]
    q0 = q1 = 0.0
    for q in range(n):
        i = o + q
        ok, _, _, _, p, rx, ry, rz, rho, c2a, s2a = _lane_pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_max)
        c_r, c_i = _exp2i_aoplm(c2a, s2a, rx, ry, rho)
        w = p * p * _taper1(rho, rho_max, taper_frac) * wm[i]
        cr[q] = c_r * w
        ci[q] = c_i * w
        xi[q] = atan2(rx, ry)
        tr[q] = _ring_t(rho, rho_lo, span, n_rings)
        u1 = _level_resid(c2a, s2a, rx, ry, rz, a0, a1, a2)
        u2 = _level_resid(c2a, s2a, rx, ry, rz, b0, b1, b2)
        u1 = u1 if ok else 0.0
        u2 = u2 if ok else 0.0
        r1[q] = u1
        r2[q] = u2
        q0 += u1 * u1
        q1 += u2 * u2
    rss[0] += q0
    rss[1] += q1


@njit(cache=True, nogil=True, fastmath=_FMV, error_model="numpy")
def _ring_harmonic(n, kk, n_rings, cr, ci, xi, tr, Bpr, Bpi, Bmr, Bmi, acc):  # pragma: no cover - compiled
    """Harmonic kk of d F' / d a: acc += Re(c E B+(ring)) + Re(c conj(E) B-(ring)), E = e^kk = exp(-i kk xi),
    B+- linear between the rings (tables padded by a zero ring)."""
    for q in range(n):
        s, c = sincos(kk * xi[q])
        pr = cr[q] * c + ci[q] * s           # c E
        pi_ = ci[q] * c - cr[q] * s
        mr = cr[q] * c - ci[q] * s           # c conj(E)
        mi = ci[q] * c + cr[q] * s
        j, f = _ring_split(tr[q], n_rings)
        g = 1.0 - f
        acc[q] += (pr * (g * Bpr[kk, j] + f * Bpr[kk, j + 1]) - pi_ * (g * Bpi[kk, j] + f * Bpi[kk, j + 1])
                   + mr * (g * Bmr[kk, j] + f * Bmr[kk, j + 1]) - mi * (g * Bmi[kk, j] + f * Bmi[kk, j + 1]))


@njit(cache=True, nogil=True, error_model="numpy")
def ring_pass2(aop, dop, valid, rays, xs, ys, seg_start, seg_end, seg_block, min_dop, rho_lo, rho_max, taper_frac,
               n_rings, K, mg, mp, a_in, rot, F2, s1, s2, block_sum, rss):  # pragma: no cover - compiled
    """Symmetry influence: d theta / d a_i = -(d F'/d a_i) / F'' with
    d F'/d a_i = Re sum_k (-8k) e^{2ik theta} w_i c_i e_i^k A_k(i) (A_k: a_k interpolated at the pixel's
    ring), times the residual against each candidate sun (pair weights as :func:`band_pass2`). In chunks:
    the per-pixel terms (vectorised), one loop per harmonic, then the block sums."""
    N = aop.size
    wm = _pair_weights(mg, mp, xs, ys)
    Bpr = np.zeros((K + 1, n_rings + 1))
    Bpi = np.zeros((K + 1, n_rings + 1))
    Bmr = np.zeros((K + 1, n_rings + 1))
    Bmi = np.zeros((K + 1, n_rings + 1))
    for kk in range(1, K + 1):
        for j in range(n_rings):
            bp = (-8.0 * kk) * rot[K + kk] * a_in[K + kk, j]
            bm = (8.0 * kk) * rot[K - kk] * a_in[K - kk, j]
            Bpr[kk, j] = bp.real
            Bpi[kk, j] = bp.imag
            Bmr[kk, j] = bm.real
            Bmi[kk, j] = bm.imag
    t0 = np.empty(N)
    t1 = np.empty(N)
    CH = _RING_CHUNK
    cr = np.empty(CH)
    ci = np.empty(CH)
    xi = np.empty(CH)
    tr = np.empty(CH)
    r1 = np.empty(CH)
    r2 = np.empty(CH)
    acc = np.empty(CH)
    for o in range(0, N, CH):
        n = min(CH, N - o)
        _ring_terms(aop, dop, valid, rays, o, n, min_dop, rho_lo, rho_max, taper_frac, n_rings, s1, s2, wm,
                    cr, ci, xi, tr, r1, r2, rss)
        acc[:n] = 0.0
        for kk in range(1, K + 1):
            _ring_harmonic(n, kk, n_rings, cr, ci, xi, tr, Bpr, Bpi, Bmr, Bmi, acc)
        for q in range(n):
            sens = -acc[q] / F2
            t0[o + q] = sens * r1[q]
            t1[o + q] = sens * r2[q]
    _block_sums(t0, t1, seg_start, seg_end, seg_block, block_sum)


@njit(cache=True, nogil=True)
def level_rss(aop, dop, valid, rays, min_dop, rho_lo, rho_max, s1, s2, step, rss):  # pragma: no cover - compiled
    """rss[j] += squared AoP residual against the level Rayleigh pattern of sun s_j over every ``step``-th pixel
    (rss[2] += 1 for each usable one)."""
    for i in range(0, aop.size, step):
        ok, fin, inr, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_max)
        if not ok:
            continue
        r1 = _level_resid(c2a, s2a, rx, ry, rz, s1[0], s1[1], s1[2])
        r2 = _level_resid(c2a, s2a, rx, ry, rz, s2[0], s2[1], s2[2])
        rss[0] += r1 * r1
        rss[1] += r2 * r2
        rss[2] += 1.0


def cr1_sigma(block_sum, n: int) -> float:
    """Cluster-robust sigma from block sums of the influence (CR1 small-sample factor, one parameter)."""
    b = np.asarray(block_sum, dtype=float)
    b = b[b != 0.0]
    G = b.size
    if G == 0:
        return 0.0
    corr = (G / (G - 1.0) if G > 1 else 1.0) * ((n - 1.0) / (n - 1.0 - 1.0) if n > 2 else 1.0)
    return math.sqrt(float(np.dot(b, b)) * corr)


# --------------------------------------------------------------------------------------------
# Mirror pairs
# --------------------------------------------------------------------------------------------
#: No mirror weighting (m = 1): an empty S map and unused parameters.
NO_MIRROR = (np.zeros((0, 0)), np.zeros(10))


@dataclass
class MirrorMap:
    """Smooth usability ``S`` on a regular grid of sensor positions, and the reflection parameters.

    ``grid`` (ny, nx) float64 in [0, 1]; grid point (r, c) is at sensor pixel (x0 + c dx, y0 + r dy)."""

    grid: np.ndarray
    params: np.ndarray          # cx, cy, pitch_x, pitch_y, 0, 0, x0, dx, y0, dy
    lattice: tuple              # x0, dx, y0, dy of the view's own pixels
    camera: CameraModel

    def at(self, theta_rad: float) -> tuple:
        """Kernel arguments (mg, mp) for the reflection about the axis ``theta`` (from +y_cam towards +x_cam)."""
        p = self.params.copy()
        p[4] = math.sin(theta_rad)
        p[5] = math.cos(theta_rad)
        return self.grid, p


def _usable_grid(view, camera: CameraModel):
    """(usable (ny, nx) bool, x0, dx, y0, dy) of the view's pixels on a regular grid: the view's own grid,
    or a pixel list scattered onto the grid of its smallest coordinate steps (cells without a pixel are
    unusable)."""
    fin = np.isfinite(view.aop) & np.isfinite(view.dop) & np.isfinite(view.rays).all(axis=0)
    usable = np.asarray(view.valid, dtype=bool) & fin
    if view.grid is not None:
        (x0, dx, nx), (y0, dy, ny) = view.grid
        return usable.reshape(ny, nx), x0, dx, y0, dy
    x = np.asarray(view.x_px, dtype=float)
    y = np.asarray(view.y_px, dtype=float)

    def axis(c):
        u = np.unique(c)
        lo, hi = float(u[0]), float(u[-1])
        gaps = np.diff(u)
        step = float(gaps[gaps > 1e-6].min()) if (gaps > 1e-6).any() else 1.0
        step = max(step, (hi - lo) / 2047.0)          # at most 2048 cells a side
        return lo, step, int(round((hi - lo) / step)) + 1

    x0, dx, nx = axis(x)
    y0, dy, ny = axis(y)
    grid = np.zeros((ny, nx), dtype=bool)
    col = np.clip(np.rint((x - x0) / dx).astype(np.int64), 0, nx - 1)
    row = np.clip(np.rint((y - y0) / dy).astype(np.int64), 0, ny - 1)
    grid[row[usable], col[usable]] = True
    return grid, x0, dx, y0, dy


@lru_cache(maxsize=16)
def _outside_disc(camera: CameraModel, x0: float, dx: float, nx: int, y0: float, dy: float, ny: int,
                  rho_max: float) -> np.ndarray:
    """Grid positions (x0 + c dx, y0 + r dy) beyond the disc's edge on the sensor (read-only bool (ny, nx))."""
    r_mm = np.hypot(((x0 + dx * np.arange(nx) - camera.cx_px) * camera.pixel_pitch_x_um * 1e-3)[None, :],
                    ((y0 + dy * np.arange(ny) - camera.cy_px) * camera.pixel_pitch_y_um * 1e-3)[:, None])
    out = r_mm > disc_radius_mm(camera, rho_max)
    out.setflags(write=False)
    return out


def mirror_map(view, camera: CameraModel, rho_max: float) -> MirrorMap:
    """The smooth usability map S of a view (see the module doc). Outside the view, positions beyond the disc
    count as usable (nothing is missing there) and positions inside it as unusable."""
    usable, x0, dx, y0, dy = _usable_grid(view, camera)
    ny, nx = usable.shape
    S, params = _smooth_usability(camera, float(x0), float(dx), float(y0), float(dy), int(ny), int(nx),
                                  float(rho_max), np.packbits(usable).tobytes())
    return MirrorMap(S, params, (float(x0), float(dx), float(y0), float(dy)), camera)


@lru_cache(maxsize=2)          # the last frame's, for both disc methods (a full-resolution S is tens of MB)
def _smooth_usability(camera: CameraModel, x0: float, dx: float, y0: float, dy: float, ny: int, nx: int,
                      rho_max: float, usable_bits: bytes):
    """(S, reflection parameters) of :func:`mirror_map` for a usable grid (packed bits): read-only, cached, so
    the two disc methods run on one frame (an error-map cell) blur it once."""
    usable = np.unpackbits(np.frombuffer(usable_bits, np.uint8), count=ny * nx).reshape(ny, nx).astype(bool)
    px, py = camera.pixel_pitch_x_um * 1e-3, camera.pixel_pitch_y_um * 1e-3
    pad = int(math.ceil(3.0 * MIRROR_BLUR_CELLS)) + 1
    full = _outside_disc(camera, x0 - pad * dx, dx, nx + 2 * pad, y0 - pad * dy, dy, ny + 2 * pad,
                         float(rho_max)).copy()
    full[pad:pad + ny, pad:pad + nx] = usable
    import cv2
    cell = math.sqrt(dx * px * dy * py)
    blur = cv2.GaussianBlur(full.astype(np.float32), (0, 0), sigmaX=MIRROR_BLUR_CELLS * cell / (dx * px),
                            sigmaY=MIRROR_BLUR_CELLS * cell / (dy * py), borderType=cv2.BORDER_REPLICATE)
    t = np.clip((blur.astype(np.float64) - MIRROR_LEVELS[0]) / (MIRROR_LEVELS[1] - MIRROR_LEVELS[0]), 0.0, 1.0)
    S = (t >= 1.0).astype(np.float64)                 # sin^2 of the rise: 0 below it, 1 above, sin only on it
    rise = (t > 0.0) & (t < 1.0)
    S[rise] = np.sin(0.5 * math.pi * t[rise]) ** 2
    S *= full                                         # exactly 0 on every unusable grid point
    params = np.array([camera.cx_px, camera.cy_px, px, py, 0.0, 0.0, x0 - pad * dx, dx, y0 - pad * dy, dy])
    for a in (S, params):
        a.setflags(write=False)
    return S, params


@lru_cache(maxsize=32)
def disc_cells(camera: CameraModel, x0: float, dx: float, y0: float, dy: float, rho_lo: float, rho_max: float,
               taper_frac: float) -> float:
    """Sum of the taper over the points of the lattice (x0 + k dx, y0 + l dy), extended over the whole image,
    whose ray lies in the disc ring [rho_lo, rho_max]: the denominator of the mirror coverage (a view that
    does not cover the disc counts what it misses)."""
    xs = x0 + dx * np.arange(math.ceil((1 - x0) / dx), math.floor((camera.width_px - x0) / dx) + 1)
    ys = y0 + dy * np.arange(math.ceil((1 - y0) / dy), math.floor((camera.height_px - y0) / dy) + 1)
    X, Y = np.meshgrid(xs, ys)
    r, ok = camera.rays_from_pixels(X.reshape(-1), Y.reshape(-1))
    rho = np.hypot(r[0], r[1])
    inr = ok & (rho >= rho_lo) & (rho <= rho_max) & (rho > 0.0)
    return float(taper(rho[inr], rho_max, taper_frac).sum())


@lru_cache(maxsize=64)
def _grid_covers_disc(camera: CameraModel, grid: tuple, rho_max: float) -> bool:
    (x0, dx, nx), (y0, dy, ny) = grid
    rr = disc_radius_mm(camera, rho_max)
    hx = rr / (camera.pixel_pitch_x_um * 1e-3)
    hy = rr / (camera.pixel_pitch_y_um * 1e-3)
    # the outermost grid lines lie within one grid step of the disc's edge or beyond it
    return (x0 <= camera.cx_px - hx + dx and x0 + dx * (nx - 1) >= camera.cx_px + hx - dx
            and y0 <= camera.cy_px - hy + dy and y0 + dy * (ny - 1) >= camera.cy_px + hy - dy)


def view_covers_disc(view, camera: CameraModel, rho_max: float) -> bool:
    """Whether a grid view reaches the disc's edge on every side (pixel lists: only their holes are seen)."""
    if view.grid is None:
        return True
    return _grid_covers_disc(camera, view.grid, float(rho_max))


@dataclass
class AxisFit:
    """One axis fit on (possibly mirror-weighted) pixels. ``theta`` rad from +y_cam towards +x_cam (axial)."""

    theta: float
    n: int                      # usable pixels
    n_paired: int               # usable pixels with a non-zero pair weight
    nonfinite: int
    holes: int                  # unusable pixels inside the disc
    coverage: float             # sum taper * m over valid pixels / sum taper over the disc
    stats: np.ndarray
    quality: float
    state: dict                 # method specific (for the influence pass)


def _fold(a: float) -> float:
    """Axial angle (rad) to [-pi/2, pi/2)."""
    return (a + 0.5 * math.pi) % math.pi - 0.5 * math.pi


def _refine(fit_at, t0: float, slope: float, tol_rad: float, max_steps: int):
    """Secant iteration on h(t) = fold(fit_at(t).theta - t) from t0 with a first slope estimate. Returns
    (fit at the fixed point or None, the last secant slope, its step length, fits used)."""
    steps = 0

    def h(x):
        nonlocal steps
        steps += 1
        f = fit_at(x)
        return (None, None) if f is None else (_fold(f.theta - x), f)

    hb, fb = h(t0)
    tb, ta = t0, t0
    while fb is not None and abs(hb) > tol_rad and steps < max_steps:
        step = max(-0.2, min(0.2, -hb / slope))
        ta, ha = tb, hb
        tb = tb + step
        hb, fb = h(tb)
        if fb is not None and tb != ta and abs((hb - ha) / (tb - ta)) > MIN_CONDITIONING:
            slope = (hb - ha) / (tb - ta)
    if fb is None or abs(hb) > tol_rad:
        return None, slope, 0.0, steps
    fb.theta = tb + hb
    return fb, slope, abs(tb - ta), steps


def solve_axes(fit_at, scan_at, keep, min_coverage: float, n_scan: int = SCAN_AXES, tol_rad: float = 1e-8,
               max_steps: int = MAX_SOLVE_STEPS):
    """Every self-consistent axis ``theta = fit_at(theta).theta`` (axial, rad) worth keeping.

    ``h(theta) = fold(f(theta) - theta)`` is scanned on ``n_scan`` axes with ``scan_at`` (a cheaper fit on a
    subsample); each interval where h changes sign (either way: the true axis may repel a plain iteration,
    f' > 1; a jump of h across the fold is not a root) and whose mirror coverage reaches ``min_coverage / 2``
    at an end (not the degenerate fixed point on an occluder's edge, where the pairs shrink to a sliver) is
    refined by the secant method, first with ``scan_at`` to 1e-4 rad; roots that ``keep(fit)`` accepts are
    then refined with ``fit_at`` to ``tol_rad``. ``h'`` (= f' - 1) is the last secant slope, or a finite
    difference over 2e-3 rad when the last step was too short. Returns (list of (fit, h'), reasons why no
    root was found, fits used)."""
    dt = math.pi / n_scan
    fs = [scan_at(i * dt) for i in range(n_scan)]
    hs = [None if f is None else _fold(f.theta - i * dt) for i, f in enumerate(fs)]
    used = n_scan
    coarse, failed = [], []
    dropped = -1.0
    best = max([f.coverage for f in fs if f is not None], default=0.0)
    if best < 0.5 * min_coverage:
        failed.append(f"at most {best:.3f} of the disc has a usable mirror image about any axis "
                      f"(min_mirror_coverage {min_coverage:g})")
    for i in range(n_scan):
        j = (i + 1) % n_scan
        h0, h1 = hs[i], hs[j]
        if h0 is None or h1 is None or (h0 < 0.0) == (h1 < 0.0) or abs(h0 - h1) > MAX_BRACKET_JUMP:
            continue
        if max(fs[i].coverage, fs[j].coverage) < 0.5 * min_coverage:
            dropped = max(dropped, fs[i].coverage, fs[j].coverage)
            continue
        fit, slope, _, n = _refine(scan_at, i * dt + dt * h0 / (h0 - h1), (h1 - h0) / dt, 1e-4, max_steps)
        used += n
        if fit is not None and not keep(fit):
            dropped = max(dropped, fit.coverage)
        elif fit is not None and all(abs(_fold(fit.theta - c[0].theta)) > 1e-3 for c in coarse):
            coarse.append((fit, slope))
    roots = []
    for fc, slope in coarse:
        fit, slope, last, n = _refine(fit_at, fc.theta, slope, tol_rad, max_steps)
        used += n
        if fit is None:
            failed.append(f"no self-consistent axis near {math.degrees(fc.theta) % 180:.1f} deg at full resolution")
            continue
        if not last >= 1e-6:                 # the last secant step is too short for a derivative
            fd = fit_at(fit.theta + 2e-3)
            used += 1
            if fd is None:
                continue
            slope = _fold(fd.theta - fit.theta - 2e-3) / 2e-3
        roots.append((fit, slope))
    if not roots and not failed and dropped >= 0.0:
        failed.append(f"the self-consistent axes have at most {dropped:.3f} of the disc with a usable mirror image "
                      f"or are not symmetric (min_mirror_coverage {min_coverage:g})")
    return roots, failed, used


# --------------------------------------------------------------------------------------------
# The estimator skeleton shared by SM-ASM and Symmetry
# --------------------------------------------------------------------------------------------
class DiscEstimator(KnobbedEstimator, Estimator):
    """An axis of mirror symmetry through the zenith pixel, fitted on the sky disc (level camera).

    Subclasses implement :meth:`_fit` (pass 1 and the plain axis), :meth:`_gather` and :meth:`_mirror_fit`
    (the axis on mirror-pair weights about a trial axis ``near``; None when there is no fit) and
    :meth:`_influence` (pass 2: block sums of the sensitivity times the residual against each candidate
    sun, and the residual sums of squares)."""

    axial = True
    KNOB_DEFAULTS = {"stride": 8, "min_dop": 0.02}

    def __init__(self, **knobs):
        super().__init__(**knobs)
        self.knobs = self._validate_knobs(knobs)

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        k = self.knobs
        if k["region"] is not None:
            return selection_for(k, camera)
        return disc_selection(camera, k["disc_fraction"], k["stride"])

    def _rho_lo(self, rho_max: float) -> float:
        return 0.0

    def _fit(self, data, rho_lo, rho_max) -> AxisFit | HeadingResult:  # pragma: no cover - interface
        raise NotImplementedError

    def _gather(self, data, rho_lo, rho_max, mm: MirrorMap) -> dict:  # pragma: no cover - interface
        raise NotImplementedError

    def _mirror_fit(self, g: dict, mirror, near: float, plain: AxisFit) -> AxisFit | None:  # pragma: no cover
        raise NotImplementedError

    def _influence(self, data, segs, rho_lo, rho_max, mirror, fit: AxisFit, s1, s2):  # pragma: no cover
        raise NotImplementedError

    def _plain_fit(self, cnt, stats, theta: float, quality: float, state: dict) -> AxisFit:
        n = int(cnt[0])
        return AxisFit(theta, n, n, int(cnt[2]), int(cnt[3]), 1.0, stats, quality, state)

    def _too_few(self, n: int) -> HeadingResult | None:
        if n < self.knobs["min_pixels"]:
            return HeadingResult.failed(self.name, Status.TOO_FEW_PIXELS,
                                        f"{n} usable pixel(s) in the sky disc < min_pixels {self.knobs['min_pixels']}",
                                        pixels=n)
        return None

    def _root_ok(self, fit: AxisFit, lenient: bool = False) -> bool:
        """Whether a self-consistent axis is acceptable beyond coverage and conditioning (default: yes);
        ``lenient`` for a fit on the scan's subsample."""
        return True

    def _root_why(self, fit: AxisFit) -> str:  # pragma: no cover - only with a _root_ok that can say no
        return ""

    def _level_ms(self, data, rho_lo, rho_max, theta, obs, step=RESIDUAL_STEP) -> float:
        """Mean square AoP residual (rad^2) against the level Rayleigh pattern of axis theta (its better end),
        over every ``step``-th usable pixel."""
        s1, s2 = level_sun_candidates(-theta, float(obs.sun_altitude_deg))
        rss = np.zeros(3)
        level_rss(data[0], data[1], data[2], data[3], self.knobs["min_dop"], rho_lo, rho_max, s1.sun_cam, s2.sun_cam,
                  step, rss)
        return float(min(rss[0], rss[1]) / max(rss[2], 1.0))

    def _solve_mirror(self, obs, view, data, rho_lo, rho_max, plain: AxisFit, extras: dict):
        """The axis on mirror-pair weights: (fit, mirror arguments, sigma inflation) or a failed result."""
        k = self.knobs
        mm = mirror_map(view, obs.camera, rho_max)
        g = self._gather(data, rho_lo, rho_max, mm)
        gate = k["min_mirror_coverage"]

        def fit_at(theta, step=1):
            f = self._mirror_fit(g, mm.at(theta), theta, plain, step)
            return f if f is not None and f.n_paired * step >= k["min_pixels"] else None

        f0 = fit_at(plain.theta)
        if f0 is not None and f0.coverage >= 0.5 and self._root_ok(f0) \
                and abs(_fold(f0.theta - plain.theta)) <= math.radians(MIRROR_AGREEMENT_DEG):
            extras["mirror_coverage"] = f0.coverage      # the unusable pixels do not bias the plain fit
            return [(plain, NO_MIRROR, 1.0)]
        roots, failed, used = solve_axes(fit_at, lambda t: fit_at(t, SCAN_STEP),
                                         lambda f: f.coverage >= 0.8 * gate and self._root_ok(f, lenient=True), gate)
        extras["mirror_fits"] = used + 1
        why = f"part of the sky disc is unusable ({plain.holes} pixel(s)"
        why += ")" if view_covers_disc(view, obs.camera, rho_max) else " and the view does not cover the disc)"
        good = [(f, sl) for f, sl in roots if f.coverage >= gate and abs(sl) >= MIN_CONDITIONING]
        sound = [(f, sl) for f, sl in good if self._root_ok(f)]
        if good and not sound:
            f, sl = max(good, key=lambda r: r[0].quality)
            extras["mirror_coverage"] = f.coverage
            return HeadingResult.failed(self.name, Status.INSUFFICIENT_COVERAGE,
                                        f"{why}: no axis about which the usable mirror pairs are symmetric "
                                        f"({self._root_why(f)})", pixels=plain.n, **extras)
        if not sound:
            if roots:
                f, sl = max(roots, key=lambda r: r[0].coverage)
                detail = (f"only {f.coverage:.3f} of the disc has a usable mirror image about the best axis "
                          f"(min_mirror_coverage {gate:g}; |1 - f'| = {abs(sl):.2g})")
                extras["mirror_coverage"] = f.coverage
            else:
                detail = failed[0] if failed else "no self-consistent axis"
            return HeadingResult.failed(self.name, Status.INSUFFICIENT_COVERAGE, f"{why}: {detail}",
                                        pixels=plain.n, **extras)
        extras["mirror_axes"] = len(sound)
        return [(f, mm.at(f.theta), 1.0 / abs(sl)) for f, sl in sound]

    def estimate(self, obs: Observation, sigma: bool = True) -> HeadingResult:
        """``sigma=False`` skips pass 2 (the influence kernel: the uncertainty and the residuals against the
        two ends of the meridian): ``sigma_deg`` is None, ``extras`` has no ``rms_residual_deg``, and an
        unresolved (axial) result names the end ``psi = -theta`` rather than the one the Rayleigh residuals
        prefer. On the mirror-pair path with re-fitted axes, whose acceptance test needs the residuals, pass 2
        runs anyway (and ``rms_residual_deg`` is reported)."""
        k = self.knobs
        bad = check_sun(self.name, obs, k)
        if bad is not None:
            return bad
        rho_max = disc_radius(obs.camera) * k["disc_fraction"]
        rho_lo = self._rho_lo(rho_max)
        try:
            view = select_view(obs, k)
        except _BadInput as exc:
            return HeadingResult.failed(self.name, Status.BAD_INPUT, str(exc))
        data, segs = view_segments(view, k["block_px"])
        fit = plain = self._fit(data, rho_lo, rho_max)
        if isinstance(fit, HeadingResult):
            return fit
        extras: dict = {}
        candidates = [(fit, NO_MIRROR, 1.0)]
        if fit.holes > 0 or not view_covers_disc(view, obs.camera, rho_max):
            candidates = self._solve_mirror(obs, view, data, rho_lo, rho_max, fit, extras)
            if isinstance(candidates, HeadingResult):
                return candidates
        if len(candidates) > 1:                     # several self-consistent axes: the best Rayleigh fit
            candidates = [min(candidates, key=lambda c: self._level_ms(data, rho_lo, rho_max, c[0].theta, obs))]
        fit, mirror, inflation = candidates[0]
        first, second = level_sun_candidates(-fit.theta, float(obs.sun_altitude_deg))
        j, rms_deg = 0, None
        if sigma or "mirror_axes" in extras:
            block_sum, rss = self._influence(data, segs, rho_lo, rho_max, mirror, fit, first.sun_cam,
                                             second.sun_cam)
            j = int(np.argmin(rss))                 # the end of the meridian the Rayleigh residuals prefer
            rms_deg = math.degrees(math.sqrt(rss[j] / fit.n))
        if "mirror_axes" in extras:
            extras["mirror_coverage"] = fit.coverage
            extras["mirror_sigma_inflation"] = inflation
            limit = MAX_MIRROR_RESIDUAL_RATIO * math.degrees(math.sqrt(
                self._level_ms(data, rho_lo, rho_max, plain.theta, obs))) + 0.01
            if rms_deg > limit:
                return HeadingResult.failed(
                    self.name, Status.INSUFFICIENT_COVERAGE,
                    f"part of the sky disc is unusable ({fit.holes} pixel(s)): the self-consistent axes on the "
                    f"usable mirror pairs miss the level Rayleigh pattern by {rms_deg:.2g} deg rms or more "
                    f"(> {limit:.2g}, {MAX_MIRROR_RESIDUAL_RATIO:g} x the plain fit's + 0.01): none is the solar "
                    "meridian", pixels=fit.n, **extras)
        n = fit.n_paired
        sigma_deg = finish_sigma_deg(cr1_sigma(block_sum[j], n) * inflation, k) if sigma else None
        if j == 1:
            first, second = second, first
        has_i = data[6] is not None
        bt = brightness_t_from_stats(fit.stats if has_i else None, first.sun_cam - second.sun_cam)
        pick, by, reason = resolve_ambiguity(self.name, first, second, bt, obs, k)
        extras.update(fit.state.get("extras", {}))
        if rms_deg is not None:
            extras["rms_residual_deg"] = rms_deg
        return result_from(self.name, Candidate(pick.psi_rad, pick.sun_cam), by, reason, obs,
                           sigma_deg, n, fit.nonfinite, fit.quality, extras=extras)
