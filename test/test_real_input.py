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
`estimate` on real-camera file formats, end to end against simulated truth.

The formats: a raw 12-bit mosaic in a 16-bit PNG (--bits 12) and as .npy, the SDK's Stokes planes
as a 3-page TIFF and an .npz, with the sun, its glare and lens-flare ghosts in the field (optics),
a static mask, and a distorted lens described by a ROS camera_calibration file. Every result is
right within 3 sigma (+ 0.5 deg) or not ok.
"""

import json
import math

import cv2
import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.cli import main
from polarization_compass.conventions import CameraAttitude, wrap_180_deg
from polarization_compass.demosaic import stokes_from_mosaic
from polarization_compass.real_input import load_mask, load_polarization_input, RealInputError
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
import pytest

N = 320
F_PX = (N / 2) / (math.pi / 2)
D_FISH = (0.02, -0.005, 0.0, 0.0)
CAM = CameraModel(
    model='fisheye_equidistant',
    width_px=N,
    height_px=N,
    focal_length_mm=F_PX * 3.45e-3,
    principal_x_px=N / 2 + 0.5 + 3.0,
    principal_y_px=N / 2 + 0.5 - 2.0,
    max_field_angle_deg=80.0,
    distortion_model='equidistant',
    distortion=D_FISH,
)
BEARING, SUN_AZ, SUN_ALT = 200.0, 135.0, 50.0
PSI = BEARING - SUN_AZ


def _yaml(cam, pol='+x-y'):
    K = cam.K_matrix()
    return (
        f'image_width: {cam.width_px}\nimage_height: {cam.height_px}\n'
        f'camera_matrix: {{rows: 3, cols: 3, data: {K.reshape(-1).tolist()}}}\n'
        f'distortion_model: {cam.distortion_model}\n'
        f'distortion_coefficients: {{rows: 1, cols: 4, data: {list(cam.distortion)}}}\n'
        f'max_field_angle_deg: {cam.max_field_angle_deg}\n'
        f"polarizer: {{layout: [[90, 45], [135, 0]], pol45_toward: '{pol}'}}\n"
    )


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp('rin')
    scene = Scene(
        camera=CAM,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        optics={'sun': {}, 'flare': {'radius_px': 6, 'radiance': 0.6}},
        sensor={
            'mosaic': {},
            'exposure': {'full_well_e': 10500, 'fill': 0.45},
            'shot_noise': {},
            'quantization': {'bits': 12},
            'demosaic': 'superpixel',
        },
    )
    f = Renderer(scene).render(
        attitude=CameraAttitude(BEARING, 0.0, 0.0), sun=SunDirection(SUN_AZ, SUN_ALT), seed=2
    )
    m = f.mosaic.astype(np.uint16)
    assert (m >= 4095).any()  # the sun saturates, as in a real frame
    out = {'frame': f}
    cv2.imwrite(str(d / 'raw.png'), m)
    np.save(d / 'raw.npy', m)
    s0, s1, s2 = stokes_from_mosaic(m, [[90, 45], [135, 0]], '+x-y', 'superpixel', 4095)
    sdk = [s0, s1, -s2]  # the SDK's S2 = I(45 label) - I(135 label)
    np.savez(d / 'stokes.npz', s0=sdk[0], s1=sdk[1], s2=sdk[2])
    cv2.imwritemulti(str(d / 'stokes.tif'), [p.astype(np.float32) for p in sdk])
    mask = np.full((N, N), 255, np.uint8)
    mask[: N // 5, :] = 0  # a building along the top edge
    cv2.imwrite(str(d / 'mask.png'), mask)
    for pol in ('+x-y', '+x+y'):
        (d / f'cam{pol}.yaml').write_text(_yaml(CAM, pol))
    out.update(
        {
            k: d / v
            for k, v in (
                ('png', 'raw.png'),
                ('npy', 'raw.npy'),
                ('npz', 'stokes.npz'),
                ('tif', 'stokes.tif'),
                ('mask', 'mask.png'),
            )
        }
    )
    out['cam'], out['cam_flipped'] = d / 'cam+x-y.yaml', d / 'cam+x+y.yaml'
    return out


def _estimate(capsys, path, cam, *extra):
    capsys.readouterr()
    rc = main(
        [
            'estimate',
            str(path),
            '--camera',
            str(cam),
            '--sun-azimuth',
            str(SUN_AZ),
            '--sun-altitude',
            str(SUN_ALT),
            '--pitch',
            '0',
            '--roll',
            '0',
            *extra,
        ]
    )
    assert rc == 0
    return json.loads(capsys.readouterr().out)


def test_readers_give_what_was_written(files):
    png = load_polarization_input(files['png'], 12)
    assert png.kind == 'mosaic' and png.mosaic.dtype == np.uint16 and png.saturation_level == 4095
    np.testing.assert_array_equal(png.mosaic, np.load(files['npy']))
    tif, npz = load_polarization_input(files['tif']), load_polarization_input(files['npz'])
    assert tif.kind == npz.kind == 'stokes'
    for a, b in zip(tif.stokes, npz.stokes):
        np.testing.assert_array_equal(a, b)
    mask = load_mask(files['mask'], (N, N))
    assert mask.dtype == bool and not mask[0].any() and mask[-1].all()
    with pytest.raises(RealInputError, match='exceed 10-bit'):
        load_polarization_input(files['png'], 10)


@pytest.mark.parametrize('kind', ['png', 'npy', 'npz', 'tif'])
def test_every_format_gives_the_truth_or_says_not(kind, files, capsys):
    extra = ['--bits', '12'] if kind == 'png' else []
    out = _estimate(capsys, files[kind], files['cam'], *extra, '--mask', str(files['mask']))
    oks = 0
    for d in out:
        if d['status'] != 'ok':
            continue
        oks += 1
        err = float(wrap_180_deg(d['psi_deg'] - PSI))
        assert abs(err) <= 3 * d['sigma_deg'] + 0.5, (
            kind,
            d['method'],
            err,
            d['sigma_deg'],
            d['reason'],
        )
    assert oks >= 3, [(d['method'], d['status'], d['reason']) for d in out]
    assert out[0]['source']['input']['kind'] == ('mosaic' if kind in ('png', 'npy') else 'stokes')


def test_the_wrong_polarizer_direction_is_never_ok(files, capsys):
    out = _estimate(capsys, files['npy'], files['cam_flipped'])
    assert not [d['method'] for d in out if d['status'] == 'ok']
