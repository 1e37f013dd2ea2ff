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
Test-only reader for the real sky frames in ``test/data/real-sky`` (ccompass quadrant format).

Each JPEG is 4096 x 4096 8-bit: four 2048 x 2048 quadrants, top-left I = p / 256, top-right
Q = p / 128 - 1, bottom-left U = p / 128 - 1 (the camera SDK's Stokes, Sony's polarizer labels),
bottom-right V (unused). See ``README.md`` in that folder (from /work/shared/data/real-sky) and
``LICENSE.ccompass`` (MIT, (c) 2024 Benjamin Potter).

The expected heading comes from the visible sun's pixel with the package's conventions only:
for a level, zenith-looking camera, the sun's ray in the camera frame is ``R_sun_cam(psi)^T @ S``
(``conventions.R_sun_cam_from_attitude``); for a radially symmetric lens the sun's image direction
from the optical centre is that ray's (x, y) direction, so psi is the angle that puts it there.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

DATA = Path(__file__).parent / 'data' / 'real-sky'

#: lens circle fitted on sunny.jpg (0-based column, row), radius (px) at 90 deg off-axis
CENTRE_PX = (1076.3, 1000.9)
RADIUS_90_PX = 1382.0

#: (file stem, sun pixel (col, row) 0-based, 1-sigma uncertainty of the sun's image direction, deg)
FRAMES = {
    'sunny': ((762.0, 1750.0), 2.0),
    'cloudy': ((375.0, 1380.0), 15.0),
    'image0': ((1950.0, 1362.0), 15.0),
}


def read_quadrants(stem: str):
    """
    Read (I, Q, U) float32 2048 x 2048 of one frame.

    SDK units; Q, U are the camera's Stokes S1, S2.
    """
    im = cv2.imread(str(DATA / f'{stem}.jpg'), cv2.IMREAD_GRAYSCALE)
    assert im is not None and im.shape == (4096, 4096), stem
    n = 2048
    i = im[:n, :n].astype(np.float32) / 256.0
    q = im[:n, n:].astype(np.float32) / 128.0 - 1.0
    u = im[n:, :n].astype(np.float32) / 128.0 - 1.0
    return i, q, u


def write_stokes_npz(directory: Path, stem: str) -> Path:
    """Write one frame's (I, Q, U) as ``<directory>/<stem>.npz`` (s0, s1, s2); return its path."""
    i, q, u = read_quadrants(stem)
    path = Path(directory) / f'{stem}.npz'
    np.savez(path, s0=i, s1=q, s2=u)
    return path


def camera_yaml_text(pol45_toward: str = '+x-y') -> str:
    """
    Return a ROS camera_calibration file for the frames.

    An equidistant fisheye, 90 deg at the lens circle.
    """
    f = RADIUS_90_PX / (math.pi / 2)
    cx, cy = CENTRE_PX
    return (
        f'image_width: 2048\nimage_height: 2048\ncamera_name: ccompass_lucid\n'
        f'camera_matrix: {{rows: 3, cols: 3, data: [{f}, 0, {cx}, 0, {f}, {cy}, 0, 0, 1]}}\n'
        f'distortion_model: equidistant\n'
        f'distortion_coefficients: {{rows: 1, cols: 4, data: [0, 0, 0, 0]}}\n'
        f'max_field_angle_deg: 88\n'
        f"polarizer: {{layout: [[90, 45], [135, 0]], pol45_toward: '{pol45_toward}'}}\n"
    )


def sun_altitude_deg(stem: str) -> float:
    """
    Return the sun altitude implied by its pixel for the equidistant lens.

    A guess: the lens model is not documented.
    """
    (x, y), _ = FRAMES[stem]
    theta = math.hypot(x - CENTRE_PX[0], y - CENTRE_PX[1]) / RADIUS_90_PX * 90.0
    return 90.0 - theta


def expected_psi_deg(stem: str) -> float:
    """
    Psi that puts the sun at its pixel's image direction, from the package's rotation convention.

    Scans psi and keeps the one whose sun ray (camera frame) points along the pixel's direction;
    the convention (eq 21) is all that is used, no estimator code.
    """
    from polarization_compass.conventions import R_sun_cam_from_attitude

    (x, y), _ = FRAMES[stem]
    d = np.array([x - CENTRE_PX[0], y - CENTRE_PX[1]])
    d /= np.linalg.norm(d)
    alt = math.radians(sun_altitude_deg(stem))
    s_a = np.array([0.0, math.cos(alt), math.sin(alt)])  # sun in frame a: y_a at its azimuth
    best, best_err = None, 9.0
    for psi in np.arange(-180.0, 180.0, 0.01):
        s_c = R_sun_cam_from_attitude(psi, 0.0, 0.0).T @ s_a
        v = s_c[:2] / math.hypot(s_c[0], s_c[1])
        err = 1.0 - float(v @ d)
        if err < best_err:
            best, best_err = float(psi), err
    return best
