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
Whole-sky robust fit of the single-scattering (Rayleigh) AoP: a second opinion on real skies.

The estimators fit the sky each in their own way; on a real sky (clouds, lens flare, haze, a wrong
polarizer convention) a fit can be precise and wrong. This module fits the one thing every method
assumes, the Rayleigh E-vector field ``E = S x P`` (eq 18) seen through the sensor (eq 28), to the
whole usable sky with a robust (Cauchy) loss, and measures how well the frame agrees with it:

- :func:`fit_sky`: the sun (psi, and the altitude unless given) that best explains the AoP image,
  by a coarse grid over the whole circle then a fine grid (no local minimum can trap it, no
  starting point);
- :func:`misfit_at`: the robust residual statistics of the sky at a given heading (poor-fit test);
- :func:`jackknife_sigma_deg`: the heading's spread when each of K sky sectors is left out in turn
(delete-a-group jackknife, Efron 1982, ch. 2): the misfit of a real sky to the model is spatially
correlated, so it is the sectors, not the pixels, that are the independent samples;
- :func:`.skyfit_assess.side_preference`: which end of an axial heading the whole sky supports,
  from the AoP pattern at the known sun altitude and from the brightness of the two half-skies
  (never a small window).

Residuals are axial angle differences computed from doubled angles (no angle subtraction and wrap).
Cost: a few thousand sampled pixels, a few 10 ms per fit (numpy, float32).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .conventions import R_sun_cam_from_attitude, wrap_180_deg

__all__ = [
    'SkySample',
    'SkyFit',
    'sample_sky',
    'fit_sky',
    'misfit_at',
    'jackknife_sigma_deg',
    'CAUCHY_SCALE_DEG',
    'OUTLIER_DEG',
]

#: Cauchy loss scale: residuals well beyond it (cloud, flare, a foreign object) stop pulling the
#: fit
CAUCHY_SCALE_DEG = 5.0
#: a pixel whose AoP is further than this from the fitted sky counts as an outlier
OUTLIER_DEG = 15.0


@dataclass(frozen=True)
class SkySample:
    """
    Usable sky pixels for the whole-sky fit.

    Rays (3, N) in the camera frame, doubled-angle AoP (cos 2a, sin 2a), weights in [0, 1]
    (DoP-based), intensity (or None), and the image azimuth of each ray (rad).
    """

    rays: np.ndarray
    c2a: np.ndarray
    s2a: np.ndarray
    weight: np.ndarray
    intensity: np.ndarray | None
    ray_azimuth_rad: np.ndarray

    @property
    def count(self) -> int:
        """Return the number of sampled pixels."""
        return int(self.c2a.size)


@dataclass(frozen=True)
class SkyFit:
    """
    A robust whole-sky fit.

    ``psi_deg``, ``sun_altitude_deg`` the best sun (camera-frame psi of eq 21); ``scatter_deg``
    1.4826 x median |residual| (weighted pixels); ``inlier_fraction`` share of weight within
    :data:`OUTLIER_DEG`; ``loss`` the mean Cauchy loss; ``pixels`` the sample size.
    """

    psi_deg: float
    sun_altitude_deg: float
    loss: float
    scatter_deg: float
    inlier_fraction: float
    pixels: int


