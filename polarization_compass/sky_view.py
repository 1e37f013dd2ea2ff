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
What the estimators saw, as layers for a picture (issue 25); no plotting here.

A :class:`SkyView` holds, on a downscaled grid of the image: the AoP and DoP the estimators read,
one class per pixel (used, or the first reason it was not, in this order: outside the lens, the
user's mask, the saturated sun and its glare, the IFOV check, no measurement, DoP below
:data:`MIN_DOP`, off the fitted sky by more than :data:`polarization_compass.skyfit.OUTLIER_DEG`
-- how clouds and flare ghosts show, since nothing masks them before the fit -- and not read by
any method), the residual against the fitted single-scattering sky (seed paper eqs 18 and 28),
and where the fitted sun, the anti-sun and the solar meridian project.
:mod:`polarization_compass.diagnostic_figure` draws it.

The fitted sky is the sun of one result (:func:`fit_result`: the usable result of least sigma,
else the least sigma of those with a psi), at the result's own sun altitude when it has one
(least squares) or the observation's (ephemeris), with the known tilt for the methods that read
it (level for the others, whose psi assumes a level camera).

Sources: :func:`view_from_seen` (what :func:`polarization_compass.headings.estimate_file` saw:
frame files, raw mosaics, Stokes planes) and :func:`view_from_mosaic` (a node's raw mosaic).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

__all__ = [
    'CLASSES',
    'MIN_DOP',
    'SkyView',
    'USED',
    'aop_residual_deg',
    'build_view',
    'fit_result',
    'project_sun',
    'view_from_mosaic',
    'view_from_seen',
]

#: DoP below which a pixel carries no usable angle (the estimators' default ``min_dop`` knob and
#: the whole-sky check's)
MIN_DOP = 0.02

#: class code of a used pixel
USED = 0
#: class codes to labels; a pixel gets the highest code whose reason applies
CLASSES = (
    'used',
    'not read by the methods',
    'off the fitted sky > 15 deg (noise, cloud, flare ghost)',
    f'DoP < {MIN_DOP:g} (cloud, haze)',
    'no measurement (dark, S1 = S2 = 0)',
    'IFOV check',
    'saturated sun + glare',
    'user mask',
    'outside the lens / no sky',
)
_NOT_READ, _OFF_FIT, _LOW_DOP, _NO_DATA, _IFOV, _GLARE, _USER, _OUTSIDE = range(1, 9)


@dataclass
class SkyView:
    """
    Layers of one image on a grid downscaled by ``step`` (see the module docstring).

    ``aop_deg`` (eq 28, [-90, 90)) and ``dop`` are NaN where there is no measurement; ``classes``
    holds a code of :data:`CLASSES` per cell (the highest code in the cell's block) and
    ``counts`` the number of full-resolution pixels per code. ``residual_deg`` is the measured
    minus the fitted AoP folded to [-90, 90) (None without a fit). Pixel positions (``sun_px``,
    ``antisun_px``, ``meridian_px``, ``centre_px``) are 1-based sensor (x, y) [px]; ``extent``
    the imshow extent (left, right, bottom, top) in the same coordinates; ``sun_dir_img`` is
    the image direction (dx, dy) of each result's sun azimuth at the principal point.
    """

    aop_deg: np.ndarray
    dop: np.ndarray
    classes: np.ndarray
    counts: list
    residual_deg: np.ndarray | None
    extent: tuple
    results: list
    fit: object = None
    sun_px: tuple | None = None
    antisun_px: tuple | None = None
    meridian_px: np.ndarray | None = None
    centre_px: tuple = (0.0, 0.0)
    sun_dir_img: dict = field(default_factory=dict)
    label: str = ''
    step: int = 1
    counted_every_px: int = 1


def fit_result(results, tilt_known: bool = False):
    """
    Pick the result whose sun draws the fitted sky.

    The usable result of least sigma (with a known tilt, among the methods that read it); else the
    result of least sigma among those with a psi (``poor_fit``, ``inconsistent``).

    Parameters
    ----------
    results : list of HeadingResult
        The methods' results.
    tilt_known : bool, default False
        Whether the observation has the camera's pitch and roll.

    Returns
    -------
    HeadingResult or None
        None when no result has a psi.

    """
    with_psi = [r for r in results if r.psi_deg is not None and math.isfinite(r.psi_deg)]
    usable = [r for r in with_psi if r.ok]
    if tilt_known and any(_reads_tilt(r.method) for r in usable):
        usable = [r for r in usable if _reads_tilt(r.method)]
    pool = usable or with_psi
    if not pool:
        return None
    return min(pool, key=lambda r: r.sigma_deg if r.sigma_deg is not None else math.inf)


def _reads_tilt(method: str) -> bool:
    """Return whether a method's psi uses the known tilt (else it assumes a level camera)."""
    from .estimators import registry

    return method in registry.tilt_methods()


def _tilt_of(result, obs):
    """Return the tilt (pitch, roll) [deg] a result's psi goes with: the known one or level."""
    if _reads_tilt(result.method):
        return obs.pitch_deg or 0.0, obs.roll_deg or 0.0
    return 0.0, 0.0


def _sun_frame(psi_deg, pitch_deg, roll_deg):
    """Camera-frame (sun-azimuth horizontal, zenith) unit vectors of eq 21."""
    from .conventions import R_sun_cam_from_attitude

    R = R_sun_cam_from_attitude(psi_deg, pitch_deg, roll_deg)
    return R.T @ np.array([0.0, 1.0, 0.0]), R.T @ np.array([0.0, 0.0, 1.0])


def project_sun(camera, psi_deg, sun_altitude_deg, pitch_deg=0.0, roll_deg=0.0):
    """
    Project the sun of a heading into the image (eq 21, then the camera model).

    Parameters
    ----------
    camera : CameraModel
        The camera.
    psi_deg : float
        The paper's yaw [deg].
    sun_altitude_deg : float
        Sun altitude [deg].
    pitch_deg, roll_deg : float, default 0
        Camera tilt [deg].

    Returns
    -------
    tuple
        ``(sun (x, y) or None, anti-sun (x, y) or None)``, 1-based [px]; None when the direction
        is behind the lens or outside the image.

    """
    h, z = _sun_frame(psi_deg, pitch_deg, roll_deg)
    a = math.radians(sun_altitude_deg)
    s = math.cos(a) * h + math.sin(a) * z
    return _project_one(camera, s), _project_one(camera, -s)


def _project_one(camera, v):
    x, y = _project(camera, np.asarray(v, float).reshape(3, 1))
    if not np.isfinite(x[0]):
        return None
    return float(x[0]), float(y[0])


def _project(camera, rays):
    """Project (3, N) rays; NaN behind the lens, beyond 90 deg (fisheye) or outside the image."""
    r = np.asarray(rays, float)
    theta = np.degrees(np.arctan2(np.hypot(r[0], r[1]), r[2]))
    limit = 89.0 if camera.model == 'pinhole' else camera.max_field_angle_deg
    ok = theta < limit
    x, y = np.full(r.shape[1], np.nan), np.full(r.shape[1], np.nan)
    if ok.any():
        x[ok], y[ok] = camera.pixels_from_rays(r[:, ok])
    W, H = camera.width_px, camera.height_px
    out = ~((x >= 0.5) & (x <= W + 0.5) & (y >= 0.5) & (y <= H + 0.5))
    x[out], y[out] = np.nan, np.nan
    return x, y


def _meridian(camera, psi_deg, pitch_deg, roll_deg, n=181):
    """Project the solar meridian, (2, n) [px]: elevation 0 at the sun's azimuth to 180."""
    h, z = _sun_frame(psi_deg, pitch_deg, roll_deg)
    e = np.radians(np.linspace(0.0, 180.0, n))
    rays = np.outer(h, np.cos(e)) + np.outer(z, np.sin(e))
    return np.vstack(_project(camera, rays))


def aop_residual_deg(aop_rad, rays_cam, valid, psi_deg, sun_altitude_deg, pitch_deg, roll_deg):
    """
    Return the measured minus the single-scattering AoP of a sun (seed paper eqs 18, 28, 21).

    Parameters
    ----------
    aop_rad : numpy.ndarray
        Measured AoP [rad] (eq 28), any shape.
    rays_cam : array_like, shape (3, N)
        Unit camera-frame rays in the order of ``aop_rad.reshape(-1)``.
    valid : numpy.ndarray of bool
        Pixels with a measurement, ``aop_rad``'s shape.
    psi_deg, sun_altitude_deg : float
        The sun: the paper's yaw and the altitude [deg].
    pitch_deg, roll_deg : float
        Camera tilt [deg].

    Returns
    -------
    numpy.ndarray
        Residual [deg] folded to [-90, 90), NaN where not valid.

    """
    h, z = _sun_frame(psi_deg, pitch_deg, roll_deg)
    a = math.radians(sun_altitude_deg)
    sx, sy, sz = (np.float32(v) for v in math.cos(a) * h + math.sin(a) * z)
    r = np.asarray(rays_cam, np.float32).reshape(3, -1)
    ex = sy * r[2] - sz * r[1]  # Rayleigh: E ~ s x v (seed paper eq 18), float32 for speed
    ey = sz * r[0] - sx * r[2]
    pred = np.arctan2(ex, ey).reshape(np.shape(aop_rad))  # eq 28: from +y_cam towards +x_cam
    d = np.degrees(np.asarray(aop_rad, np.float32) - pred)
    res = (d + np.float32(90.0)) % np.float32(180.0) - np.float32(90.0)
    return np.where(valid, res, np.float32(np.nan))


def _block_max(codes, step):
    """Highest code in each ``step`` x ``step`` block (the rarest reason stays visible)."""
    if step == 1:
        return codes.copy()
    h, w = codes.shape
    H, W = -(-h // step) * step, -(-w // step) * step
    pad = np.zeros((H, W), codes.dtype)
    pad[:h, :w] = codes
    return pad.reshape(H // step, step, W // step, step).max(axis=(1, 3))


def build_view(
    obs,
    reasons: dict,
    results,
    max_side_px: int = 400,
    label: str = '',
):
    """
    Make the layers of a whole-image observation (see the module docstring).

    Parameters
    ----------
    obs : Observation
        The whole image as the estimators saw it, on a 2-D grid (``aop_rad``, ``dop``, ``valid``,
        ``rays_cam``, ``x_px``, ``y_px``, the camera, the sun altitude and the tilt).
    reasons : dict
        Class code (1..8 of :data:`CLASSES`) to a bool array of the grid's shape, True where the
        reason applies; codes 2, 3 and 4 are derived here (DoP, fit, invalid).
    results : list of HeadingResult
        The methods' results.
    max_side_px : int, default 400
        Longest side of the view [cells].
    label : str, default ''
        What the image is (a file name).

    Returns
    -------
    SkyView
        The layers.

    """
    aop, dop = np.asarray(obs.aop_rad), np.asarray(obs.dop)
    valid = np.asarray(obs.valid, bool)
    fit = fit_result(results, obs.pitch_deg is not None)
    alt = obs.sun_altitude_deg
    if fit is not None and fit.sun_altitude_deg is not None:
        alt = fit.sun_altitude_deg
    codes = np.zeros(aop.shape, np.uint8)
    codes[valid & (dop < MIN_DOP)] = _LOW_DOP
    residual = None
    if fit is not None:
        residual = aop_residual_deg(
            aop, obs.rays_cam, valid, fit.psi_deg, alt, *_tilt_of(fit, obs)
        )
        from .skyfit import OUTLIER_DEG

        off = valid & (dop >= MIN_DOP) & (np.abs(np.nan_to_num(residual)) > OUTLIER_DEG)
        codes[off] = _OFF_FIT
    codes[~valid] = _NO_DATA
    for code in sorted(reasons):
        mask = np.asarray(reasons[code], bool)
        codes[mask & (codes < code)] = code
    counts = np.bincount(codes.reshape(-1), minlength=len(CLASSES)).tolist()
    step = max(1, -(-max(aop.shape) // int(max_side_px)))
    return _downscaled(obs, codes, counts, residual, results, fit, alt, step, label)


def _downscaled(obs, codes, counts, residual, results, fit, alt, step, label):
    """Sample the layers every ``step`` cells (block maximum for the classes) and add geometry."""
    c = step // 2
    show = _block_max(codes, step)
    h, w = show.shape
    aop = np.degrees(np.asarray(obs.aop_rad)[c::step, c::step][:h, :w].astype(np.float64))
    dop = np.asarray(obs.dop)[c::step, c::step][:h, :w].astype(np.float64)
    nodata = np.asarray(obs.valid, bool)[c::step, c::step][:h, :w] == 0
    aop[nodata], dop[nodata] = np.nan, np.nan
    res = None if residual is None else residual[c::step, c::step][:h, :w]
    x, y = np.asarray(obs.x_px), np.asarray(obs.y_px)
    dx = float(x[0, 1] - x[0, 0]) if x.shape[1] > 1 else 1.0
    dy = float(y[1, 0] - y[0, 0]) if y.shape[0] > 1 else 1.0
    x0, y0 = float(x[0, 0]) - dx / 2, float(y[0, 0]) - dy / 2
    extent = (x0, x0 + dx * step * w, y0 + dy * step * h, y0)
    cam = obs.camera
    view = SkyView(aop, dop, show, counts, res, extent, list(results), fit, label=label, step=step)
    view.centre_px = (cam.cx_px, cam.cy_px)
    for r in results:
        if r.psi_deg is not None and math.isfinite(r.psi_deg):
            hv, _ = _sun_frame(r.psi_deg, *_tilt_of(r, obs))
            n = math.hypot(hv[0], hv[1]) or 1.0
            view.sun_dir_img[r.method] = (hv[0] / n, hv[1] / n)
    if fit is not None:
        tilt = _tilt_of(fit, obs)
        view.sun_px, view.antisun_px = project_sun(cam, fit.psi_deg, alt, *tilt)
        view.meridian_px = _meridian(cam, fit.psi_deg, *tilt)
    return view


# ------------------------------------------------------------------------------------------------
# Sources
# ------------------------------------------------------------------------------------------------
def view_from_seen(
    seen: dict, demosaic: str = 'superpixel', ifov_k=None, max_side_px=400, label=''
):
    """
    Make the layers of what :func:`polarization_compass.headings.estimate_file` saw.

    Parameters
    ----------
    seen : dict
        Filled by ``estimate_file(..., seen=seen)``.
    demosaic : {"superpixel", "bilinear"}, default "superpixel"
        The demosaic a raw mosaic was read with.
    ifov_k : float, optional
        The IFOV check's threshold [noise sigmas] it was read with (default the front ends').
    max_side_px : int, default 400
        Longest side of the view [cells].
    label : str, default ''
        What the image is (a file name).

    Returns
    -------
    SkyView
        The layers.

    """
    from .demosaic import IFOV_K_DEFAULT

    k = IFOV_K_DEFAULT if ifov_k is None else ifov_k
    results = seen['results']
    if seen['kind'] != 'frame':
        obs, reasons = _real_reasons(seen, demosaic)
    elif seen['plan'] is None:
        obs = next(iter(seen['observations'].values()))
        reasons = {_OUTSIDE: ~np.asarray(seen['frame'].valid, bool)}
    else:
        frame, plan, sun = seen['frame'], seen['plan'], seen['sun']
        first = next(iter(seen['observations'].values()))
        obs, reasons = _mosaic_reasons(
            frame.mosaic,
            frame.camera,
            sun,
            plan.demosaic,
            plan.layout,
            plan.pol45_toward,
            plan.saturation_level,
            k,
            first.pitch_deg,
            first.roll_deg,
            plan.origin_px,
        )
        reasons[_NOT_READ] = ~_read_by(obs, seen['observations'].values())
    return build_view(obs, reasons, results, max_side_px, label)


def _read_by(whole, observations):
    """Cells of the whole grid that some method's observation read (nearest cell)."""
    x, y = np.asarray(whole.x_px), np.asarray(whole.y_px)
    dx = float(x[0, 1] - x[0, 0]) if x.shape[1] > 1 else 1.0
    dy = float(y[1, 0] - y[0, 0]) if y.shape[0] > 1 else 1.0
    read = np.zeros(x.shape, bool)
    for o in observations:
        ci = np.rint((np.asarray(o.x_px).reshape(-1) - x[0, 0]) / dx).astype(np.int64)
        ri = np.rint((np.asarray(o.y_px).reshape(-1) - y[0, 0]) / dy).astype(np.int64)
        ok = (ci >= 0) & (ci < x.shape[1]) & (ri >= 0) & (ri < x.shape[0])
        read[ri[ok], ci[ok]] = True
    return read


def _mosaic_reasons(
    mosaic,
    camera,
    sun,
    method,
    layout,
    pol45,
    sat_level,
    ifov_k,
    pitch,
    roll,
    origin_px=(1, 1),
    stride_px=None,
):
    """
    Whole-frame observation of a raw mosaic and its reasons: outside, saturated, IFOV.

    ``stride_px``: every N-th sensor pixel only (a sparse demosaic with the full frame's values).
    """
    from .camera_pixels import PixelSelection
    from .estimators.mosaic_input import observation_from_mosaic

    selection = None if not stride_px else PixelSelection.strided(stride_px)

    def obs_with(k):
        return observation_from_mosaic(
            mosaic,
            camera,
            sun.azimuth_deg,
            sun.altitude_deg,
            origin_px=origin_px,
            method=method,
            layout=layout,
            pol45_toward=pol45,
            saturation_level=sat_level,
            pitch_deg=pitch,
            roll_deg=roll,
            ifov_k=k,
            selection=selection,
        )

    obs = obs_with(ifov_k)
    shape = np.shape(obs.aop_rad)
    if camera.model == 'pinhole' and not camera.distorted:
        has_ray = np.ones(shape, bool)  # every pixel of an ideal pinhole has a ray
    else:
        has_ray = np.asarray(camera.rays_from_pixels(obs.x_px, obs.y_px)[1], bool)
    if sat_level is None:
        m = np.asarray(mosaic)
        sat_level = np.iinfo(m.dtype).max if m.dtype.kind in 'ui' else None
    reasons = {
        _OUTSIDE: ~has_ray.reshape(shape),
        _GLARE: _saturated_at(mosaic, sat_level, obs, method, origin_px),
    }
    if ifov_k:
        reasons[_IFOV] = np.asarray(obs_with(0.0).valid, bool) & ~np.asarray(obs.valid, bool)
    return obs, reasons


def _saturated_at(mosaic, sat_level, obs, method, origin_px) -> np.ndarray:
    """Mark the observation's pixels whose raw samples (2 x 2 block for superpixels) saturate."""
    if sat_level is None:
        return np.zeros(np.shape(obs.aop_rad), bool)
    m = np.asarray(mosaic)
    base = (-0.5, 0.5) if method == 'superpixel' else (0.0,)  # the block's samples
    x = np.asarray(obs.x_px, float) - origin_px[0]  # 0-based mosaic column of the pixel's centre
    y = np.asarray(obs.y_px, float) - origin_px[1]
    sat = np.zeros(x.shape, bool)
    for dx in base:
        c = np.clip(np.rint(x + dx), 0, m.shape[1] - 1).astype(np.int64)
        for dy in base:
            r = np.clip(np.rint(y + dy), 0, m.shape[0] - 1).astype(np.int64)
            sat |= m[r, c] >= sat_level
    return sat


def _real_reasons(seen, demosaic):
    """Return the real image's observation and its reasons: lens, user mask, glare, IFOV."""
    from .demosaic import aop_dop_from_stokes
    from .pipeline import real_image
    from .polarizer_files import plane_rays

    inp, cam_file, keep = seen['input'], seen['camera_file'], np.asarray(seen['data_mask'], bool)
    obs = next(iter(seen['observations'].values()))
    cam = cam_file.camera
    s0, s1, s2, saturated = real_image._camera_stokes(inp, cam_file, demosaic, 0.0)
    xg, yg, _, has_ray = plane_rays(cam, s0.shape)
    has_ray = np.asarray(has_ray, bool).reshape(s0.shape)
    unmasked = real_image._sky_mask(s0, has_ray, saturated, None, xg, yg, cam.shape)
    reasons = {
        _OUTSIDE: ~has_ray,
        _USER: unmasked & ~keep,
        _GLARE: has_ray & ~unmasked,
    }
    if inp.kind != 'stokes':
        valid0 = aop_dop_from_stokes(s0, s1, s2)[2]
        reasons[_IFOV] = valid0 & keep & ~np.asarray(obs.valid, bool)
    return obs, reasons


def view_from_mosaic(
    mosaic,
    camera,
    sun,
    results,
    layout,
    pol45_toward,
    demosaic='superpixel',
    pitch_deg=None,
    roll_deg=None,
    ifov_k=None,
    max_side_px=400,
    label='',
    sampled: bool = False,
):
    """
    Make the layers of a raw mosaic as a node's front end reads it (whole frame).

    Parameters
    ----------
    mosaic : numpy.ndarray
        Raw DoFP image, the camera's (height, width).
    camera : CameraModel
        The camera.
    sun : Sun
        Where the sun was (:class:`polarization_compass.pipeline.sun.Sun`: azimuth, altitude
        [deg]).
    results : list of HeadingResult
        The results to draw.
    layout : sequence
        The sensor's 2 x 2 polarizer angles [deg].
    pol45_toward : str
        Image direction of the 45 deg polarizer.
    demosaic : {"superpixel", "bilinear"}, default "superpixel"
        Demosaicing.
    pitch_deg, roll_deg : float, optional
        Known camera tilt [deg].
    ifov_k : float, optional
        IFOV check threshold [noise sigmas] (default the front ends').
    max_side_px : int, default 400
        Longest side of the view [cells].
    label : str, default ''
        What the image is.
    sampled : bool, default False
        Demosaic only every N-th sensor pixel (N = longest side / ``max_side_px``, the values the
        full frame would give), for speed: the counts are then of those pixels
        (``counted_every_px``).

    Returns
    -------
    SkyView
        The layers.

    """
    from .demosaic import IFOV_K_DEFAULT

    k = IFOV_K_DEFAULT if ifov_k is None else ifov_k
    stride = max(2, -(-max(camera.shape) // int(max_side_px))) if sampled else None
    obs, reasons = _mosaic_reasons(
        mosaic,
        camera,
        sun,
        demosaic,
        layout,
        pol45_toward,
        None,
        k,
        pitch_deg,
        roll_deg,
        stride_px=stride,
    )
    view = build_view(obs, reasons, results, max_side_px, label)
    view.counted_every_px = stride or 1
    return view
