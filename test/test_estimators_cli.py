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

"""The estimate command (in-process main([...]) calls) and the mosaic front-end."""

import json
import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.cli import main
from polarization_compass.estimators import make_estimator
from polarization_compass.estimators.mosaic_input import MosaicInputError, observation_from_mosaic
from polarization_compass.frame_io import save_frame_npz
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
from polarization_compass.scene_load import load_scene
import pytest

KEYS = {
    'method',
    'psi_deg',
    'bearing_deg',
    'yaw_enu_deg',
    'sigma_deg',
    'pixels',
    'status',
    'reason',
}


def _run(capsys, argv):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope='module')
def ideal_frame(tmp_path_factory):
    f = Renderer(Scene(pixels=PixelSelection.strided(4))).render(
        attitude=cv.CameraAttitude(170.0, -8.0, 5.0), sun=SunDirection(100.0, 35.0)
    )
    p = tmp_path_factory.mktemp('est') / 'ideal.npz'
    save_frame_npz(p, f)
    return p, f


def test_estimate_all_methods_json(capsys, ideal_frame):
    path, f = ideal_frame
    code, out, err = _run(
        capsys, ['estimate', str(path), '--method', 'all', '--pitch', '-8', '--roll', '5']
    )
    assert code == 0, err
    rows = json.loads(out)
    assert [r['method'] for r in rows] == [
        'zenith',
        'sm_asm',
        'symmetry',
        'least_squares',
        'tilt_aware',
    ]
    for r in rows:
        assert KEYS <= set(r)
        assert r['status'] in ('ok', 'ambiguous')
        for k in ('psi_deg', 'bearing_deg', 'yaw_enu_deg', 'sigma_deg'):
            assert math.isfinite(r[k])
        assert abs(cv.wrap_180_deg(r['yaw_enu_deg'] - (90.0 - r['bearing_deg']))) < 1e-9
        assert abs(cv.wrap_180_deg(r['bearing_deg'] - (r['psi_deg'] + 100.0))) < 1e-9
    ta = rows[-1]
    assert ta['status'] == 'ok' and abs(cv.wrap_180_deg(ta['bearing_deg'] - 170.0)) < 0.01
    assert abs(ta['error_deg']) < 0.01 and ta['source']['input'] == 'stored AoP/DoP'


def test_tilt_aware_without_tilt_says_why(capsys, ideal_frame):
    path, _ = ideal_frame
    code, out, _ = _run(capsys, ['estimate', str(path), '--method', 'tilt_aware'])
    assert code == 0
    (row,) = json.loads(out)
    assert row['status'] == 'bad_input' and 'pitch' in row['reason'] and row['psi_deg'] is None


def test_prior_and_stride_and_knobs(capsys, ideal_frame):
    path, _ = ideal_frame
    code, out, err = _run(
        capsys,
        [
            'estimate',
            str(path),
            '--method',
            'zenith,sm_asm',
            '--prior-bearing',
            '160',
            '--stride',
            '16',
            '--knob',
            'min_dop=0.05',
        ],
    )
    assert code == 0, err
    rows = json.loads(out)
    assert rows[1]['knobs'] == {'min_dop': 0.05, 'stride': 16}
    for r in rows:
        assert r['status'] == 'ok' and r['extras']['ambiguity_resolved_by'] == 'prior'


@pytest.mark.parametrize(
    'argv,msg',
    [
        (['--method', 'hough'], 'unknown'),
        (['--knob', 'nonsense=1'], 'no selected method'),
        (['--knob', 'min_dop=7'], 'min_dop'),
        (['--pitch', '3'], 'go together'),
        (['--stride', '0'], 'stride'),
        (['--pitch', 'nan', '--roll', '0'], 'pitch'),
        (['--ifov-k', '-1'], '--ifov-k'),
        (['--ifov-k', '0.5'], '--ifov-k'),
        (['--ifov-k', 'nan'], '--ifov-k'),
    ],
)
def test_bad_arguments_exit_2(capsys, ideal_frame, argv, msg):
    path, _ = ideal_frame
    code, out, err = _run(capsys, ['estimate', str(path)] + argv)
    assert code == 2 and msg in err and out == ''