def sample_sky(
    aop_rad,
    dop,
    valid,
    rays_cam,
    intensity=None,
    max_pixels: int = 4000,
    min_dop: float = 0.02,
    extra_mask=None,
) -> SkySample | None:
    """
    Sample up to ``max_pixels`` usable pixels spread evenly over the image.

    A fixed stride over the usable pixels, deterministic. A pixel is usable when ``valid``, finite,
    with a DoP of at least ``min_dop`` and, if given, inside ``extra_mask``. Each pixel is weighted
    by ``clip(dop / 0.3, 0, 1)``.

    Parameters
    ----------
    aop_rad : array_like of float
        Angle of polarization of each pixel [rad], camera frame as in eq 28 (any shape).
    dop : array_like of float
        Degree of linear polarization, [0, 1], same shape as ``aop_rad``.
    valid : array_like of bool
        True where the pixel has a measurement, same shape as ``aop_rad``.
    rays_cam : array_like of float, shape (3, N)
        Unit viewing rays in the camera frame, in the order of ``aop_rad.reshape(-1)``.
    intensity : array_like of float, optional
        Intensity of each pixel (any linear unit), same shape as ``aop_rad``; used by
        :func:`.skyfit_assess.side_preference`.
    max_pixels : int, default 4000
        Most pixels kept.
    min_dop : float, default 0.02
        Smallest usable DoP [-].
    extra_mask : array_like of bool, optional
        Same shape as ``aop_rad``, True = usable (e.g. :func:`data_mask`).

    Returns
    -------
    SkySample or None
        The sampled rays, doubled-angle AoP, weights, intensities and ray azimuths [rad]; None when
        fewer than 30 pixels are usable.

    """
    a = np.asarray(aop_rad, dtype=np.float32).reshape(-1)
    d = np.asarray(dop, dtype=np.float32).reshape(-1)
    ok = (
        np.asarray(valid, dtype=bool).reshape(-1)
        & np.isfinite(a)
        & np.isfinite(d)
        & (d >= min_dop)
    )
    if extra_mask is not None:
        ok &= np.asarray(extra_mask, dtype=bool).reshape(-1)
    idx = np.flatnonzero(ok)
    if idx.size < 30:
        return None
    if idx.size > max_pixels:
        idx = idx[np.linspace(0, idx.size - 1, max_pixels).astype(np.int64)]
    r = np.asarray(rays_cam, dtype=np.float32).reshape(3, -1)[:, idx]
    aa = a[idx].astype(np.float64)
    w = np.clip(d[idx] / 0.3, 0.0, 1.0).astype(np.float32)
    inten = None if intensity is None else np.asarray(intensity, dtype=np.float32).reshape(-1)[idx]
    return SkySample(
        np.ascontiguousarray(r),
        np.cos(2 * aa).astype(np.float32),
        np.sin(2 * aa).astype(np.float32),
        w,
        inten,
        np.arctan2(r[1], r[0]).astype(np.float32),
    )


def _sun_cam(psi_deg, alt_deg, pitch_deg=0.0, roll_deg=0.0) -> np.ndarray:
    """
    Return (K, 3) sun directions in the camera frame for K (psi, altitude) pairs.

    Eq 21 transposed, at the given pitch and roll.
    """
    psi = np.asarray(psi_deg, dtype=float).reshape(-1)
    alt = np.radians(np.asarray(alt_deg, dtype=float).reshape(-1))
    s_a = np.stack(
        [np.zeros_like(alt), np.cos(alt), np.sin(alt)], axis=-1
    )  # frame a: y at the sun
    R = R_sun_cam_from_attitude(psi, np.full_like(psi, pitch_deg), np.full_like(psi, roll_deg))
    return np.einsum('kji,kj->ki', R, s_a)  # R^T s_a


def _cos_sin_2res(sample: SkySample, sun_cam: np.ndarray):
    """
    Return cos and sin of twice the residual (measured - model), shape (K, N).

    The model is E = S x P (eqs 18, 28) for each of the K suns.
    """
    P = sample.rays
    S = sun_cam.astype(np.float32)
    ex = S[:, 1:2] * P[2] - S[:, 2:3] * P[1]
    ey = S[:, 2:3] * P[0] - S[:, 0:1] * P[2]
    n2 = ex * ex + ey * ey
    n2 = np.where(n2 > 1e-12, n2, np.float32(1.0))
    c2m = (ey * ey - ex * ex) / n2  # model AoP m = atan2(ex, ey): cos 2m, sin 2m
    s2m = 2 * ex * ey / n2
    c = sample.c2a * c2m + sample.s2a * s2m
    s = sample.s2a * c2m - sample.c2a * s2m
    return c, s


def _loss(sample: SkySample, sun_cam: np.ndarray, weight=None) -> np.ndarray:
    """Return the mean weighted Cauchy loss per candidate sun (K,). sin^2 r = (1 - cos 2r) / 2."""
    c, _ = _cos_sin_2res(sample, sun_cam)
    s2 = np.float32(math.sin(math.radians(CAUCHY_SCALE_DEG)) ** 2)
    rho = np.log1p(np.maximum(0.5 * (1 - c), 0) / s2)
    w = sample.weight if weight is None else weight
    return (rho @ w) / max(float(w.sum()), 1e-9)


def _chunked_loss(sample, psi, alt, pitch, roll, weight=None, chunk=256):
    out = np.empty(psi.size)
    for i in range(0, psi.size, chunk):
        out[i : i + chunk] = _loss(
            sample, _sun_cam(psi[i : i + chunk], alt[i : i + chunk], pitch, roll), weight
        )
    return out


