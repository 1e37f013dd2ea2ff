"""What SM-ASM and Symmetry share: the AoP relative to the local meridian (eqs 29-30) on a disc of
sky centred on the zenith pixel, with a smooth radial taper.

``xi`` (eq 30, the angle between +y_cam and the local meridian at a pixel) is computed from the pixel's
ray, ``xi = atan2(r_x, r_y)``: for the paper's pinhole with square pixels this is eq 30 exactly
(``atan2(x - cx, y - cy)``, tested), and it stays right for a fisheye or non-square pixels. Both methods
assume a level camera (the paper's premise); under tilt they show the paper's tilt errors.

Why a disc with a smooth edge: both methods find an axis of mirror symmetry of the AOPLM pattern. The
image rectangle is not mirror-symmetric about an arbitrary line through its centre, so its corners
would bias the axis; a disc is symmetric about every such line, and a taper that goes smoothly to zero
keeps the pixel lattice from aliasing at the edge.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from ..camera import CameraModel, PixelSelection
from ._common import Knob, axial_residual_rad, level_sun_candidates, rayleigh_aop_rad

__all__ = ["DISC_KNOBS", "disc_radius", "disc_selection", "taper", "aoplm_rad", "level_residual", "band_pass1",
           "band_pass2", "ring_pass1", "ring_pass2", "cr1_sigma"]

DISC_KNOBS = {
    "disc_fraction": Knob(1.0, "float", 0.05, 1.0,
                          doc="radius of the sky disc used, as a fraction of the largest disc inside the image"),
    "taper_fraction": Knob(0.2, "float", 0.0, 1.0, doc="outer part of the disc over which weights fall to zero"),
}


@lru_cache(maxsize=32)
def disc_radius(camera: CameraModel) -> float:
    """hypot(r_x, r_y) of the largest ray circle about the optical axis inside the image."""
    cx, cy = camera.cx_px, camera.cy_px
    xs = np.array([1.0, float(camera.width_px), cx, cx])
    ys = np.array([cy, cy, 1.0, float(camera.height_px)])
    r, ok = camera.rays_from_pixels(xs, ys)
    rho = np.hypot(r[0], r[1])
    return float(rho[ok].min()) if ok.any() else 1.0


def disc_selection(camera: CameraModel, fraction: float, stride: int) -> PixelSelection:
    """The square of sensor pixels holding the disc (and the stride)."""
    rho_max = disc_radius(camera) * fraction
    f = camera.focal_length_mm
    if camera.model == "pinhole":
        rr = f * math.tan(math.asin(min(rho_max, 1.0)))
    else:
        rr = f * math.asin(min(rho_max, 1.0))
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
# --------------------------------------------------------------------------------------------
@njit(inline="always", cache=True)
def _sincos64(a):  # pragma: no cover - compiled
    """sin, cos of a folded to [-pi/2, pi/2] (sign flip harmless for axial angles): Taylor, err < 1e-11."""
    a = a - math.pi * np.rint(a * (1.0 / math.pi))
    z = a * a
    s = 1.0 / 1307674368000.0
    s = s * -z + 1.0 / 6227020800.0
    s = s * -z + 1.0 / 39916800.0
    s = s * -z + 1.0 / 362880.0
    s = s * -z + 1.0 / 5040.0
    s = s * -z + 1.0 / 120.0
    s = s * -z + 1.0 / 6.0
    s = a * (1.0 - z * s)
    c = 1.0 / 20922789888000.0
    c = c * -z + 1.0 / 87178291200.0
    c = c * -z + 1.0 / 479001600.0
    c = c * -z + 1.0 / 3628800.0
    c = c * -z + 1.0 / 40320.0
    c = c * -z + 1.0 / 720.0
    c = c * -z + 1.0 / 24.0
    c = c * -z + 0.5
    c = 1.0 - z * c
    return s, c


@njit(inline="always", cache=True)
def _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_hi):  # pragma: no cover - compiled
    """Load pixel i: (usable, finite-but-masked flag, a, p, rx, ry, rz, rho, cos 2a, sin 2a)."""
    a = np.float64(aop[i])
    p = np.float64(dop[i])
    rx = np.float64(rays[0, i])
    ry = np.float64(rays[1, i])
    rz = np.float64(rays[2, i])
    fin = (abs(a) < 1e6) and (abs(p) < 1e6) and (abs(rx) < 1e6) and (abs(ry) < 1e6) and (abs(rz) < 1e6)
    rho = math.sqrt(rx * rx + ry * ry) if fin else 0.0
    ok = valid[i] and fin and p >= min_dop and rho >= rho_lo and rho <= rho_hi and rho > 0.0
    sa, ca = _sincos64(a if fin else 0.0)
    return ok, fin, a, p, rx, ry, rz, rho, ca * ca - sa * sa, 2.0 * sa * ca


@njit(inline="always", cache=True)
def _taper1(rho, rho_max, frac):  # pragma: no cover - compiled
    if frac <= 0.0:
        return 1.0 if rho <= rho_max else 0.0
    t = (rho / rho_max - (1.0 - frac)) / frac
    if t <= 0.0:
        return 1.0
    if t >= 1.0:
        return 0.0
    c = math.cos(0.5 * math.pi * t)
    return c * c


@njit(inline="always", cache=True)
def _level_resid(c2a, s2a, rx, ry, rz, s):  # pragma: no cover - compiled
    """AoP residual (rad, axial) against the Rayleigh E-vector s x r: 0.5 arg(exp(2ia) conj(u)^2), u = ey + i ex."""
    ex = s[1] * rz - s[2] * ry
    ey = s[2] * rx - s[0] * rz
    ur = ey * ey - ex * ex               # u^2 = (ey + i ex)^2
    ui = 2.0 * ex * ey
    qr = c2a * ur + s2a * ui             # exp(2ia) * conj(u^2)
    qi = s2a * ur - c2a * ui
    return 0.5 * math.atan2(qi, qr)


@njit(cache=True)
def _counts_stats(ok, fin, v, I, rx, ry, rz, has_i, cnt, stats):  # pragma: no cover - compiled
    cnt[1] += 1 if v else 0
    cnt[2] += 1 if (v and not fin) else 0
    if ok:
        cnt[0] += 1
        if has_i and abs(I) < 1e30:
            stats[0] += 1.0
            stats[1] += I
            stats[2] += I * I
            stats[3] += rx
            stats[4] += ry
            stats[5] += rz
            stats[6] += I * rx
            stats[7] += I * ry
            stats[8] += I * rz
            stats[9] += rx * rx
            stats[10] += rx * ry
            stats[11] += rx * rz
            stats[12] += ry * ry
            stats[13] += ry * rz
            stats[14] += rz * rz


@njit(cache=True)
def band_pass1(aop, dop, valid, rays, inten, has_i, min_dop, rho_max, taper_frac, inv4tol2, out, cnt, stats):  # pragma: no cover
    """SM-ASM: out = (Re Z, Im Z, sum W rho^2) with Z = sum W z^2, W = exp((cos 2 delta - 1) / (4 tol^2))
    DoP^2 taper; cnt = (usable, valid, valid non-finite)."""
    for i in range(aop.size):
        ok, fin, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, 0.0, rho_max)
        _counts_stats(ok, fin, valid[i], np.float64(inten[i]) if has_i else 0.0, rx, ry, rz, has_i, cnt, stats)
        if not ok:
            continue
        er = ry / rho
        ei = -rx / rho
        x2r = er * er - ei * ei
        x2i = 2.0 * er * ei
        cr = c2a * x2r - s2a * x2i                 # exp(2i AOPLM)
        W = math.exp((-cr - 1.0) * inv4tol2) * p * p * _taper1(rho, rho_max, taper_frac)   # cos 2 delta = -cr
        out[0] += W * (ry * ry - rx * rx)
        out[1] += W * 2.0 * rx * ry
        out[2] += W * rho * rho


@njit(cache=True)
def band_pass2(aop, dop, valid, rays, seg_start, seg_end, seg_block, min_dop, rho_max, taper_frac, inv4tol2,
               Zr, Zi, s1, s2, block_sum, rss):  # pragma: no cover - compiled
    """SM-ASM influence: block_sum[j, b] += (d theta / d a_i) * residual_j(i) for the two candidate suns;
    rss[j] += residual_j^2."""
    modZ2 = Zr * Zr + Zi * Zi
    for k in range(seg_start.size):
        bk = seg_block[k]
        for i in range(seg_start[k], seg_end[k]):
            ok, fin, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, 0.0, rho_max)
            if not ok:
                continue
            er = ry / rho
            ei = -rx / rho
            x2r = er * er - ei * ei
            x2i = 2.0 * er * ei
            cr = c2a * x2r - s2a * x2i
            ci = c2a * x2i + s2a * x2r
            W = math.exp((-cr - 1.0) * inv4tol2) * p * p * _taper1(rho, rho_max, taper_frac)
            dW = W * ci * 2.0 * inv4tol2             # dW/da: d(cos 2 delta)/da = -2 sin 2 delta = 2 ci
            z2r = ry * ry - rx * rx
            z2i = 2.0 * rx * ry
            sens = 0.5 * dW * (z2i * Zr - z2r * Zi) / modZ2
            r1 = _level_resid(c2a, s2a, rx, ry, rz, s1)
            r2 = _level_resid(c2a, s2a, rx, ry, rz, s2)
            block_sum[0, bk] += sens * r1
            block_sum[1, bk] += sens * r2
            rss[0] += r1 * r1
            rss[1] += r2 * r2


@njit(cache=True)
def ring_pass1(aop, dop, valid, rays, inten, has_i, min_dop, rho_lo, rho_max, taper_frac, n_rings, K,
               a_out, cnt, stats):  # pragma: no cover - compiled
    """Symmetry: a_out[k + K, ring] += hat * w * c * exp(-i k phi), k = -K..K, c = exp(2i AOPLM),
    w = DoP^2 taper, linear split between neighbouring rings."""
    span = max(rho_max - rho_lo, 1e-12)
    for i in range(aop.size):
        ok, fin, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_max)
        _counts_stats(ok, fin, valid[i], np.float64(inten[i]) if has_i else 0.0, rx, ry, rz, has_i, cnt, stats)
        if not ok:
            continue
        e = complex(ry / rho, -rx / rho)
        c = complex(c2a, s2a) * e * e * (p * p * _taper1(rho, rho_max, taper_frac))
        t = min(max((rho - rho_lo) / span, 0.0), 1.0) * (n_rings - 1)
        j = min(int(math.floor(t)), n_rings - 1)
        f = t - j
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


@njit(cache=True)
def ring_pass2(aop, dop, valid, rays, seg_start, seg_end, seg_block, min_dop, rho_lo, rho_max, taper_frac,
               n_rings, K, a_in, rot, F2, s1, s2, block_sum, rss):  # pragma: no cover - compiled
    """Symmetry influence: d theta / d a_i = -(d F'/d a_i) / F'' with
    d F'/d a_i = Re sum_k (-8k) e^{2ik theta} w_i c_i e_i^k A_k(i) (A_k: a_k interpolated at the pixel's
    ring), times the residual against each candidate sun."""
    span = max(rho_max - rho_lo, 1e-12)
    for k in range(seg_start.size):
        bk = seg_block[k]
        for i in range(seg_start[k], seg_end[k]):
            ok, fin, a, p, rx, ry, rz, rho, c2a, s2a = _pixel(aop, dop, valid, rays, i, min_dop, rho_lo, rho_max)
            if not ok:
                continue
            e = complex(ry / rho, -rx / rho)
            c = complex(c2a, s2a) * e * e * (p * p * _taper1(rho, rho_max, taper_frac))
            t = min(max((rho - rho_lo) / span, 0.0), 1.0) * (n_rings - 1)
            j = min(int(math.floor(t)), n_rings - 1)
            f = t - j
            ep = c
            em = c
            ec = e.conjugate()
            acc = 0.0
            for kk in range(1, K + 1):
                ep = ep * e
                em = em * ec
                Ap = (1.0 - f) * a_in[K + kk, j]
                Am = (1.0 - f) * a_in[K - kk, j]
                if j + 1 < n_rings:
                    Ap += f * a_in[K + kk, j + 1]
                    Am += f * a_in[K - kk, j + 1]
                acc += (-8.0 * kk) * (rot[K + kk] * ep * Ap).real
                acc += (8.0 * kk) * (rot[K - kk] * em * Am).real
            sens = -acc / F2
            r1 = _level_resid(c2a, s2a, rx, ry, rz, s1)
            r2 = _level_resid(c2a, s2a, rx, ry, rz, s2)
            block_sum[0, bk] += sens * r1
            block_sum[1, bk] += sens * r2
            rss[0] += r1 * r1
            rss[1] += r2 * r2


def cr1_sigma(block_sum, n: int) -> float:
    """Cluster-robust sigma from block sums of the influence (CR1 small-sample factor, one parameter)."""
    b = np.asarray(block_sum, dtype=float)
    b = b[b != 0.0]
    G = b.size
    if G == 0:
        return 0.0
    corr = (G / (G - 1.0) if G > 1 else 1.0) * ((n - 1.0) / (n - 1.0 - 1.0) if n > 2 else 1.0)
    return math.sqrt(float(np.dot(b, b)) * corr)
