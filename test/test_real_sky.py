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
Real sky frames: headings consistent with the visible sun.

Real sky frames (three IMX250MZR fisheye frames, test/data/real-sky, MIT, see LICENSE.ccompass
there): each method gives a heading consistent with the visible sun within the reference's
uncertainty plus 3 sigma, or a non-ok status -- never a wrong ``ok``. The expected heading comes
from the sun's pixel and the package's rotation convention only (``real_sky.expected_psi_deg``);
the polarizer convention is checked by the sky itself (check-polarizer), with the shipped default
and with the flipped one.
"""

import json
import math

import numpy as np
from polarization_compass.cli import main
from polarization_compass.conventions import wrap_180_deg
import pytest
import real_sky as R

OK_STATUSES = ('ok',)


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp('real')
    out = {}
    for stem in R.FRAMES:
        out[stem] = R.write_stokes_npz(d, stem)
    for pol in ('+x-y', '+x+y'):
        (d / f'cam{pol}.yaml').write_text(R.camera_yaml_text(pol))
        out[pol] = d / f'cam{pol}.yaml'
    (d / 'cam_default.yaml').write_text(
        '\n'.join(ln for ln in R.camera_yaml_text().splitlines() if not ln.startswith('polarizer'))
        + '\n'
    )
    out['default'] = d / 'cam_default.yaml'
    return out


def _run(capsys, argv):
    capsys.readouterr()
    rc = main(argv)
    assert rc == 0
    return json.loads(capsys.readouterr().out)


def test_expected_heading_follows_the_sun_pixel():
    """
    The expected heading follows the sun pixel.

    The reference itself: psi of a sun straight 'down' the image (+y) is 0, the sunny frame's sun
    is down-left, so camera +y is clockwise of the sun: psi = atan2(-dx, dy) for a level zenith
    camera.
    """
    (x, y), _ = R.FRAMES['sunny']
    dx, dy = x - R.CENTRE_PX[0], y - R.CENTRE_PX[1]
    assert R.expected_psi_deg('sunny') == pytest.approx(
        math.degrees(math.atan2(-dx, dy)), abs=0.02
    )


@pytest.mark.parametrize('stem', list(R.FRAMES))
def test_the_sky_supports_the_default_polarizer_direction(stem, files, capsys):
    rep = _run(capsys, ['check-polarizer', str(files[stem]), '--camera', str(files['default'])])
    assert rep['configured']['pol45_toward'] == '+x-y' and not rep['configured_in_file']
    assert rep['verdict'] == 'supported', rep['reason']
    assert rep['best']['pol45_toward'] == '+x-y'
    if stem == 'sunny':  # a clear sky decides by a wide margin
        assert rep['margin'] > 0.8


def test_a_flipped_configuration_is_contradicted_with_the_fix(files, capsys):
    rep = _run(
        capsys,
        ['check-polarizer', *(str(files[s]) for s in R.FRAMES), '--camera', str(files['+x+y'])],
    )
    assert rep['verdict'] == 'contradicted'
    assert rep['best']['pol45_toward'] == '+x-y'
    assert "pol45_toward: '+x-y'" in rep['fix']


@pytest.mark.parametrize('pol', ['+x-y', '+x+y'])
@pytest.mark.parametrize('stem', list(R.FRAMES))
def test_every_method_is_right_or_says_it_is_not(stem, pol, files, capsys):
    expected = R.expected_psi_deg(stem)
    _, ref_sigma = R.FRAMES[stem]
    out = _run(
        capsys,
        [
            'estimate',
            str(files[stem]),
            '--camera',
            str(files[pol]),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            f'{R.sun_altitude_deg(stem):.3f}',
            '--method',
            'zenith,sm_asm,symmetry,least_squares',
        ],
    )
    assert len(out) == 4
    n_ok = 0
    for d in out:
        if d['status'] not in OK_STATUSES:
            continue
        n_ok += 1
        err = float(wrap_180_deg(d['psi_deg'] - expected))
        assert d['sigma_deg'] is not None and math.isfinite(d['sigma_deg'])
        assert abs(err) <= ref_sigma + 3 * d['sigma_deg'], (
            d['method'],
            err,
            d['sigma_deg'],
            d['reason'],
        )
    if pol == '+x+y':
        assert n_ok == 0  # the wrong convention: no method may claim a heading
    elif stem == 'sunny':
        assert n_ok >= 3  # the clear sky must actually give headings


def test_bad_real_inputs_exit_2_with_one_line(files, tmp_path, capsys):
    cases = [
        [
            'estimate',
            str(files['sunny']),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ],  # no --camera
        ['estimate', str(files['sunny']), '--camera', str(files['+x-y'])],  # no sun
        [
            'estimate',
            str(tmp_path / 'nothing.png'),
            '--camera',
            str(files['+x-y']),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ],
    ]
    bad = tmp_path / 'bad.npz'
    np.savez(bad, s0=np.ones((4, 4)), s1=np.ones((4, 5)), s2=np.ones((4, 4)))
    cases.append(
        [
            'estimate',
            str(bad),
            '--camera',
            str(files['+x-y']),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    small = tmp_path / 'small.npz'
    np.savez(small, s0=np.ones((10, 10)), s1=np.zeros((10, 10)), s2=np.zeros((10, 10)))
    cases.append(
        [
            'estimate',
            str(small),
            '--camera',
            str(files['+x-y']),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    raw = tmp_path / 'raw.npy'
    np.save(raw, np.full((2048, 2048), 5000, np.uint16))
    cases.append(
        [
            'estimate',
            str(raw),
            '--camera',
            str(files['+x-y']),
            '--bits',
            '12',
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    cases.append(['check-polarizer', str(files['sunny']), '--camera', str(tmp_path / 'none.yaml')])
    import cv2

    cv2.imwrite(
        str(tmp_path / 'colour.png'), np.zeros((2048, 2048, 3), np.uint8)
    )  # a rendering, not raw
    cases.append(
        [
            'estimate',
            str(tmp_path / 'colour.png'),
            '--camera',
            str(files['+x-y']),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    (tmp_path / 'frame.bmp').write_bytes(b'BM')
    cases.append(
        [
            'estimate',
            str(tmp_path / 'frame.bmp'),
            '--camera',
            str(files['+x-y']),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    bad_cam = tmp_path / 'bad_cam.yaml'
    bad_cam.write_text(R.camera_yaml_text().replace('data: [0, 0, 0, 0]', 'data: [0.1, 0.2]'))
    cases.append(
        [
            'estimate',
            str(files['sunny']),
            '--camera',
            str(bad_cam),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    cases.append(
        [
            'estimate',
            str(raw),
            '--camera',
            str(files['+x-y']),
            '--bits',
            '20',
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    mask = tmp_path / 'mask.png'
    cv2.imwrite(str(mask), np.zeros((10, 10), np.uint8))
    cases.append(
        [
            'estimate',
            str(files['sunny']),
            '--camera',
            str(files['+x-y']),
            '--mask',
            str(mask),
            '--sun-azimuth',
            '0',
            '--sun-altitude',
            '30',
        ]
    )
    cases.append(
        ['estimate', str(files['sunny']), '--camera', str(files['+x-y']), '--sun-azimuth', '0']
    )
    for argv in cases:
        capsys.readouterr()
        rc = main(argv)
        err = capsys.readouterr().err.strip()
        assert rc == 2, argv
        assert err and '\n' not in err and 'Traceback' not in err, err
