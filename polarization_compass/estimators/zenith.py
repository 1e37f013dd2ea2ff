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
The zenith approach: the E-vector at the zenith is perpendicular to the solar meridian.

Classically ``psi = 90 deg - AoP(zenith)`` (mod 180 deg; for a level camera the zenith E-vector is
``s x z``, whose eq 28 angle is ``90 deg - psi``), with the AoP averaged axially over a window at
the image centre. The axial mean over a window of finite size is biased at second order in the
window's angular size (0.005 deg for 32 px, 0.16 deg for 64 px with a high sun), so this
implementation does the same thing exactly:

1. lift every window pixel's AoP to its 3-D E-vector ``e_i`` (perpendicular to its ray);
2. the dominant eigenvector ``u`` of ``sum e_i e_i^T`` is the window's E-vector axis: for a window
   shrinking to the zenith it is the zenith E-vector, and for any window the Rayleigh sun is
   perpendicular to it (every ``e_i`` is perpendicular to the sun);
3. under the level-camera assumption the sun lies on the cone of elevation ``h`` (the ephemeris
   altitude, which every compass needs anyway for the sun's azimuth): the two intersections of the
   plane ``u . s = 0`` with that cone are ``psi`` and (nearly) ``psi + 180 deg``; the one that fits
   the window's E-vectors better (smaller ``s^T M s``) is kept -- exact without noise.

Note on a hint we were given ("each pixel's lifted E-vector and ray give the solar meridian plane
normal, exactly under a level camera"): only at the zenith pixel. Off the zenith, ``e_i`` is the
normal of the plane through the pixel's ray and the sun, not of the meridian plane; one pixel alone
fixes the meridian only together with the sun's altitude. Step 3 is where the altitude enters.

The result is axial (the zenith E-vector does not say which end of the meridian holds the sun)
unless the whole sky (a sparse grid of pixels over the sensor: the AoP pattern at the sun's
altitude and the half-sky brightness, :func:`polarization_compass.skyfit_assess.side_votes`) or a
prior bearing resolves it -- never the window's own brightness gradient, which lens-flare ghosts
opposite the sun can dominate (a real frame gave 177 deg error that way). Uncertainty: to first
order ``d psi = -sum_i w_i da_i / sum w``; ``da_i`` is the residual against the Rayleigh AoP of the
fitted sun; cluster-robust over blocks of ``block_px`` (default 4 sensor pixels: the window is
small).

Speed: one compiled pass over the window (:func:`_window_sums`) masks the pixels and accumulates
``M``, the counts, the axial resultant and the brightness statistics without copying; the per-pixel
residuals of the uncertainty are computed only when it is asked for (``estimate(obs, sigma=False)``
skips them: error-map sweeps).
"""

from __future__ import annotations

from functools import lru_cache
import math

from numba import njit
import numpy as np

from ._common import (
    axial_residual_rad,
    cluster_sigma_rad,
    finish_sigma_deg,
    level_sun_candidates,
    psi_from_sun_rad,
    rayleigh_aop_rad,
    resolve_ambiguity,
    result_from,
)
from ._kernels import acc_brightness, acc_sym, N_STATS
from ._knobs import Knob, KnobbedEstimator
from ._views import _BadInput, check_sun, samples_from_view, select_view
from .base import Estimator, HeadingResult, Observation, Status
from ..camera import CameraModel
from ..camera_pixels import PixelSelection

__all__ = ['ZenithEstimator', 'zenith_window']


@lru_cache(maxsize=32)
def zenith_window(camera: CameraModel, window_px: int):
    """
    Locate the zenith window: the square centred on the principal point.

    Under the level-camera assumption the zenith is the principal point (eq 20 with ``V = (0, 0,
    f)``).

    Parameters
    ----------
    camera : CameraModel
        The camera; the window is clipped to its sensor.
    window_px : int
        Side of the square window [sensor pixels].

    Returns
    -------
    bounds : tuple of int
        ``(x_lo, x_hi, y_lo, y_hi)``, 1-based eq 20 pixel coordinates of the pixel centres,
        inclusive.
    selection : PixelSelection
        The matching rectangle.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 20.

    """
    half = window_px / 2.0
    x_lo = math.ceil(camera.cx_px - half)
    y_lo = math.ceil(camera.cy_px - half)
    x_lo = max(1, x_lo)
    y_lo = max(1, y_lo)
    x_hi = min(int(camera.width_px), x_lo + window_px - 1)
    y_hi = min(int(camera.height_px), y_lo + window_px - 1)
    sel = PixelSelection.rect(x_lo, y_lo, x_hi - x_lo + 1, y_hi - y_lo + 1)
    return (x_lo, x_hi, y_lo, y_hi), sel


@njit(cache=True, nogil=True)
def _window_sums(
    aop, dop, valid, rays, inten, has_i, min_dop, m, cnt, trig, stats
):  # pragma: no cover - compiled
    """
    Accumulate the window's usable pixels into the lifted E-vector matrix.

    Usable: valid, every value finite, DoP >= min_dop (the mask of
    :func:`._views.samples_from_view`). m += upper triangle of sum e e^T of the unit lifted
    E-vectors (:func:`polarization_compass.conventions.evector_cam_from_aop`, float64), cnt =
    (usable, valid with a non-finite value, valid), trig += (sum cos 2a, sum sin 2a), brightness
    statistics into ``stats`` (``cnt[3]`` = 1 when a usable pixel's intensity is not finite: then
    there are none).
    """
    n = n_bad = n_valid = 0
    i_bad = 0
    for i in range(aop.size):
        if not valid[i]:
            continue
        n_valid += 1
        a = np.float64(aop[i])
        p = np.float64(dop[i])
        rx = np.float64(rays[0, i])
        ry = np.float64(rays[1, i])
        rz = np.float64(rays[2, i])
        if not (
            math.isfinite(a)
            and math.isfinite(p)
            and math.isfinite(rx)
            and math.isfinite(ry)
            and math.isfinite(rz)
        ):
            n_bad += 1
            continue
        if not p >= min_dop:
            continue
        n += 1
        sa = math.sin(a)
        ca = math.cos(a)
        ex = rz * sa
        ey = rz * ca
        ez = -(rx * sa + ry * ca)
        nn = max(math.sqrt(ex * ex + ey * ey + ez * ez), 2.2250738585072014e-308)
        ex /= nn
        ey /= nn
        ez /= nn
        acc_sym(m, 0, 1.0, ex, ey, ez)
        trig[0] += ca * ca - sa * sa  # cos 2a
        trig[1] += 2.0 * sa * ca  # sin 2a
        if has_i:
            ival = np.float64(inten[i])
            if math.isfinite(ival):
                acc_brightness(stats, 0, ival, rx, ry, rz)
            else:
                i_bad = 1
    cnt[0] = n
    cnt[1] = n_bad
    cnt[2] = n_valid
    cnt[3] = i_bad


@njit(cache=True, nogil=True)
def _eigh3(m):  # pragma: no cover - compiled
    """
    Return np.linalg.eigh (lam, U) of the symmetric 3x3 matrix with upper triangle m.

    ``m`` = (00 01 02 11 12 22). The same LAPACK routine as numpy's (the same bits here), without
    numpy's ~10 us of Python per call.
    """
    M = np.empty((3, 3))
    M[0, 0], M[0, 1], M[0, 2] = m[0], m[1], m[2]
    M[1, 0], M[1, 1], M[1, 2] = m[1], m[3], m[4]
    M[2, 0], M[2, 1], M[2, 2] = m[2], m[4], m[5]
    return np.linalg.eigh(M)


def side_grid_px(camera: CameraModel, n: int):
    """
    Return the 1-based pixel columns and rows (eq 20) of an n x n grid over the sensor.

    The same pixels as ``PixelSelection.grid(n, n)`` (centres of equal blocks, rounded), clipped to
    the sensor size; the zenith method decides its 180 deg side from them.

    Parameters
    ----------
    camera : CameraModel
        The camera (its sensor size [px]).
    n : int
        Grid size (>= 1) along each axis.

    Returns
    -------
    xs, ys : numpy.ndarray of int
        Columns and rows [sensor pixels, 1-based]; the grid is their outer product.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 20.

    """
    W, H = int(camera.width_px), int(camera.height_px)
    nx, ny = min(n, W), min(n, H)
    xs = np.rint(0.5 + (np.arange(nx) + 0.5) * W / nx).astype(np.int64)
    ys = np.rint(0.5 + (np.arange(ny) + 0.5) * H / ny).astype(np.int64)
    return xs, ys


@lru_cache(maxsize=64)
def _pixels_needed(camera: CameraModel, window_px: int, side_grid: int) -> PixelSelection:
    """Return the zenith window plus the whole-sky side grid as one pixel list (cached)."""
    (x_lo, x_hi, y_lo, y_hi), sel = zenith_window(camera, window_px)
    if side_grid <= 0:
        return sel
    wx, wy = np.meshgrid(np.arange(x_lo, x_hi + 1), np.arange(y_lo, y_hi + 1))
    gx, gy = np.meshgrid(*side_grid_px(camera, side_grid))
    outside = ~((gx >= x_lo) & (gx <= x_hi) & (gy >= y_lo) & (gy <= y_hi))
    return PixelSelection.explicit(
        np.concatenate([wx.ravel(), gx[outside]]), np.concatenate([wy.ravel(), gy[outside]])
    )


def _side_sample(obs: Observation, side_grid: int):
    """
    Return the observation's pixels nearest the side grid as a sky sample, or None.

    The whole-sky side grid is :func:`side_grid_px`; the sample a
    :class:`~polarization_compass.skyfit.SkySample`, None when fewer than 30 are usable.

    A 2-D observation is read at the nearest row and column to each grid pixel; a 1-D pixel list at
    the grid pixels it contains. Either way a frame and a sweep that renders
    :meth:`ZenithEstimator.pixels_needed` read the same pixels.
    """
    from ..skyfit import sample_sky

    gx, gy = side_grid_px(obs.camera, side_grid)
    aop = np.asarray(obs.aop_rad)
    if aop.ndim == 2:
        xa = np.asarray(obs.x_px, dtype=float)[0]
        ya = np.asarray(obs.y_px, dtype=float)[:, 0]
        ci = np.unique(np.clip(np.searchsorted(xa, gx), 0, xa.size - 1))
        ri = np.unique(np.clip(np.searchsorted(ya, gy), 0, ya.size - 1))
        ix = np.ix_(ri, ci)
        W = aop.shape[1]
        flat = (ri[:, None] * W + ci[None, :]).reshape(-1)
        pick = (
            aop[ix],
            np.asarray(obs.dop)[ix],
            np.asarray(obs.valid)[ix],
            np.asarray(obs.rays_cam).reshape(3, -1)[:, flat],
            None if obs.intensity is None else np.asarray(obs.intensity)[ix],
        )
    else:
        W = int(obs.camera.width_px) + 1
        key = np.rint(np.asarray(obs.y_px, dtype=float)).astype(np.int64) * W + np.rint(
            np.asarray(obs.x_px, dtype=float)
        ).astype(np.int64)
        want = (gy[:, None] * W + gx[None, :]).reshape(-1)
        sel = np.flatnonzero(np.isin(key.reshape(-1), want))
        pick = (
            aop.reshape(-1)[sel],
            np.asarray(obs.dop).reshape(-1)[sel],
            np.asarray(obs.valid).reshape(-1)[sel],
            np.asarray(obs.rays_cam).reshape(3, -1)[:, sel],
            None if obs.intensity is None else np.asarray(obs.intensity).reshape(-1)[sel],
        )
    return sample_sky(*pick[:4], intensity=pick[4], max_pixels=side_grid * side_grid)


def _whole_sky_side(obs: Observation, side_grid: int, first, second, extras: dict):
    """
    Decide the 180 deg side from the whole sky: (candidate or None, reason).

    The votes of :func:`polarization_compass.skyfit_assess.side_votes` (the AoP pattern at the
    ephemeris sun altitude, and the brightness of the half-sky towards each candidate sun) over the
    side grid: all votes for one candidate decide; no vote, disagreeing votes or too little sky
    leave it open. The votes go to ``extras["side_votes"]``.
    """
    from ..skyfit_assess import side_votes

    if side_grid <= 0:
        return None, 'no whole-sky side grid (side_grid 0)'
    sample = _side_sample(obs, side_grid)
    if sample is None:
        return None, 'too little usable sky outside the zenith window to decide the 180 deg side'
    # a known tilt enters the pattern vote: with the sun low, a few degrees of unmodelled pitch
    # turn the AoP pattern's small up/down asymmetry around and the vote would pick the wrong side
    pitch = 0.0 if obs.pitch_deg is None else float(obs.pitch_deg)
    roll = 0.0 if obs.roll_deg is None else float(obs.roll_deg)
    votes, extras['side_votes'] = side_votes(
        sample, math.degrees(first.psi_rad), float(obs.sun_altitude_deg), pitch, roll
    )
    if votes and all(v > 0 for v in votes):
        return first, 'sun side decided by the whole sky (AoP pattern and half-sky brightness)'
    if votes and all(v < 0 for v in votes):
        return second, 'sun side decided by the whole sky (AoP pattern and half-sky brightness)'
    return None, (
        "the whole sky's side votes disagree"
        if votes
        else 'the whole sky does not tell the side '
        '(sun altitude near 0 or 90 deg and no brightness contrast)'
    )


def _window_matrix(view, min_dop: float):
    """
    Return the window's ``sum e e^T`` (upper triangle), counts and AoP trig sums.

    (m (6,), cnt = (usable, valid non-finite, valid, intensity not finite), trig = (sum cos 2a,
    sum sin 2a)) from one compiled pass (:func:`_window_sums`), with the brightness statistics
    when the view has intensities.
    """
    has_i = view.intensity is not None
    m = np.zeros(6)
    cnt = np.zeros(4, np.int64)
    trig = np.zeros(2)
    stats = np.zeros(N_STATS)
    _window_sums(
        view.aop,
        view.dop,
        view.valid,
        view.rays,
        view.intensity if has_i else np.zeros(1, np.float32),
        has_i,
        float(min_dop),
        m,
        cnt,
        trig,
        stats,
    )
    return m, cnt, trig


def _sun_on_altitude_cone(m, altitude_deg: float):
    """
    Return the camera-frame sun on the plane perpendicular to the window's E-vector axis.

    Step 3 of the module doc: of the two intersections of the plane ``u . s = 0`` (``u`` the
    dominant eigenvector of ``m``, upper triangle of ``sum e e^T``) with the cone of elevation
    ``altitude_deg``, the one that fits the window's E-vectors better (smaller ``s^T M s``); None
    when ``u`` lies along the optical axis.
    """
    lam, U = _eigh3(m)
    u = U[:, 2]
    h = math.radians(altitude_deg)
    rho_u = math.hypot(u[0], u[1])
    if rho_u <= 1e-12:
        return None
    phi = math.atan2(u[0], u[1])  # azimuth of u (from +y towards +x)
    num = -u[2] * math.sin(h)
    den = rho_u * math.cos(h)
    kappa = max(-1.0, min(1.0, num / den)) if den > abs(num) else math.copysign(1.0, num)
    off = math.acos(kappa)
    best = None
    ch, sh = math.cos(h), math.sin(h)
    for mu in (phi + off, phi - off):
        x, y, z = ch * math.sin(mu), ch * math.cos(mu), sh
        cost = (
            m[0] * x * x
            + m[3] * y * y
            + m[5] * z * z
            + 2.0 * (m[1] * x * y + m[2] * x * z + m[4] * y * z)
        )  # s^T M s
        if best is None or cost < best[0]:
            best = (cost, (x, y, z))
    return np.array(best[1])


def _window_sigma_deg(view, sun_cam, k: dict):
    """
    Return (sigma_deg, rms residual deg) of the window fit.

    To first order ``d psi = -sum_i w_i da_i / sum w`` with ``da_i`` the residual against the
    Rayleigh AoP of ``sun_cam``; cluster-robust over blocks of ``block_px``.
    """
    smp = samples_from_view(view, k['min_dop'])
    resid = axial_residual_rad(smp.aop_rad, rayleigh_aop_rad(sun_cam, smp.rays))
    w = np.ones(smp.n)
    infl = w * resid / w.sum()
    sigma_deg = finish_sigma_deg(cluster_sigma_rad(infl, smp, k['block_px'], n_params=1), k)
    return sigma_deg, math.degrees(math.sqrt(float(np.mean(resid**2))))


class ZenithEstimator(KnobbedEstimator, Estimator):
    """
    Estimate the heading by the paper's zenith approach (level camera).

    The zenith is the principal point and its E-vector is perpendicular to the solar meridian; this
    implementation fits the window's lifted E-vectors exactly instead of averaging the AoP (see the
    module docstring).

    Parameters
    ----------
    **knobs
        Validated against :meth:`knob_specs`: ``window_px`` (side of the centred window, sensor
        pixels, default 32) and the common knobs (``min_dop``, ``min_pixels``, ``block_px`` [sensor
        pixels], sun-altitude limits [deg], ...); ``stride`` and ``region`` do not apply.

    Raises
    ------
    EstimatorError
        A knob is unknown or out of range.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), Sec. 3 (the zenith approach,
       after its refs [3, 16, 23-25]) and eq 28 (the AoP it reads).
    .. [2] K. D. Pham, J. L. Cox, T. M. Aycock et al., "Using Atmospheric Polarization Patterns for
       Azimuth Sensing", Sensors and Systems for Space Applications VII, 2014.
    .. [3] J. Dupeyroux, S. Viollet and J. R. Serres, "Polarized skylight-based heading
       measurements: a bio-inspired approach", J R Soc Interface 16(150): 20180878, 2019.

    """

    name = 'zenith'
    label = 'Zenith'
    style = ('tab:blue', '-')
    axial = True
    paper_method = True
    sweep_knobs = {}  # reads its 32 x 32 px window at the image centre
    relative_cost = 0.7
    OWN_KNOBS = {
        'window_px': Knob(
            32, 'int', 1, 2048, doc='side of the square window at the image centre, sensor pixels'
        ),
        'side_grid': Knob(
            32,
            'int',
            0,
            512,
            doc='the 180 deg side is decided from a side_grid x '
            'side_grid grid of pixels over the whole sensor '
            '(0: only a prior bearing decides it)',
        ),
    }
    KNOB_DEFAULTS = {'min_pixels': 4, 'block_px': 4, 'min_dop': 0.0}
    NO_KNOBS = ('stride', 'region')  # it reads its window, every pixel

    def pixels_needed(self, camera: CameraModel) -> PixelSelection:
        """
        Tell a renderer which pixels the method reads, so sweeps render only those.

        Parameters
        ----------
        camera : CameraModel
            The camera the frames come from.

        Returns
        -------
        PixelSelection
            The zenith window (:func:`zenith_window`), plus the whole-sky grid that decides the 180
            deg side (:func:`side_grid_px`) unless ``side_grid`` is 0.

        """
        return _pixels_needed(camera, self.knobs['window_px'], self.knobs['side_grid'])

    def estimate(self, obs: Observation, sigma: bool = True) -> HeadingResult:
        """
        Estimate one heading from the E-vectors of the zenith window.

        The dominant eigenvector of the window's ``sum e e^T`` is the zenith E-vector axis; the sun
        lies on the plane perpendicular to it at the ephemeris altitude, which gives psi and psi +
        180 deg; the whole sky (the ``side_grid`` pixels) or a prior bearing may resolve that
        ambiguity, never the window alone.

        Parameters
        ----------
        obs : Observation
            AoP [rad, eq 28], DoP, valid mask, camera-frame rays, the sun (azimuth clockwise from
            North and geometric altitude, deg); optional ``prior_bearing_deg`` [deg].
        sigma : bool, default True
            Compute the 1-sigma uncertainty ``sigma_deg`` (cluster-robust over blocks of
            ``block_px``).

        Returns
        -------
        HeadingResult
            psi [deg, (-180, 180]] (eq 21), true bearing of camera +y and REP-103 yaw,
            ``sigma_deg``, pixels used and quality (status ``ambiguous`` when the 180 deg ambiguity
            is unresolved); or a failure status with a reason (sun below the horizon or near the
            zenith, bad input, too few pixels, degenerate data), never NaN.

        References
        ----------
        .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
           Polarized Skylight Orientation Determination" (the seed paper), Sec. 3 (zenith
           approach), eqs 21 and 28.

        """
        k = self.knobs
        bad = check_sun(self.name, obs, k)
        if bad is not None:
            return bad
        win, _ = zenith_window(obs.camera, k['window_px'])
        try:
            view = select_view(obs, k, window=win)
        except _BadInput as exc:
            return HeadingResult.failed(self.name, Status.BAD_INPUT, str(exc))
        m, cnt, trig = _window_matrix(view, k['min_dop'])
        n, nonfinite = int(cnt[0]), int(cnt[1])
        if n < k['min_pixels']:
            return HeadingResult.failed(
                self.name,
                Status.TOO_FEW_PIXELS,
                f'{n} usable pixel(s) in the {k["window_px"]} px zenith window < '
                f'min_pixels {k["min_pixels"]}',
                pixels=n,
            )
        s = _sun_on_altitude_cone(m, float(obs.sun_altitude_deg))
        if s is None:
            return HeadingResult.failed(
                self.name,
                Status.DEGENERATE,
                "the window's E-vector points along the optical axis",
                pixels=n,
            )
        psi = psi_from_sun_rad(s)
        first, second = level_sun_candidates(psi, float(obs.sun_altitude_deg))
        first.sun_cam = s  # the exact fit (the other end is the level mirror)
        extras = {'window_px': k['window_px']}
        # the 180 deg side: a prior bearing when given, else the whole sky (a sparse grid over the
        # sensor) -- never the window's own brightness gradient, which lens-flare ghosts opposite
        # the sun can dominate
        pick, by, reason = resolve_ambiguity(
            self.name, first, second, None, obs, k, use_brightness=False
        )
        if by is None:
            sky_pick, why = _whole_sky_side(obs, k['side_grid'], first, second, extras)
            if sky_pick is not None:
                pick, by, reason = sky_pick, 'whole_sky', why
            else:
                reason = f'{reason}; {why}'
        sigma_deg = None
        if sigma:
            sigma_deg, extras['rms_residual_deg'] = _window_sigma_deg(view, s, k)
        R = math.hypot(trig[0], trig[1]) / n  # axial resultant length of the window's AoP
        return result_from(
            self.name, pick, by, reason, obs, sigma_deg, n, nonfinite, R, extras=extras
        )
