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
``check-polarizer --plot``: the hypotheses side by side (issue 25).

A Rayleigh sky through a raw mosaic whose +45 deg polarizer points towards +x+y, checked with a
camera file that says +x-y: the picture is written, and its panels are the AoP under each
hypothesis minus that hypothesis' fitted sky -- near zero for the true convention, tens of degrees
for the configured (wrong) one.
"""

import math

import numpy as np
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.conventions import CameraAttitude
from polarization_compass.demosaic import IMX250MZR_LAYOUT, parse_layout
from polarization_compass.polarizer_check import polarizer_hypotheses
from polarization_compass.polarizer_figure import _residual, save_polarizer_figure
from polarization_compass.polarizer_files import check_polarizer_files
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene

N = 128
F_PX = (N / 2) / (math.pi / 2)
CAM = CameraModel(
    model='fisheye_equidistant',
    width_px=N,
    height_px=N,
    focal_length_mm=F_PX * 3.45e-3,
    max_field_angle_deg=85.0,
)


def _camera_yaml(path, pol45):
    c = (N + 1) / 2 - 1  # 0-based principal point of the 1-based centre
    path.write_text(
        f'image_width: {N}\nimage_height: {N}\ncamera_name: sim\n'
        f'camera_matrix: {{rows: 3, cols: 3, data: [{F_PX}, 0, {c}, 0, {F_PX}, {c}, 0, 0, 1]}}\n'
        'distortion_model: equidistant\n'
        'distortion_coefficients: {rows: 1, cols: 4, data: [0, 0, 0, 0]}\n'
        'max_field_angle_deg: 85\n'
        f"polarizer: {{layout: [[90, 45], [135, 0]], pol45_toward: '{pol45}'}}\n"
    )
    return path


def test_true_convention_is_the_white_panel(tmp_path):
    truth = '+x+y'
    layout = parse_layout(IMX250MZR_LAYOUT, truth).angles_deg
    scene = Scene(
        camera=CAM,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor={'mosaic': {'layout': [list(r) for r in layout], 'pol45_toward': truth}},
    )
    f = Renderer(scene).render(
        attitude=CameraAttitude(75.0, 0.0, 0.0), sun=SunDirection(40.0, 40.0), seed=1
    )
    mosaic_path = tmp_path / 'sky.npy'
    np.save(mosaic_path, f.mosaic)
    cam_yaml = _camera_yaml(tmp_path / 'cam.yaml', '+x-y')
    rep = check_polarizer_files([str(mosaic_path)], str(cam_yaml))
    assert rep['verdict'] == 'contradicted'
    out = tmp_path / 'check.png'
    save_polarizer_figure(rep, [str(mosaic_path)], str(cam_yaml), out)
    assert out.stat().st_size > 10_000
    assert rep['best']['pol45_toward'] == truth
    rows = {str(r['hypothesis']): r for r in rep['hypotheses']}
    spread = {}
    for h in polarizer_hypotheses(IMX250MZR_LAYOUT, '+x-y', raw=True):
        fr = rows[str(h.describe())]['frames'][0]
        res = _residual(CAM, ('mosaic', np.load(mosaic_path), None), h, fr, None, 0.0, 0.0)
        spread[str(h.describe())] = float(np.nanmedian(np.abs(res)))
    configured = spread[str(rep['configured'])]
    best = spread[str(rep['best'])]
    assert best < 1.0 and configured > 10.0, spread
