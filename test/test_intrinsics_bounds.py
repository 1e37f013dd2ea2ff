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
Intrinsics from another mode are refused where they enter ``estimate`` (issue 24, item 1).

``estimate --camera`` never checked the intrinsics: on the real ``sunny`` frame a principal point
20 % off gave four methods ``ok`` 18-22 deg off. The camera file now passes the same
:func:`~polarization_compass.camera.check_intrinsics` as a camera_info (node, replay), with the
tighter 10 % bound; the right file still gives the headings.
"""

import math

from polarization_compass.cli import main
import pytest
import real_sky as R


def _yaml(cx, cy, f=None, w=2048, h=2048):
    f = f or R.RADIUS_90_PX / (math.pi / 2)
    return (
        f'image_width: {w}\nimage_height: {h}\n'
        f'camera_matrix: {{rows: 3, cols: 3, data: [{f}, 0, {cx}, 0, {f}, {cy}, 0, 0, 1]}}\n'
        'distortion_model: equidistant\n'
        'distortion_coefficients: {rows: 1, cols: 4, data: [0, 0, 0, 0]}\n'
        'max_field_angle_deg: 88\n'
    )


def _estimate(path, cam, capsys):
    capsys.readouterr()
    rc = main(
        [
            'estimate',
            str(path),
            '--camera',
            str(cam),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            f'{R.sun_altitude_deg("sunny"):.3f}',
            '--method',
            'zenith',
        ]
    )
    return rc, capsys.readouterr()


@pytest.mark.parametrize(
    'dx, dy, scale',
    [
        (0.20 * 2048, 0.0, 1.0),  # 20 % off: four methods ok 18-22 deg off before
        (0.0, -0.24 * 2048, 1.0),  # 24 %: 38-45 deg off
        (None, None, 0.5),  # a K calibrated 2x binned: (cx, cy) and f halved
    ],
)
def test_a_camera_file_from_another_mode_is_refused_with_the_reason(sunny, capsys, dx, dy, scale):
    cx, cy = R.CENTRE_PX
    if scale != 1.0:
        text = _yaml(cx * scale, cy * scale, R.RADIUS_90_PX / (math.pi / 2) * scale)
    else:
        text = _yaml(cx + dx, cy + dy)
    cam = sunny / 'bad.yaml'
    cam.write_text(text)
    rc, out = _estimate(sunny / 'sunny.npz', cam, capsys)
    assert rc == 2 and out.out == ''
    assert 'principal point' in out.err and 'from the centre' in out.err
    assert len(out.err.strip().splitlines()) == 1


def test_the_right_camera_file_still_gives_the_heading(sunny, capsys):
    cam = sunny / 'good.yaml'
    cam.write_text(_yaml(*R.CENTRE_PX))
    rc, out = _estimate(sunny / 'sunny.npz', cam, capsys)
    assert rc == 0
    import json

    (row,) = json.loads(out.out)
    assert row['status'] == 'ok'
    err = math.remainder(row['psi_deg'] - R.expected_psi_deg('sunny'), 360.0)
    assert abs(err) <= 2.0 + 3 * row['sigma_deg']