def test_missing_sun_needs_site_and_time(capsys, tmp_path, ideal_frame):
    _, f = ideal_frame
    f2 = Renderer(Scene(pixels=PixelSelection.strided(8))).render(
        attitude=cv.CameraAttitude(30.0, 0.0, 0.0), sun=SunDirection(100.0, 35.0)
    )
    f2.meta = {k: v for k, v in f2.meta.items() if not k.startswith('sun')}
    p = save_frame_npz(tmp_path / 'nosun.npz', f2)
    code, _, err = _run(capsys, ['estimate', str(p), '--method', 'least_squares'])
    assert code == 2 and '--lat' in err
    code, out, err = _run(
        capsys,
        [
            'estimate',
            str(p),
            '--method',
            'least_squares',
            '--lat',
            '32',
            '--lon',
            '118.8',
            '--time',
            '2019-11-15T06:00:00Z',
        ],
    )
    assert code == 0, err
    (row,) = json.loads(out)
    assert row['source']['sun'].startswith('ephemeris') and row['psi_deg'] is not None


def test_missing_file_exit_2(capsys, tmp_path):
    code, _, err = _run(capsys, ['estimate', str(tmp_path / 'nope.npz')])
    assert code == 2 and 'nope.npz' in err


def test_mosaic_frame_is_demosaiced(capsys, tmp_path):
    scene = load_scene('config/scenes/imx250mzr_noisy.yaml')
    scene = scene.replace(pixels=PixelSelection.rect(905, 705, 640, 640))
    f = Renderer(scene).render(
        attitude=cv.CameraAttitude(40.0, 0.0, 0.0), sun=SunDirection(0.0, 30.0), seed=2
    )
    p = save_frame_npz(tmp_path / 'noisy.npz', f)
    code, out, err = _run(
        capsys,
        ['estimate', str(p), '--method', 'least_squares,zenith', '--pitch', '0', '--roll', '0'],
    )
    assert code == 0, err
    rows = json.loads(out)
    src = rows[0]['source']['input']
    assert src['demosaic'] == 'superpixel' and src['mosaic'] == [640, 640] and src['assumed'] == []
    ls = rows[0]
    assert ls['status'] == 'ok' and abs(ls['error_deg']) < 6 * ls['sigma_deg'] + 0.01
    code, out, _ = _run(
        capsys,
        [
            'estimate',
            str(p),
            '--method',
            'least_squares',
            '--pitch',
            '0',
            '--roll',
            '0',
            '--use-stored',
        ],
    )
    stored = json.loads(out)[0]
    assert (
        stored['source']['input'].startswith('stored')
        and abs(stored['psi_deg'] - ls['psi_deg']) < 1e-9
    )


# --------------------------------------------------------------------------------------------
# Mosaic front-end
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def noisy_full():
    out = {}
    sc = load_scene('config/scenes/imx250mzr_noisy.yaml')
    for demo in ('superpixel', 'bilinear'):
        r = Renderer(
            sc.replace(
                sensor=dict(sc.sensor, demosaic=demo),
                pixels=PixelSelection.rect(601, 401, 1248, 1248),
            )
        )
        out[demo] = r.render(
            attitude=cv.CameraAttitude(30.0, 0.0, 0.0), sun=SunDirection(0.0, 40.0), seed=3
        )
    return sc, out


