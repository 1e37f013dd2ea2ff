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

"""Camera intrinsics (eq 20, Table 1), fisheye projection and pixel selections."""

import math

import numpy as np
from polarization_compass.camera import CameraError, CameraModel
from polarization_compass.camera_pixels import PixelSelection, select_pixels
import pytest


def test_table1_imager_has_the_papers_108_degree_field_of_view():
    h, v, d = CameraModel().field_of_view_deg()
    # paper section 3: "the imager angle of view is 108 deg" (the diagonal)
    assert d == pytest.approx(108.0, abs=0.5)
    assert h == pytest.approx(2 * math.degrees(math.atan(2448 * 3.45e-3 / 2 / 4.0)), abs=1e-9)


def test_eq20_rays_written_out():
    cam = CameraModel()
    for x, y in [(1, 1), (2448, 2048), (1000, 77), (1224.5, 1024.5)]:
        v = np.array(
            [3.45e-3 * (x - (2448 + 1) / 2), 3.45e-3 * (y - (2048 + 1) / 2), 4.0]
        )  # eq 20, mm
        r, ok = cam.rays_from_pixels([x], [y])
        np.testing.assert_allclose(r[:, 0], v / np.linalg.norm(v), atol=1e-15)
        assert ok[0]


def test_pinhole_and_fisheye_inverse_projection():
    for cam in (CameraModel(), CameraModel(model='fisheye_equidistant', focal_length_mm=1.8)):
        rng = np.random.default_rng(1)
        x = rng.uniform(1, cam.width_px, 200)
        y = rng.uniform(1, cam.height_px, 200)
        r, ok = cam.rays_from_pixels(x, y)
        xb, yb = cam.pixels_from_rays(r[:, ok])
        np.testing.assert_allclose(xb, x[ok], atol=1e-8)
        np.testing.assert_allclose(yb, y[ok], atol=1e-8)
        np.testing.assert_allclose(np.linalg.norm(r, axis=0), 1.0, atol=1e-12)


def test_fisheye_is_equidistant_and_masks_beyond_its_field():
    cam = CameraModel(
        model='fisheye_equidistant',
        focal_length_mm=1.0,
        width_px=2000,
        height_px=2000,
        max_field_angle_deg=80.0,
    )
    r_mm = np.array([0.1, 0.5, 1.2, 1.5])  # theta = 5.7, 28.6, 68.8, 85.9 deg
    x = cam.cx_px + r_mm / (cam.pixel_pitch_x_um * 1e-3)
    rays, ok = cam.rays_from_pixels(x, np.full_like(x, cam.cy_px))
    theta = np.degrees(np.arccos(np.clip(rays[2], -1, 1)))
    np.testing.assert_allclose(theta, np.degrees(r_mm / 1.0), atol=1e-9)  # r = f * theta
    assert list(ok) == [True, True, True, False]  # 80 deg limit


def test_stride_selection_is_centred_and_cached():
    cam = CameraModel()
    p = select_pixels(cam, PixelSelection.strided(8))
    assert p.shape == (256, 306)
    # symmetric about the principal point to within one pixel (even image, odd offsets)
    assert abs((p.x_px[0, 0] + p.x_px[0, -1]) / 2 - cam.cx_px) <= 1.0
    assert abs((p.y_px[0, 0] + p.y_px[-1, 0]) / 2 - cam.cy_px) <= 1.0
    assert select_pixels(cam, PixelSelection.strided(8)) is p  # rays computed once
    assert not p.rays_cam.flags.writeable


def test_full_grid_and_region_and_list():
    cam = CameraModel(width_px=64, height_px=48)
    full = select_pixels(cam, PixelSelection.full())
    assert full.shape == (48, 64) and full.x_px[0, 0] == 1 and full.x_px[0, -1] == 64
    reg = select_pixels(cam, PixelSelection.rect(10, 5, 8, 6))
    assert reg.shape == (6, 8) and reg.x_px.min() == 10 and reg.y_px.max() == 10
    np.testing.assert_array_equal(
        reg.rays_cam, full.rays_cam.reshape(3, 48, 64)[:, 4:10, 9:17].reshape(3, -1)
    )
    lst = select_pixels(cam, PixelSelection.explicit([3, 64], [1, 48]))
    np.testing.assert_array_equal(lst.rays_cam[:, 1], full.rays_cam[:, -1])


@pytest.mark.parametrize(
    'sel',
    [
        PixelSelection.strided(0),
        PixelSelection.rect(60, 1, 10, 10),
        PixelSelection.explicit([0], [1]),
        PixelSelection.grid(0, 3),
        PixelSelection('bogus'),
    ],
)
def test_bad_selections_raise(sel):
    with pytest.raises(CameraError):
        select_pixels(CameraModel(width_px=64, height_px=48), sel)


@pytest.mark.parametrize(
    'kw',
    [
        {'width_px': 0},
        {'focal_length_mm': -1.0},
        {'model': 'orthographic'},
        {'pixel_pitch_x_um': float('nan')},
    ],
)
def test_bad_intrinsics_raise(kw):
    with pytest.raises(CameraError):
        CameraModel(**kw)
