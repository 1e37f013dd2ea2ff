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
Readout flips are part of the camera model (issue 24, item 2).

A camera that mirrors its readout (GenICam ReverseX/ReverseY) delivers a mirrored image: a
polarizer layout cannot undo the mirrored geometry (every heading came out as -psi, or 180 deg off
for the 180 deg readout, with status ``ok``). ``readout_flip`` in CAMERA.yaml reads the image as
the sensor sees it, with the file's K (calibrated on the delivered images) mirrored with it, and
the sensor's own polarizer; the simulated truth is recovered. ``check-polarizer`` names the flip
as the fix for a mirror it sees.
"""

import json

from conftest import FisheyeSky
import numpy as np
from polarization_compass.cli import main
from polarization_compass.conventions import wrap_180_deg
from polarization_compass.headings import estimate_file, EstimateOptions
import pytest

N = 160
CX, CY = (N + 1) / 2 + 8.0, (N + 1) / 2 - 5.0  # 1-based, off-centre so a mirror matters
CAM = FisheyeSky.camera(N, (CX, CY))
PSI, SUN_ALT = 35.0, 30.0


def delivered(flip):
    """Render the sensor (IMX250MZR as delivered, native) and mirror it as the readout does."""
    m = FisheyeSky.mosaic(CAM, [[90, 45], [135, 0]], '+x-y', PSI, 0.0, SUN_ALT, 2)
    if 'x' in flip:
        m = m[:, ::-1]
    if 'y' in flip:
        m = m[::-1, :]
    return np.ascontiguousarray(m)


def yaml_text(flip, extra=''):
    """Write the calibration of the delivered images (the readout mirrors the principal point)."""
    cx0, cy0 = CX - 1, CY - 1
    if 'x' in flip:
        cx0 = N - 1 - cx0
    if 'y' in flip:
        cy0 = N - 1 - cy0
    f = CAM.K_matrix()[0, 0]
    return FisheyeSky.camera_yaml(N, [[f, 0, cx0], [0, f, cy0], [0, 0, 1]], extra)


@pytest.mark.parametrize('flip', ['x', 'y', 'xy'])
def test_a_flipped_readout_with_readout_flip_gives_the_true_heading(tmp_path, flip):
    np.save(tmp_path / 'm.npy', delivered(flip))
    (tmp_path / 'cam.yaml').write_text(yaml_text(flip, f'readout_flip: {flip}\n'))
    rows = estimate_file(
        tmp_path / 'm.npy',
        EstimateOptions(
            methods=['zenith', 'sm_asm', 'least_squares'],
            camera_yaml=str(tmp_path / 'cam.yaml'),
            sun_azimuth_deg=0.0,
            sun_altitude_deg=SUN_ALT,
        ),
    )
    oks = [d for d in rows if d['status'] == 'ok']
    assert len(oks) >= 2, rows
    for d in oks:
        assert abs(float(wrap_180_deg(d['psi_deg'] - PSI))) < 1.0, d


def test_check_polarizer_proposes_the_readout_flip_for_a_mirror(tmp_path, capsys):
    np.save(tmp_path / 'm.npy', delivered('x'))
    (tmp_path / 'cam.yaml').write_text(yaml_text('x'))  # the flip not configured
    capsys.readouterr()
    argv = ['check-polarizer', str(tmp_path / 'm.npy'), '--camera', str(tmp_path / 'cam.yaml')]
    assert main(argv) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep['verdict'] == 'contradicted'
    assert 'readout_flip: x, y or xy' in rep['fix']
    # and with the flip configured, the sensor's own convention is supported
    (tmp_path / 'cam.yaml').write_text(yaml_text('x', 'readout_flip: x\n'))
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)['verdict'] == 'supported'
