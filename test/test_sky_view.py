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
The diagnostic figure's layers (issue 25), checked against independent computations.

A small level pinhole camera sees a Rayleigh sky written here from the sun's direction by hand
(E ~ s x v, AoP = atan2(E_x, E_y)); a user mask and saturated pixels are placed where we say. The
rendered figure must colour those pixels with their class's colour (read back from the RGB array
at the data position), and draw the sun where the pinhole formula puts the result's sun.
"""

import math

import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.diagnostic_figure import CLASS_COLOURS, make_figure
from polarization_compass.estimators import HeadingResult, Observation, Status
from polarization_compass.sky_view import build_view, CLASSES, project_sun
import pytest

PSI_DEG, ALT_DEG = 35.0, 70.0
W, H = 120, 100


def _camera():
    return CameraModel(
        width_px=W, height_px=H, focal_length_mm=4.0, pixel_pitch_x_um=60.0, pixel_pitch_y_um=60.0
    )


def _sun_cam(psi_deg, alt_deg):
    """Level camera: the sun lies -psi clockwise from camera +y (z up, x = +y turned clockwise)."""
    p, a = math.radians(psi_deg), math.radians(alt_deg)
    return np.array([-math.cos(a) * math.sin(p), math.cos(a) * math.cos(p), math.sin(a)])


def _observation():
    cam = _camera()
    x, y = np.meshgrid(np.arange(1, W + 1, dtype=float), np.arange(1, H + 1, dtype=float))
    pitch_mm = 60.0e-3
    rays = np.stack(
        [(x - cam.cx_px) * pitch_mm, (y - cam.cy_px) * pitch_mm, np.full(x.shape, 4.0)]
    )
    rays /= np.linalg.norm(rays, axis=0)
    s = _sun_cam(PSI_DEG, ALT_DEG)
    e = np.cross(s, rays.reshape(3, -1).T)
    aop = np.arctan2(e[:, 0], e[:, 1]).reshape(x.shape)
    aop = (aop + np.pi / 2) % np.pi - np.pi / 2
    dop = np.full(x.shape, 0.5, np.float32)
    valid = np.ones(x.shape, bool)
    valid[5:9, 100:110] = False  # no measurement
    return Observation(
        aop.astype(np.float32),
        dop,
        valid,
        rays.reshape(3, -1).astype(np.float32),
        x,
        y,
        cam,
        0.0,
        ALT_DEG,
        None,
        0.0,
        0.0,
    )


def _result(psi=PSI_DEG, status=Status.OK):
    return HeadingResult(
        'least_squares',
        status,
        'test',
        psi_deg=psi,
        bearing_deg=psi % 360,
        yaw_enu_deg=90 - psi,
        sigma_deg=1.0,
        pixels=W * H,
        quality=1.0,
    )


def _view(results=None):
    user = np.zeros((H, W), bool)
    user[60:80, 10:30] = True
    glare = np.zeros((H, W), bool)
    glare[20:30, 40:50] = True
    reasons = {CLASSES.index('user mask'): user, CLASSES.index('saturated sun + glare'): glare}
    return (
        build_view(_observation(), reasons, results or [_result()], max_side_px=400),
        user,
        glare,
    )


def _colour_at(fig, ax, x_px, y_px):
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3]
    dx, dy = ax.transData.transform((x_px, y_px))
    return rgb[int(round(rgb.shape[0] - dy)), int(round(dx))] / 255.0


def test_counts_are_the_masks_sizes():
    view, user, glare = _view()
    assert view.counts[CLASSES.index('user mask')] == user.sum()
    assert view.counts[CLASSES.index('saturated sun + glare')] == glare.sum()
    assert view.counts[CLASSES.index('no measurement (dark, S1 = S2 = 0)')] == 40
    # the sky is the fitted one: nothing off the fit, every other pixel used
    assert (
        view.counts[CLASSES.index('off the fitted sky > 15 deg (noise, cloud, flare ghost)')] == 0
    )
    assert view.counts[0] == W * H - user.sum() - glare.sum() - 40


def test_masked_pixels_have_their_colour_in_the_picture():
    view, _, _ = _view()
    fig = make_figure(view, dpi=100)
    ax = next(a for a in fig.axes if a.get_title().startswith('pixels used and masked'))
    # centres of the masked blocks (1-based pixel = index + 1) and a used pixel
    for (x, y), name in [
        ((20.5, 70.5), 'user mask'),
        ((45.5, 25.5), 'saturated sun + glare'),
        ((105.5, 7.5), 'no measurement (dark, S1 = S2 = 0)'),
        ((90.5, 90.5), 'used'),
    ]:
        got = _colour_at(fig, ax, x, y)
        assert np.allclose(got, CLASS_COLOURS[CLASSES.index(name)], atol=0.02), (name, got)


def test_residual_flags_a_wrong_sky():
    """A fit 40 deg off has large residuals; the true one has none."""
    good, _, _ = _view()
    assert np.nanmax(np.abs(good.residual_deg)) < 1e-3
    bad, _, _ = _view([_result(PSI_DEG + 40.0)])
    assert bad.counts[CLASSES.index('off the fitted sky > 15 deg (noise, cloud, flare ghost)')] > 0


def test_sun_drawn_where_the_pinhole_puts_it():
    cam = _camera()
    s = _sun_cam(PSI_DEG, ALT_DEG)
    x_exp = 4.0 * s[0] / s[2] / 60e-3 + cam.cx_px
    y_exp = 4.0 * s[1] / s[2] / 60e-3 + cam.cy_px
    sun, anti = project_sun(cam, PSI_DEG, ALT_DEG)
    assert sun == pytest.approx((x_exp, y_exp), abs=1e-6)
    assert anti is None  # below the horizon: behind a camera looking up
    view, _, _ = _view()
    fig = make_figure(view)
    stars = [ln for ax in fig.axes for ln in ax.lines if ln.get_marker() == '*']
    assert stars, 'no sun drawn'
    for ln in stars:
        assert (ln.get_xdata()[0], ln.get_ydata()[0]) == pytest.approx((x_exp, y_exp), abs=1e-6)


def test_no_fit_no_residual_and_title_says_why():
    r = HeadingResult.failed('zenith', Status.TOO_FEW_PIXELS, 'only 3 pixels')
    view, _, _ = _view([r])
    assert view.residual_deg is None and view.sun_px is None
    fig = make_figure(view)
    assert 'only 3 pixels' in fig._suptitle.get_text()


def test_quick_picture_has_the_same_layers():
    """The fast renderer (debug image, replay): mask colours and the sun read back."""
    from polarization_compass.diagnostic_rgb import panel_origin_px, quick_rgb, to_panel_px

    view, _, _ = _view()
    width = 640
    img = quick_rgb(view, width)
    c0, r0 = panel_origin_px(view, width, 'classes')
    for (x, y), name in [
        ((20.5, 70.5), 'user mask'),
        ((45.5, 25.5), 'saturated sun + glare'),
        ((90.5, 90.5), 'used'),
    ]:
        px, py = to_panel_px(view, width, x, y)
        got = img[int(r0 + py), int(c0 + px)] / 255.0
        assert np.allclose(got, CLASS_COLOURS[CLASSES.index(name)], atol=0.01), (name, got)
    cam = _camera()
    s = _sun_cam(PSI_DEG, ALT_DEG)
    sx, sy = to_panel_px(
        view, width, 4.0 * s[0] / s[2] / 60e-3 + cam.cx_px, 4.0 * s[1] / s[2] / 60e-3 + cam.cy_px
    )
    c0, r0 = panel_origin_px(view, width, 'dop')
    assert tuple(img[int(round(r0 + sy)), int(round(c0 + sx))]) == (255, 200, 0)


def test_mosaic_reasons_where_the_mosaic_says():
    """Raw mosaic: saturated samples and the fisheye's edge land in their classes, sampled too."""
    from polarization_compass.camera_pixels import PixelSelection
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.pipeline.sun import Sun
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene
    from polarization_compass.sky_view import view_from_mosaic

    n = 128
    f_px = (n / 2) / (math.pi / 2)
    cam = CameraModel(
        model='fisheye_equidistant',
        width_px=n,
        height_px=n,
        focal_length_mm=f_px * 3.45e-3,
        max_field_angle_deg=80.0,
    )
    scene = Scene(
        camera=cam,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor={'mosaic': {}, 'quantization': {'bits': 12}},
    )
    frame = Renderer(scene).render(
        attitude=CameraAttitude(0.0, 0.0, 0.0), sun=SunDirection(30.0, 50.0), seed=2
    )
    m = np.array(frame.mosaic, dtype=np.uint16)
    top = np.iinfo(m.dtype).max
    m[40:50, 60:70] = top  # superpixel rows 20-24, columns 30-34
    glare = CLASSES.index('saturated sun + glare')
    outside = CLASSES.index('outside the lens / no sky')
    for sampled in (False, True):
        view = view_from_mosaic(
            m,
            cam,
            Sun(30.0, 50.0, 'test'),
            [],
            [[90, 45], [135, 0]],
            '+x-y',
            max_side_px=64 if sampled else 400,
            sampled=sampled,
        )
        c = view.classes
        if not sampled:
            assert view.counts[glare] == 25 and (c[20:25, 30:35] == glare).all()
        # independent: the superpixel centre's angle off-axis (equidistant) beyond 80 deg
        step = view.counted_every_px
        x0, x1, y1, y0 = view.extent
        xs = np.linspace(x0, x1, c.shape[1] + 1)[:-1] + (x1 - x0) / c.shape[1] / 2
        ys = np.linspace(y0, y1, c.shape[0] + 1)[:-1] + (y1 - y0) / c.shape[0] / 2
        xg, yg = np.meshgrid(xs, ys)
        theta = np.degrees(np.hypot(xg - cam.cx_px, yg - cam.cy_px) / f_px)
        far, near = theta > 82.0, theta < 78.0  # away from the edge's discretisation
        assert (c[far] == outside).all() and not (c[near] == outside).any(), step