def misfit_at(
    sample: SkySample,
    psi_deg: float,
    sun_altitude_deg: float,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
) -> SkyFit:
    """
    Return the residual statistics of the sky for one sun and known tilt.

    The model is the single-scattering E-vector ``E = S x P`` (eq 18) projected to an AoP as in
    eq 28, with the sun placed in the camera frame by eq 21; residuals are axial differences from
    doubled angles.

    Parameters
    ----------
    sample : SkySample
        Sampled sky pixels (:func:`sample_sky`).
    psi_deg : float
        Camera-frame sun angle psi of eq 21 [deg].
    sun_altitude_deg : float
        Sun altitude [deg].
    pitch_deg : float, default 0
        Camera pitch [deg] (conventions module).
    roll_deg : float, default 0
        Camera roll [deg] (conventions module).

    Returns
    -------
    SkyFit
        ``psi_deg`` wrapped to (-180, 180], the sun altitude, the mean Cauchy loss, the robust
        scatter ``1.4826 * median |residual|`` [deg] (90 without weighted pixels), the inlier
        fraction of weight within :data:`OUTLIER_DEG`, and the sample size.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 18, 21 and 28.

    """
    sun = _sun_cam([psi_deg], [sun_altitude_deg], pitch_deg, roll_deg)
    c, s = _cos_sin_2res(sample, sun)
    res_deg = np.degrees(0.5 * np.arctan2(s[0], c[0]).astype(np.float64))
    w = sample.weight.astype(np.float64)
    keep = w > 0
    ad = np.abs(res_deg[keep])
    scatter = 1.4826 * float(np.median(ad)) if ad.size else 90.0
    inl = float(w[keep][ad < OUTLIER_DEG].sum() / max(w[keep].sum(), 1e-9)) if ad.size else 0.0
    loss = float(_loss(sample, sun)[0])
    return SkyFit(
        float(wrap_180_deg(psi_deg)), float(sun_altitude_deg), loss, scatter, inl, sample.count
    )


def fit_sky(
    sample: SkySample,
    sun_altitude_deg: float | None = None,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
    psi_range_deg=None,
    weight=None,
) -> SkyFit:
    """
    Fit psi (and the sun altitude when ``sun_altitude_deg`` is None) to the sampled sky.

    Coarse grid on at most 600 of the pixels: psi every 2 deg over the circle (or ``psi_range_deg =
    (lo, hi)``), altitude every 4 deg in [0, 88]; then on all pixels two rounds of fine line
    searches (psi +-3 deg by 0.1 deg, altitude +-6 deg by 0.5 deg) around the best. The loss is the
    mean weighted Cauchy loss (scale :data:`CAUCHY_SCALE_DEG`) of the axial residuals to the
    single-scattering pattern of eqs 18 and 28. Tilt is taken as known.

    Parameters
    ----------
    sample : SkySample
        Sampled sky pixels (:func:`sample_sky`).
    sun_altitude_deg : float, optional
        Known sun altitude [deg]; None fits it as well.
    pitch_deg : float, default 0
        Known camera pitch [deg].
    roll_deg : float, default 0
        Known camera roll [deg].
    psi_range_deg : tuple of float, optional
        ``(lo, hi)`` range of psi searched by the coarse grid [deg]; default the whole circle
        [-180, 180).
    weight : array_like of float, optional
        Per-pixel weights replacing ``sample.weight`` (shape (N,)).

    Returns
    -------
    SkyFit
        The best sun with its residual statistics (:func:`misfit_at`).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 18, 21 and 28.

    """
    lo, hi = (-180.0, 180.0) if psi_range_deg is None else psi_range_deg
    psis = np.arange(lo, hi, 2.0)
    alts = (
        np.array([sun_altitude_deg], float)
        if sun_altitude_deg is not None
        else np.arange(0.0, 88.1, 4.0)
    )
    coarse = sample
    if sample.count > 600:
        idx = np.linspace(0, sample.count - 1, 600).astype(np.int64)
        coarse = SkySample(
            np.ascontiguousarray(sample.rays[:, idx]),
            sample.c2a[idx],
            sample.s2a[idx],
            (sample.weight if weight is None else weight)[idx],
            None,
            sample.ray_azimuth_rad[idx],
        )
    P, A = np.meshgrid(psis, alts, indexing='ij')
    L = _chunked_loss(coarse, P.ravel(), A.ravel(), pitch_deg, roll_deg)
    k = int(np.argmin(L))
    p0, a0 = float(P.ravel()[k]), float(A.ravel()[k])
    for _ in range(2):
        fp = p0 + np.arange(-3.0, 3.001, 0.1)
        p0 = float(
            fp[
                int(
                    np.argmin(
                        _chunked_loss(
                            sample, fp, np.full(fp.size, a0), pitch_deg, roll_deg, weight
                        )
                    )
                )
            ]
        )
        if sun_altitude_deg is None:
            fa = np.unique(np.clip(a0 + np.arange(-6.0, 6.001, 0.5), 0.0, 89.5))
            a0 = float(
                fa[
                    int(
                        np.argmin(
                            _chunked_loss(
                                sample, np.full(fa.size, p0), fa, pitch_deg, roll_deg, weight
                            )
                        )
                    )
                ]
            )
    return misfit_at(sample, p0, a0, pitch_deg, roll_deg)


