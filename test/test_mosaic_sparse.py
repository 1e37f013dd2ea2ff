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
The sparse mosaic front end (list/grid selections) against a whole-frame demosaic.

The sparse front end of :func:`observation_from_mosaic` demosaics only the outputs nearest the
wanted pixels (the zenith window and its whole-sky side grid). References, computed here without
``mosaic_input``: the whole frame demosaiced by :mod:`polarization_compass.demosaic`, its pixel
coordinates from the documented output lattice (superpixel block centres ``x0 + 2 l + 0.5``,
bilinear pixels ``x0 + i``), rays from the camera model, and the nearest outputs on either side of
each wanted coordinate found by brute force. Checked: the same values at the same pixels (bitwise:
the same kernels on the same samples), and zenith's psi, sigma, status, reason and extras equal
those from the whole-frame observation on ideal, noisy, tilted and real (test/data/real-sky)
frames.
"""

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel
from polarization_compass.camera_file import load_camera_yaml
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.demosaic import (
    aop_dop_from_stokes,
    IFOV_K_DEFAULT,
    polarization_from_mosaic,
    redundancy_noise,
    stokes_from_mosaic,
)
from polarization_compass.estimators import make_estimator, Observation
from polarization_compass.estimators.mosaic_input import MosaicInputError, observation_from_mosaic
from polarization_compass.mosaic import parse_layout
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene_load import load_scene
import pytest
import real_sky as R

LAYOUT = ((90, 45), (135, 0))
POL45 = '+x-y'


def _dense(
    mosaic, cam, method, origin=(1, 1), with_intensity=False, sat=None, sun=(10.0, 30.0), **obs_kw
):
    """Demosaic the whole frame into an Observation, without mosaic_input (IFOV check on)."""
    x0, y0 = origin
    lay = parse_layout(LAYOUT, POL45).shifted((y0 - 1) % 2, (x0 - 1) % 2)
    check = (IFOV_K_DEFAULT, redundancy_noise(mosaic, lay, lay.pol45_toward, method, sat))
    if with_intensity:
        s0, s1, s2 = stokes_from_mosaic(mosaic, lay, lay.pol45_toward, method, sat, *check)
        aop, dop, valid = aop_dop_from_stokes(s0, s1, s2)
    else:
        aop, dop, valid = polarization_from_mosaic(
            mosaic, lay, lay.pol45_toward, method, sat, *check
        )
        s0 = None
    H, W = aop.shape
    if method == 'superpixel':
        xs, ys = x0 + 2.0 * np.arange(W) + 0.5, y0 + 2.0 * np.arange(H) + 0.5
    else:
        xs, ys = x0 + np.arange(W, dtype=float), y0 + np.arange(H, dtype=float)
    xg, yg = np.meshgrid(xs, ys)
    rays, ok = cam.rays_from_pixels(xg, yg)
    return Observation(
        aop,
        dop,
        valid & ok.reshape(xg.shape),
        np.ascontiguousarray(rays.astype(np.float32)),
        xg,
        yg,
        cam,
        sun[0],
        sun[1],
        intensity=s0,
        **obs_kw,
    )


def _nearest_either_side(axis, wanted):
    """Return the indices into sorted ``axis`` of the last value <= w and the first >= w, all w."""
    keep = set()
    for w in np.unique(wanted):
        below = np.nonzero(axis <= w)[0]
        above = np.nonzero(axis >= w)[0]
        keep.add(int(below[-1]) if below.size else 0)
        keep.add(int(above[0]) if above.size else axis.size - 1)
    return np.array(sorted(keep))


def _wanted(sel, cam):
    """Return the wanted columns and rows of a selection, from its definition."""
    if sel.mode == 'list':
        x = np.frombuffer(sel.x_list, dtype=np.int32)
        y = np.frombuffer(sel.y_list, dtype=np.int32)
        return x, y
    assert sel.mode == 'grid'
    W, H = cam.width_px, cam.height_px
    return (
        np.rint(0.5 + (np.arange(sel.nx) + 0.5) * W / sel.nx),
        np.rint(0.5 + (np.arange(sel.ny) + 0.5) * H / sel.ny),
    )


def _assert_same_pixels(sparse, dense, sel, cam, dop_ulp=0):
    """
    Check that the sparse observation holds exactly the dense outputs nearest the wanted pixels.

    ``dop_ulp``: the fused bilinear kernel's DoP of a float (non-integer) mosaic may differ by a
    few float32 ulp with the pixel's place in its row (its ``fastmath`` lets LLVM contract and
    reassociate the vectorised body and the scalar remainder differently; a region crop shows the
    same). Integer mosaics (every sensor's) have exact Stokes products: no difference.
    """
    wx, wy = _wanted(sel, cam)
    ci = _nearest_either_side(dense.x_px[0], wx)
    ri = _nearest_either_side(dense.y_px[:, 0], wy)
    ix = np.ix_(ri, ci)
    assert np.array_equal(sparse.x_px, dense.x_px[ix])
    assert np.array_equal(sparse.y_px, dense.y_px[ix])
    for name in ('aop_rad', 'dop', 'valid', 'intensity'):
        a, b = getattr(sparse, name), getattr(dense, name)
        if b is None:
            assert a is None
            continue
        assert a.dtype == b.dtype, name
        if name == 'dop' and dop_ulp:
            np.testing.assert_array_max_ulp(a, b[ix], dop_ulp)
        else:
            assert np.array_equal(a, b[ix]), name
    W = dense.aop_rad.shape[1]
    flat = (ri[:, None] * W + ci[None, :]).reshape(-1)
    assert np.array_equal(sparse.rays_cam, dense.rays_cam[:, flat])
    return ri.size * ci.size


def _same_result(a, b):
    """Check every field equal: floats by their shortest round-trip repr, i.e. bitwise."""
    assert a.status == b.status and a.reason == b.reason, (a.reason, b.reason)
    assert (a.psi_deg, a.sigma_deg, a.bearing_deg, a.pixels) == (
        b.psi_deg,
        b.sigma_deg,
        b.bearing_deg,
        b.pixels,
    )
    assert repr(a) == repr(b)


# ------------------------------------------------------------------------------------------------
# the observation: same values at the same pixels
# ------------------------------------------------------------------------------------------------
SMALL = CameraModel(width_px=301, height_px=243, focal_length_mm=1.0)


def _random_mosaic(shape, dtype, rng):
    if np.issubdtype(dtype, np.integer):
        hi = np.iinfo(dtype).max
        m = rng.integers(0, hi, size=shape, endpoint=True).astype(dtype)
        m[rng.random(shape) < 0.01] = hi  # saturated samples
        return m
    m = (rng.random(shape) * 4000.0).astype(dtype)
    m[rng.random(shape) < 0.01] = np.nan
    m[rng.random(shape) < 0.005] = np.inf
    return m


@pytest.mark.parametrize('method', ['superpixel', 'bilinear'])
@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize(
    'origin,shape', [((1, 1), (243, 301)), ((2, 1), (242, 300)), ((40, 31), (117, 153))]
)
def test_sparse_observation_is_the_dense_one_at_the_nearest_outputs(method, dtype, origin, shape):
    rng = np.random.default_rng(7)
    m = _random_mosaic(shape, dtype, rng)
    sels = [
        make_estimator('zenith').pixels_needed(SMALL),
        make_estimator('zenith', window_px=7, side_grid=5).pixels_needed(SMALL),
        PixelSelection.grid(9, 4),
        PixelSelection.explicit(rng.integers(1, 302, 40), rng.integers(1, 244, 40)),
        PixelSelection.explicit([1, 301, 2, 300], [243, 1, 242, 2]),  # sensor corners
    ]
    assert sels[0].mode == 'list'
    for wi in (False, True):
        dense = _dense(m, SMALL, method, origin, wi)
        for sel in sels:
            sparse = observation_from_mosaic(
                m,
                SMALL,
                10.0,
                30.0,
                origin_px=origin,
                method=method,
                selection=sel,
                with_intensity=wi,
                layout=LAYOUT,
                pol45_toward=POL45,
            )
            ulp = 4 * (method == 'bilinear' and m.dtype.kind == 'f')
            n = _assert_same_pixels(sparse, dense, sel, SMALL, ulp)
            assert n < dense.aop_rad.size


def test_a_sparse_selection_outside_the_camera_is_refused():
    m = np.zeros((20, 20), np.uint16)
    cam = CameraModel(width_px=20, height_px=20)
    with pytest.raises(MosaicInputError, match='pixels wanted'):
        observation_from_mosaic(m, cam, 0.0, 30.0, selection=PixelSelection.explicit([21], [3]))


# ------------------------------------------------------------------------------------------------
# zenith on full frames: the same answers as from the whole-frame demosaic
# ------------------------------------------------------------------------------------------------
SCENE = load_scene('config/scenes/imx250mzr_noisy.yaml')


@pytest.fixture(scope='module')
def full_frames():
    """Render full 2448 x 2048 mosaics: ideal (float, no noise), noisy level, tilted, low sun."""
    ideal = SCENE.replace(
        sensor={'mosaic': dict(SCENE.sensor['mosaic']), 'demosaic': 'superpixel'}
    )
    sun = SunDirection(135.0, 35.0)
    out = {}
    for label, sc, (b, p, r) in (
        ('ideal', ideal, (40.0, 0.0, 0.0)),
        ('noisy', SCENE, (160.0, 0.0, 0.0)),
        ('tilted', SCENE, (280.0, 10.0, -5.0)),
        ('low_sun_tilted', SCENE, (75.0, -3.0, 6.0)),
    ):
        s = sun if label != 'low_sun_tilted' else SunDirection(135.0, 4.0)
        f = Renderer(sc).render(attitude=cv.CameraAttitude(b, p, r), sun=s, seed=5)
        assert f.mosaic is not None and f.mosaic.shape == (2048, 2448)
        out[label] = (f.mosaic, s, b, p, r, f.psi_deg)
    return out


def _real_mosaic(stem):
    """Make a 12-bit mosaic of a real frame's Stokes planes (I_phi = (S0 + w . (S1, S2)) / 2)."""
    i, q, u = R.read_quadrants(stem)
    w = parse_layout(LAYOUT, POL45).stokes_weights()
    wi = np.tile(w, (i.shape[0] // 2, i.shape[1] // 2, 1))  # (H, W, 2) per pixel
    sample = 0.5 * (i + wi[..., 0] * q + wi[..., 1] * u)
    return np.clip(np.rint(sample * 4000.0), 0, 4095).astype(np.uint16)


def _compare_zenith(m, cam, sun_az, sun_alt, knobs, method='superpixel', **obs_kw):
    est = make_estimator('zenith', **knobs)
    sel = est.pixels_needed(cam)
    results = []
    sat = 4095.0 if m.dtype == np.uint16 else None  # 12-bit data; float: no saturation
    ulp = 4 * (method == 'bilinear' and m.dtype.kind == 'f')  # see _assert_same_pixels
    for wi in (False, True):
        dense = _dense(m, cam, method, with_intensity=wi, sat=sat, sun=(sun_az, sun_alt), **obs_kw)
        sparse = observation_from_mosaic(
            m,
            cam,
            sun_az,
            sun_alt,
            method=method,
            selection=sel,
            with_intensity=wi,
            saturation_level=sat,
            layout=LAYOUT,
            pol45_toward=POL45,
            **obs_kw,
        )
        _assert_same_pixels(sparse, dense, sel, cam, ulp)
        assert sparse.aop_rad.size < 0.01 * dense.aop_rad.size  # cost scales with pixels read
        for sigma in (True, False):
            a, b = est.estimate(sparse, sigma=sigma), est.estimate(dense, sigma=sigma)
            _same_result(a, b)
            results.append(a)
    return results


@pytest.mark.parametrize('label', ['ideal', 'noisy', 'tilted', 'low_sun_tilted'])
def test_zenith_on_a_full_frame_gives_the_dense_answer(full_frames, label):
    m, sun, b, p, r, psi = full_frames[label]
    cam = SCENE.camera
    assert m.dtype == (np.float32 if label == 'ideal' else np.uint16)
    res = []
    for obs_kw in ({}, {'pitch_deg': p, 'roll_deg': r}, {'prior_bearing_deg': b + 20.0}):
        res += _compare_zenith(m, cam, sun.azimuth_deg, sun.altitude_deg, {}, **obs_kw)
    knobs = {'window_px': 64, 'side_grid': 20}
    res += _compare_zenith(m, cam, sun.azimuth_deg, sun.altitude_deg, knobs, method='bilinear')
    ok = [x for x in res if x.status.value == 'ok']
    assert ok  # the comparison covers real answers, not only failures
    if label in ('ideal', 'noisy'):  # level: the answer is also right
        for x in ok:
            assert abs(float(cv.wrap_180_deg(x.psi_deg - psi))) < 0.5, (x.psi_deg, psi)


@pytest.mark.parametrize('stem', list(R.FRAMES))
def test_zenith_on_real_frames_gives_the_dense_answer(stem, tmp_path):
    (tmp_path / 'cam.yaml').write_text(R.camera_yaml_text(POL45))
    cam = load_camera_yaml(tmp_path / 'cam.yaml').camera
    m = _real_mosaic(stem)
    res = _compare_zenith(m, cam, 0.0, R.sun_altitude_deg(stem), {})
    res += _compare_zenith(m, cam, 0.0, R.sun_altitude_deg(stem), {}, method='bilinear')
    if stem == 'sunny':  # the clear frame gives a heading (the sun side from the whole sky)
        assert any(x.status.value == 'ok' for x in res)
