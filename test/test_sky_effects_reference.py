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
The fused kernels of issue 16's effects against float64 numpy references.

The fused, vectorised kernels of issue 16's effects against straightforward float64 numpy
evaluations of each effect, on both paths of the renderer (the one-pass
polarization_compass.sky_effects over a pixel block, and the stage kernels). Lens effects
(polarization_compass.optics): the formulas of the module
docstring written out per pixel with arccos-like angles and powers, as the first implementation
computed them, on full frames, regions, strided and scattered selections, a pinhole and a fisheye,
glare exponent 2 (the divisions-only path) and another one. Clouds
(polarization_compass.atmosphere): the layer's transmission from ``CloudLayer.density_at`` on every
8th row and column, interpolated with np.interp and composited with the module's formulas.
"""

import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.optics import ghost_centres_px, SUN_SEMIDIAMETER_DEG
from polarization_compass.optics_kernels import _glare_angle_sq_f32
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, Validity
import pytest

FISHEYE = CameraModel(
    model='fisheye_equidistant',
    width_px=400,
    height_px=360,
    focal_length_mm=1.0,
    pixel_pitch_x_um=6.0,
    pixel_pitch_y_um=6.0,
)
PINHOLE = CameraModel(width_px=320, height_px=240)


def angle_between(s, rays):
    """
    Return the angle (rad) between s and each ray, in float64 by atan2.

    Angle (rad) between s and each ray of (3, N), both normalised in float64, by atan2 of |s x p|
    and s.p (arccos of a float32 dot product, as the first implementation used, loses ~1 % near the
    sun).
    """
    p = rays / np.linalg.norm(rays, axis=0)
    s = s / np.linalg.norm(s)
    return np.arctan2(np.linalg.norm(np.cross(s, p.T), axis=1), s @ p)


def reference(frame, clear, camera, optics):
    """(intensity, dop) of the clear frame with ``optics`` applied, float64, per pixel."""
    rays = frame.rays_cam.astype(float)
    x = frame.x_px.reshape(-1).astype(float)
    y = frame.y_px.reshape(-1).astype(float)
    inten = (
        np.ones(x.size) if clear.intensity is None else clear.intensity.reshape(-1).astype(float)
    )
    dop = clear.dop.reshape(-1).astype(float)
    v = np.ones_like(inten)
    vig = optics.get('vignetting')
    if vig and vig.get('law') == 'cos4':
        v = np.maximum(rays[2], 0.0) ** 4
    elif vig:
        k = list(vig['k']) + [0.0] * (3 - len(vig['k']))
        half_diag2 = 0.25 * (camera.width_px**2 + camera.height_px**2)
        q = ((x - camera.cx_px) ** 2 + (y - camera.cy_px) ** 2) / half_diag2
        v = 1 + k[0] * q + k[1] * q**2 + k[2] * q**3
    base = inten * v
    g = np.zeros_like(base)
    s = frame.sun_cam / np.linalg.norm(frame.sun_cam)
    gam = angle_between(s, rays)
    disk_rad = math.radians(SUN_SEMIDIAMETER_DEG)
    if optics.get('sun') is not None:
        p = {'disk_radiance': 2.0e5, 'glare_at_1deg': 30.0, 'glare_exponent': 2.0, **optics['sun']}
        g += np.where(
            gam <= disk_rad,
            p['disk_radiance'],
            p['glare_at_1deg']
            * (math.radians(1.0) / np.maximum(gam, disk_rad)) ** p['glare_exponent'],
        )
    if optics.get('flare') is not None:
        f = {
            'positions': [-0.37, -0.63, -0.83, -1.11],
            'radius_px': 18.0,
            'radiance': 0.6,
            **optics['flare'],
        }
        sx, sy = camera.pixels_from_rays(s.reshape(3, 1))
        for gx, gy in ghost_centres_px(
            (sx[0], sy[0]), (camera.cx_px, camera.cy_px), f['positions']
        ):
            g += np.where((x - gx) ** 2 + (y - gy) ** 2 <= f['radius_px'] ** 2, f['radiance'], 0.0)
    tot = base + g
    return tot, np.where(g > 0, dop * base / np.where(tot > 0, tot, 1.0), dop), gam


def _renderer(scene, path):
    """
    Return a renderer of ``scene`` on the given path: 'fused' (one pass) or 'staged'.

    The renderer takes the one-pass :class:`~polarization_compass.sky_effects.SkyEffects` for a
    pixel block; 'staged' drops it, so that the stage kernels (sky, then clouds, then lens) run and
    are checked against the same references.
    """
    r = Renderer(scene)
    if path == 'staged':
        r.sky_effects = None
    return r


def _render(camera, pixels, optics, sun, att, path='fused'):
    scene = Scene(
        pixels=pixels, camera=camera, sky={'model': 'rayleigh', 'dop_max': 0.8}, optics=optics
    )
    clear = Renderer(scene.replace(optics=None)).render(attitude=att, sun=sun)
    return _renderer(scene, path).render(attitude=att, sun=sun), clear


ALL = {'sun': {}, 'flare': {'radius_px': 9}, 'vignetting': {'law': 'cos4'}}
CASES = [
    (FISHEYE, PixelSelection.full(), ALL, SunDirection(200.0, 55.0), (0, 0, 0)),
    (
        FISHEYE,
        PixelSelection.full(),
        {
            'sun': {'glare_exponent': 2.6, 'glare_at_1deg': 12.0},
            'vignetting': {'k': [-0.3, 0.05, -0.01]},
            'flare': {},
        },
        SunDirection(120.0, 30.0),
        (0, 5, -3),
    ),
    (FISHEYE, PixelSelection.rect(150, 40, 180, 150), ALL, SunDirection(200.0, 55.0), (0, 0, 0)),
    (FISHEYE, PixelSelection.strided(3), ALL, SunDirection(200.0, 55.0), (0, 0, 0)),
    (PINHOLE, PixelSelection.full(), ALL, SunDirection(135.0, 35.0), (135, 30, 0)),
    (
        PINHOLE,
        PixelSelection.explicit(np.arange(1, 320, 2), np.arange(1, 240, 1.5).astype(int)[:160]),
        ALL,
        SunDirection(135.0, 35.0),
        (135, 30, 0),
    ),
]


@pytest.mark.parametrize('path', ['fused', 'staged'])
@pytest.mark.parametrize('case', range(len(CASES)))
def test_fused_optics_equal_the_per_pixel_formulas(case, path):
    camera, pixels, optics, sun, att = CASES[case]
    frame, clear = _render(camera, pixels, optics, sun, cv.CameraAttitude(*att), path)
    inten, dop, gam = reference(frame, clear, camera, optics)
    disk_rad = math.radians(SUN_SEMIDIAMETER_DEG)
    # pixels within 1e-5 rad of the disk edge may fall on either side in float32 (radiance 2e5 vs
    # ~400)
    ok = np.abs(gam - disk_rad) > 1e-5
    assert ok.sum() > 0.99 * ok.size
    got_i = frame.intensity.reshape(-1).astype(float)
    np.testing.assert_allclose(got_i[ok], inten[ok], rtol=3e-5, atol=1e-6)
    np.testing.assert_allclose(frame.dop.reshape(-1)[ok], dop[ok], rtol=3e-5, atol=1e-6)
    np.testing.assert_array_equal(frame.aop_rad, clear.aop_rad)
    if camera is FISHEYE and pixels.mode != 'region':
        assert (
            gam < 3 * disk_rad
        ).any() and inten.max() > 100.0  # the sun is really in the compared frame


def test_glare_angle_chord_form_matches_arccos_in_float64():
    """
    The float32 glare angle matches the angle in float64.

    Gamma^2 from the float32 Cephes asin polynomial in three ranges (2 asin(|p - s| / 2) up to 60
    deg, pi/2 - asin(p.s) to 120 deg, pi - 2 asin(|p + s| / 2) beyond), its square root against
    atan2(|s x p|, s.p) in float64, from 0.0006 deg to 150 deg: relative error < 2e-6.
    """
    from numba import njit

    @njit(cache=False)
    def angles(p, s, out):
        for i in range(p.shape[1]):
            out[i] = math.sqrt(_glare_angle_sq_f32(p[0, i], p[1, i], p[2, i], s[0], s[1], s[2]))

    rng = np.random.default_rng(3)
    gam = np.concatenate(
        [10.0 ** rng.uniform(-5, math.log10(math.pi), 200_000), [math.pi, math.pi / 2, 0.5]]
    )
    phi = rng.uniform(-math.pi, math.pi, gam.size)
    s = np.array([0.3, -0.5, 0.8])
    s /= np.linalg.norm(s)
    e1 = np.cross(s, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(s, e1)
    p = np.cos(gam) * s[:, None] + np.sin(gam) * (
        np.cos(phi) * e1[:, None] + np.sin(phi) * e2[:, None]
    )
    p32, s32 = p.astype(np.float32), s.astype(np.float32)
    out = np.empty(gam.size, np.float32)
    angles(p32, s32, out)
    truth = angle_between(s32.astype(float), p32.astype(float))  # the angle of the rounded vectors
    near = truth < math.radians(150.0)
    np.testing.assert_allclose(out[near], truth[near], rtol=2e-6, atol=1e-9)
    # towards the antisolar point asin(|p - s| / 2) is ill-conditioned in float32: 1e-3 rad there,
    # where the glare is 1e-3 of the clear zenith and its error 1e-9
    np.testing.assert_allclose(out[~near], truth[~near], atol=1e-3)
    np.testing.assert_allclose(out, gam, rtol=1e-3, atol=1e-7)  # and of the exact ones


def _grid(n, step=8):
    return np.unique(np.r_[np.arange(0, n, step), n - 1])


@pytest.mark.parametrize('path', ['fused', 'staged'])
@pytest.mark.parametrize('min_dop', [0.0, 0.12])
def test_cloud_composite_equals_the_numpy_reference(min_dop, path):
    from polarization_compass.atmosphere import CloudLayer

    clouds = {'coverage': 0.5, 'scale_m': 300.0, 'optical_thickness': 2.0, 'brightness': 1.5}
    att = cv.CameraAttitude(30.0, 8.0, -4.0)
    sun = SunDirection(120.0, 40.0)
    scene = Scene(
        camera=FISHEYE,
        sky={'model': 'rayleigh', 'dop_max': 0.8},
        validity=Validity(min_dop=min_dop),
        atmosphere={'clouds': clouds},
        seed=5,
    )
    frame = _renderer(scene, path).render(attitude=att, sun=sun)
    clear = Renderer(scene.replace(atmosphere=None)).render(attitude=att, sun=sun)
    H, W = frame.pixels.shape
    R = cv.R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg)
    enu = (R @ frame.rays_cam.astype(float)).reshape(3, H, W)
    rows, cols = _grid(H), _grid(W)
    e, n, u = (c[np.ix_(rows, cols)] for c in enu)
    layer = CloudLayer(**clouds, seed=(5 * 2654435761 + 1) & 0x7FFFFFFF)
    h = layer.height_m / np.maximum(u, 0.02)
    d = layer.density_at(e * h, n * h).reshape(u.shape)
    tg = np.where(u > 0, np.exp(-layer.optical_thickness * d), 1.0)
    t_cols = np.array(
        [np.interp(np.arange(H), rows, tg[:, j]) for j in range(cols.size)]
    ).T  # (H, grid cols)
    t = np.array([np.interp(np.arange(W), cols, t_cols[i]) for i in range(H)])
    i_clear = 1.0
    inten = i_clear * t + layer.brightness * (1 - t)
    dop = clear.dop.astype(float) * i_clear * t / inten
    valid = clear.valid & (dop >= min_dop)
    assert 0.2 < (t < 0.99).mean() < 0.8  # clouds and clear sky both in the frame
    np.testing.assert_allclose(frame.intensity, inten, rtol=2e-5)
    np.testing.assert_array_equal(frame.valid, valid)
    np.testing.assert_allclose(frame.dop[valid], dop[valid], rtol=2e-5, atol=1e-7)
    np.testing.assert_array_equal(frame.aop_rad[valid], clear.aop_rad[valid])
    assert not frame.dop[~valid].any() and not frame.aop_rad[~valid].any()
    if min_dop > 0:
        assert (
            clear.valid & ~valid
        ).sum() > 0.01 * valid.size  # the minimum DoP really removed pixels