@pytest.mark.parametrize('demo', ['superpixel', 'bilinear'])
def test_mosaic_front_end_reads_the_same_pixels(noisy_full, demo):
    sc, frames = noisy_full
    f = frames[demo]
    origin = (601, 401)
    full = observation_from_mosaic(
        f.mosaic, sc.camera, 0.0, 40.0, origin_px=origin, method=demo, saturation_level=4095
    )
    assert np.array_equal(full.aop_rad, f.aop_rad) and np.array_equal(full.x_px, f.x_px)
    assert np.allclose(full.rays_cam, f.rays_cam, atol=1e-7)
    # zenith with its whole-sky side grid wants an explicit pixel list: the front end demosaics
    # only the rendered outputs nearest its pixels (test_mosaic_sparse.py checks which); zenith's
    # answer is the one from the whole mosaic
    est = make_estimator('zenith')
    sel = est.pixels_needed(sc.camera)
    assert sel.mode == 'list'
    sub = observation_from_mosaic(
        f.mosaic,
        sc.camera,
        0.0,
        40.0,
        origin_px=origin,
        method=demo,
        selection=sel,
        saturation_level=4095,
    )
    ci = np.searchsorted(f.x_px[0], sub.x_px[0])
    ri = np.searchsorted(f.y_px[:, 0], sub.y_px[:, 0])
    assert np.array_equal(f.x_px[0][ci], sub.x_px[0])
    assert np.array_equal(f.y_px[:, 0][ri], sub.y_px[:, 0])
    assert np.array_equal(sub.aop_rad, f.aop_rad[np.ix_(ri, ci)])
    assert sub.aop_rad.size < 0.1 * f.aop_rad.size
    assert repr(est.estimate(sub)) == repr(est.estimate(full))
    for name, kn in (
        ('zenith', {'side_grid': 0}),
        ('sm_asm', {'stride': 8}),
        ('least_squares', {'stride': 12}),
    ):
        sel = make_estimator(name, **kn).pixels_needed(sc.camera)
        sub = observation_from_mosaic(
            f.mosaic,
            sc.camera,
            0.0,
            40.0,
            origin_px=origin,
            method=demo,
            selection=sel,
            saturation_level=4095,
        )
        ci = np.searchsorted(f.x_px[0], sub.x_px[0])
        ri = np.searchsorted(f.y_px[:, 0], sub.y_px[:, 0])
        assert np.allclose(f.x_px[0][ci], sub.x_px[0]) and np.allclose(
            f.y_px[:, 0][ri], sub.y_px[:, 0]
        )
        both = sub.valid & f.valid[np.ix_(ri, ci)]
        assert both.sum() > 0.5 * sub.valid.size
        assert np.array_equal(sub.aop_rad[both], f.aop_rad[np.ix_(ri, ci)][both])
        assert sub.aop_rad.size < f.aop_rad.size


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32, np.float64, np.int32])
@pytest.mark.parametrize('shape', [(12, 16), (13, 17)])
@pytest.mark.parametrize('k', [1, 2, 3])
def test_superpixel_block_gather_matches_indexing(dtype, shape, k):
    """The wide-element gather of strided 2 x 2 blocks equals indexing their four samples."""
    from polarization_compass.estimators.mosaic_input import _superpixel_blocks

    m = (np.arange(shape[0] * shape[1]) * 7 % 251).reshape(shape).astype(dtype)
    rows, cols = np.arange(1, shape[0] // 2, k), np.arange(0, shape[1] // 2, k)
    got = _superpixel_blocks(m, rows, cols, k)
    want = np.empty((2 * rows.size, 2 * cols.size), dtype)
    for a, r in enumerate(rows):
        for b, c in enumerate(cols):
            want[2 * a : 2 * a + 2, 2 * b : 2 * b + 2] = m[2 * r : 2 * r + 2, 2 * c : 2 * c + 2]
    assert got.dtype == m.dtype and got.flags.c_contiguous
    assert np.array_equal(got, want)


def test_mosaic_front_end_rejects_bad_input():
    sc = load_scene('config/scenes/imx250mzr_noisy.yaml')
    with pytest.raises(MosaicInputError, match='does not fit'):
        observation_from_mosaic(
            np.zeros((10, 10), np.uint16), sc.camera, 0, 30, origin_px=(2445, 1)
        )
    with pytest.raises(MosaicInputError, match='2-D'):
        observation_from_mosaic(np.zeros(10, np.uint16), sc.camera, 0, 30)
    with pytest.raises(MosaicInputError, match='superpixel or bilinear'):
        observation_from_mosaic(np.zeros((10, 10), np.uint16), sc.camera, 0, 30, method='nearest')