def jackknife_sigma_deg(
    sample: SkySample,
    psi_deg: float,
    sun_altitude_deg: float,
    pitch_deg: float = 0.0,
    roll_deg: float = 0.0,
    sectors: int = 8,
) -> float:
    """
    Estimate the delete-a-group jackknife standard error of psi over azimuthal sky sectors.

    Each sector (by the ray's azimuth about the optical axis) is left out in turn and psi refitted
    on a 0.05 deg grid within +-6 deg of ``psi_deg`` at the given sun altitude;
    ``sqrt((K - 1) / K * sum (psi_k - mean)^2)``. Sectors with no pixels are skipped.

    Parameters
    ----------
    sample : SkySample
        Sampled sky pixels (:func:`sample_sky`).
    psi_deg : float
        Camera-frame sun angle psi of eq 21 around which psi is refitted [deg].
    sun_altitude_deg : float
        Sun altitude [deg].
    pitch_deg : float, default 0
        Camera pitch [deg].
    roll_deg : float, default 0
        Camera roll [deg].
    sectors : int, default 8
        Number K of equal azimuthal sectors.

    Returns
    -------
    float
        Jackknife standard error of psi [deg]; 180 (unknown) when fewer than 3 sectors are usable.

    References
    ----------
    .. [1] B. Efron, "The Jackknife, the Bootstrap and Other Resampling Plans", SIAM, 1982, ch. 2.

    """
    edges = np.linspace(-math.pi, math.pi, sectors + 1)
    grid = psi_deg + np.arange(-6.0, 6.001, 0.05)
    alts = np.full(grid.size, sun_altitude_deg)
    suns = _sun_cam(grid, alts, pitch_deg, roll_deg)
    c, _ = _cos_sin_2res(sample, suns)
    s2 = np.float32(math.sin(math.radians(CAUCHY_SCALE_DEG)) ** 2)
    rho = np.log1p(np.maximum(0.5 * (1 - c), 0) / s2)
    est = []
    for i in range(sectors):
        out = (sample.ray_azimuth_rad >= edges[i]) & (sample.ray_azimuth_rad < edges[i + 1])
        if not out.any():
            continue
        w = np.where(out, 0.0, sample.weight).astype(np.float32)
        if w.sum() <= 0:
            continue
        est.append(float(grid[int(np.argmin(rho @ w))]))
    if len(est) < 3:
        return 180.0
    e = np.asarray(est)
    k = e.size
    return float(math.sqrt((k - 1) / k * float(np.sum((e - e.mean()) ** 2))))


def data_mask(intensity, has_ray, saturation_level=None, glare_fraction: float = 0.02):
    """
    Return the pixels to keep: in the lens' field, away from saturation and glare.

    Saturated areas (the sun and its glare) are grown by ``glare_fraction`` of the image diagonal
    with OpenCV's elliptical dilation and removed. Lens-flare ghosts, clouds and obstacles are not
    masked here: they are down-weighted by the robust loss (and show up as misfit).

    Parameters
    ----------
    intensity : array_like of float, shape (H, W)
        Intensity image (any linear unit).
    has_ray : array_like of bool
        True where the pixel is inside the lens' field (reshaped to ``intensity``'s shape).
    saturation_level : float, optional
        Intensity at and above which a pixel is saturated (unit of ``intensity``). None: taken from
        the data when 0.05-50 % of the in-field pixels sit within 0.5 % of a maximum at least 10 %
        above the median (a clipped plateau), else nothing counts as saturated.
    glare_fraction : float, default 0.02
        Dilation radius as a fraction of the image diagonal [-] (at least 1 pixel).

    Returns
    -------
    numpy.ndarray of bool, shape (H, W)
        True = pixel to keep.

    """
    import cv2

    i = np.asarray(intensity, dtype=np.float32)
    keep = np.asarray(has_ray, dtype=bool).reshape(i.shape).copy()
    if not keep.any():
        return keep
    if saturation_level is None:
        vals = i[keep]
        top = float(vals.max())
        share = float(np.mean(vals >= top * 0.995)) if top > 0 else 0.0
        # a clipped plateau: some (not most) pixels at a maximum well above the typical sky
        if 5e-4 <= share <= 0.5 and top > 1.1 * float(np.median(vals)):
            saturation_level = top * 0.995
    if saturation_level is not None:
        sat = (i >= saturation_level).astype(np.uint8)
        if sat.any():
            r = max(1, int(round(glare_fraction * math.hypot(*i.shape))))
            k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
            keep &= cv2.dilate(sat, k) == 0
    return keep
