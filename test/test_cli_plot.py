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
``estimate --plot`` on the three kinds of input (issue 25): frame file, raw mosaic, Stokes planes.

Each writes a PNG, and the JSON answer is the same with and without ``--plot`` (the figure only
looks; the one road computes). A file that cannot be written is one line and exit 2.
"""

import json
import math

import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.cli import main
from polarization_compass.conventions import CameraAttitude
from polarization_compass.demosaic import stokes_from_mosaic
from polarization_compass.frame_io import save_frame_npz
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
import pytest

N = 128
F_PX = (N / 2) / (math.pi / 2)
CAM = CameraModel(
    model='fisheye_equidistant',
    width_px=N,
    height_px=N,
    focal_length_mm=F_PX * 3.45e-3,
    max_field_angle_deg=85.0,
)


@pytest.fixture(scope='module')
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp('plot_inputs')
    scene = Scene(
        camera=CAM,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor={
            'mosaic': {'layout': [[90, 45], [135, 0]], 'pol45_toward': '+x-y'},
            'quantization': {'bits': 12},
        },
    )
    f = Renderer(scene).render(
        attitude=CameraAttitude(75.0, 0.0, 0.0), sun=SunDirection(40.0, 40.0), seed=1
    )
    mosaic = np.asarray(f.mosaic, np.uint16)
    np.save(d / 'raw.npy', mosaic)
    s0, s1, s2 = stokes_from_mosaic(mosaic, [[90, 45], [135, 0]], '+x-y', 'superpixel')
    np.savez(d / 'stokes.npz', s0=s0, s1=s1, s2=-s2)  # an SDK's labels: +x-y flips S2
    save_frame_npz(d / 'frame.npz', f)
    c = (N + 1) / 2 - 1
    (d / 'cam.yaml').write_text(
        f'image_width: {N}\nimage_height: {N}\ncamera_name: sim\n'
        f'camera_matrix: {{rows: 3, cols: 3, data: [{F_PX}, 0, {c}, 0, {F_PX}, {c}, 0, 0, 1]}}\n'
        'distortion_model: equidistant\n'
        'distortion_coefficients: {rows: 1, cols: 4, data: [0, 0, 0, 0]}\n'
        'max_field_angle_deg: 85\n'
        "polarizer: {layout: [[90, 45], [135, 0]], pol45_toward: '+x-y'}\n"
    )
    return d


def _estimate(capsys, argv):
    capsys.readouterr()
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    for row in out:  # wall times differ between two runs
        row.pop('time_ms')
        row.get('source', {}).get('polarizer_check', {}).pop('ms', None)
    return out


@pytest.mark.parametrize('name', ['frame.npz', 'raw.npy', 'stokes.npz'])
def test_plot_written_and_answer_unchanged(inputs, capsys, name, tmp_path):
    argv = ['estimate', str(inputs / name), '--method', 'least_squares,zenith']
    if name != 'frame.npz':
        argv += [
            '--camera',
            str(inputs / 'cam.yaml'),
            '--sun-azimuth',
            '40',
            '--sun-altitude',
            '40',
        ]
    plain = _estimate(capsys, argv)
    png = tmp_path / 'fig.png'
    plotted = _estimate(capsys, argv + ['--plot', str(png)])
    assert plotted == plain
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 20_000


def test_unwritable_plot_is_one_line_exit_2(inputs, capsys, tmp_path):
    rc = main(['estimate', str(inputs / 'frame.npz'), '--plot', str(tmp_path / 'no' / 'f.png')])
    err = capsys.readouterr().err
    assert rc == 2 and '--plot: cannot write' in err and len(err.strip().splitlines()) == 1
