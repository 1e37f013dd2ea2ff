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
Lens distortion through OpenCV against its own forward projection.

Rays of plumb_bob / rational_polynomial / equidistant lenses, checked against OpenCV's own forward
projection (cv2.projectPoints / cv2.fisheye.projectPoints) of known rays, and the ideal models as
the zero-coefficient special cases; CAMERA.yaml (ROS camera_calibration).
"""

import math

import cv2
import numpy as np
from polarization_compass.camera import camera_from_intrinsics, CameraError, CameraModel
from polarization_compass.camera_file import load_camera_yaml
import pytest

K = [[1200.0, 0.0, 1230.5], [0.0, 1195.0, 1010.25], [0.0, 0.0, 1.0]]
FISH_K = [[700.0, 0.0, 1220.0], [0.0, 702.0, 1030.0], [0.0, 0.0, 1.0]]


def _known_rays(max_theta_deg, n=400, seed=3):
    rng = np.random.default_rng(seed)
    th = np.radians(rng.uniform(0.5, max_theta_deg, n))
    ph = rng.uniform(-math.pi, math.pi, n)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])


@pytest.mark.parametrize(
    'model,D',
    [
        ('plumb_bob', [-0.28, 0.09, 0.001, -0.0015, -0.012]),
        ('rational_polynomial', [0.4, -0.2, 0.0008, 0.0011, 0.01, 0.7, -0.1, 0.05]),
    ],
)
def test_pinhole_distortion_rays_recover_opencv_projection(model, D):
    cam = camera_from_intrinsics(2448, 2048, K, D, model)
    rays = _known_rays(40.0)
    px, _ = cv2.projectPoints(
        rays.T.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.asarray(K), np.asarray(D)
    )
    px = px.reshape(-1, 2)
    got, ok = cam.rays_from_pixels(px[:, 0] + 1.0, px[:, 1] + 1.0)  # the model is 1-based (eq 20)
    assert ok.all()
    ang = np.degrees(np.arccos(np.clip(np.sum(got * rays, axis=0), -1, 1)))
    assert ang.max() < 1e-4


def test_fisheye_distortion_rays_recover_opencv_projection():
    D = [0.05, -0.02, 0.004, -0.0008]
    cam = camera_from_intrinsics(2448, 2048, FISH_K, D, 'equidistant')
    rays = _known_rays(85.0)
    px, _ = cv2.fisheye.projectPoints(
        rays.T.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), np.asarray(FISH_K), np.asarray(D)
    )
    px = px.reshape(-1, 2)
    got, ok = cam.rays_from_pixels(px[:, 0] + 1.0, px[:, 1] + 1.0)
    assert ok.all()
    ang = np.degrees(np.arccos(np.clip(np.sum(got * rays, axis=0), -1, 1)))
    assert ang.max() < 1e-4


def test_fisheye_rays_follow_the_equidistant_law_and_stop_where_opencv_does():
    """
    Fisheye rays follow the equidistant law and stop where OpenCV does.

    Checked against theta_d = theta (1 + k1 theta^2) written out here, not OpenCV. OpenCV's fisheye
    undistortion clamps theta_d to 90 deg, so pixels beyond it have no ray (never a wrong one).
    """
    k1 = -0.01
    cam = camera_from_intrinsics(
        2448, 2048, FISH_K, [k1, 0, 0, 0], 'equidistant', max_field_angle_deg=100
    )
    th = np.radians(np.array([30.0, 80.0, 91.0, 92.0, 95.0, 99.0]))
    rd = th * (1 + k1 * th**2) * 700.0  # theta_d < 90 deg up to theta ~ 92.3 deg
    x = 1220.0 + rd * math.cos(0.7) + 1.0
    y = 1030.0 + rd * math.sin(0.7) * 702.0 / 700.0 + 1.0
    rays, ok = cam.rays_from_pixels(x, y)
    assert ok.tolist() == [True, True, True, True, False, False]
    rays, th = rays[:, ok], th[ok]
    np.testing.assert_allclose(
        np.degrees(np.arccos(np.clip(rays[2], -1, 1))), np.degrees(th), atol=1e-4
    )
    np.testing.assert_allclose(np.arctan2(rays[1], rays[0]), 0.7, atol=1e-6)


def test_zero_distortion_is_the_ideal_model():
    pin = camera_from_intrinsics(2448, 2048, K, [0, 0, 0, 0, 0], 'plumb_bob')
    assert pin.model == 'pinhole' and not pin.distorted
    eq = camera_from_intrinsics(2448, 2048, FISH_K, [0, 0, 0, 0], 'equidistant')
    assert eq.model == 'fisheye_equidistant' and not eq.distorted
    # the OpenCV route with a vanishing coefficient agrees with the analytic ideal models
    for ideal, dm, D in (
        (pin, 'plumb_bob', [1e-15, 0, 0, 0, 0]),
        (eq, 'equidistant', [1e-15, 0, 0, 0]),
    ):
        cv = camera_from_intrinsics(2448, 2048, ideal.K_matrix(), D, dm)
        assert cv.distorted
        xs, ys = np.meshgrid(np.linspace(100, 2300, 9), np.linspace(100, 1900, 7))
        a, oka = ideal.rays_from_pixels(xs, ys)
        b, okb = cv.rays_from_pixels(xs, ys)
        assert (oka == okb).all()
        np.testing.assert_allclose(a[:, oka], b[:, okb], atol=1e-9)


def test_pixels_from_rays_inverts_rays_from_pixels_with_distortion():
    cam = camera_from_intrinsics(2448, 2048, K, [-0.28, 0.09, 0.001, -0.0015, -0.012], 'plumb_bob')
    xs, ys = np.meshgrid(np.linspace(200, 2200, 6), np.linspace(200, 1800, 5))
    rays, ok = cam.rays_from_pixels(xs, ys)
    x2, y2 = cam.pixels_from_rays(rays[:, ok])
    np.testing.assert_allclose(x2, xs.ravel()[ok], atol=1e-6)
    np.testing.assert_allclose(y2, ys.ravel()[ok], atol=1e-6)


def test_camera_yaml_roundtrip_and_errors(tmp_path):
    p = tmp_path / 'cam.yaml'
    p.write_text(
        'image_width: 2448\nimage_height: 2048\ncamera_name: pol\n'
        'camera_matrix: {rows: 3, cols: 3, data: [1200, 0, 1230.5, 0, 1195, 1010.25, 0, 0, 1]}\n'
        'distortion_model: plumb_bob\n'
        'distortion_coefficients: {rows: 1, cols: 5, data: [-0.28, 0.09, 0.001, -0.0015, '
        '-0.012]}\n'
        "polarizer: {layout: [[0, 45], [135, 90]], pol45_toward: '+x+y'}\n"
    )
    cf = load_camera_yaml(p)
    np.testing.assert_allclose(cf.camera.K_matrix(), K)
    assert cf.camera.distortion == (-0.28, 0.09, 0.001, -0.0015, -0.012)
    assert cf.layout == ((0, 45), (135, 90)) and cf.pol45_toward == '+x+y' and cf.layout_given
    p.write_text(
        'image_width: 10\nimage_height: 10\ncamera_matrix: [1, 0, 5, 0, 1, 5, 0, 0, 1]\n'
        'distortion_model: plumb_bob\ndistortion_coefficients: [0.1, 0.2]\n'
    )
    with pytest.raises(CameraError, match='takes 5 coefficients'):
        load_camera_yaml(p)
    p.write_text('image_width: 10\n')
    with pytest.raises(CameraError, match='image_height'):
        load_camera_yaml(p)
    with pytest.raises(CameraError, match='cannot read'):
        load_camera_yaml(tmp_path / 'missing.yaml')
    with pytest.raises(CameraError, match='distortion_model'):
        CameraModel(distortion_model='kannala', distortion=(0.1,))
