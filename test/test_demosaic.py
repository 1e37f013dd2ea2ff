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
Demosaicing against closed forms and an OpenCV reference.

The closed forms: Malus's law on uniform patches (written with dot products, not Stokes), numpy's
arctan2, an OpenCV per-channel bilinear reference, exactness on linear fields, and the awkward
inputs (odd sizes, integer/float, NaN, all-zero, saturated).
"""

import itertools
import math

import cv2
from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass.conventions import fold_axial_rad
from polarization_compass.demosaic import (
    aop_dop_from_stokes,
    polarization_from_mosaic,
    stokes_from_mosaic,
)
from polarization_compass.mosaic import (
    IMX250MZR_LAYOUT,
    IMX250MZR_POL45,
    MosaicLayout,
    parse_layout,
    SensorError,
)
import pytest

LAYOUTS = [((p[0], p[1]), (p[2], p[3])) for p in itertools.permutations((0, 45, 90, 135))]
METHODS = ('superpixel', 'bilinear')


def axis_cam(theta_deg, pol45_toward):
    """
    Return the unit transmission axis of a polarizer at theta, in the camera frame.

    Unit transmission axis (x, y) in the camera frame of a polarizer at theta from +x towards
    pol45.
    """
    t = math.radians(theta_deg)
    return np.array([math.cos(t), math.sin(t) if pol45_toward == '+x+y' else -math.sin(t)])


def malus_mosaic(shape, aop_rad, dop, s0, layout, pol45_toward):
    """
    Build a mosaic by Malus's law from AoP, DoP and S0.

    Each pixel: unpolarized half of (1 - P) S0 plus P S0 cos^2(E, axis), E = (sin a, cos a) (eq
    28).
    """
    e = np.array([math.sin(aop_rad), math.cos(aop_rad)])
    m = np.empty(shape)
    for r in range(2):
        for c in range(2):
            u = axis_cam(layout[r][c], pol45_toward)
            m[r::2, c::2] = s0 * (1 - dop) / 2 + s0 * dop * float(e @ u) ** 2
    return m


def ang_err_deg(a, b):
    return np.degrees(np.abs(fold_axial_rad(np.asarray(a, float) - np.asarray(b, float))))


@given(
    st.floats(-math.pi / 2, math.pi / 2 - 1e-6),
    st.floats(0.02, 1.0),
    st.floats(1.0, 3000.0),
    st.sampled_from(LAYOUTS),
    st.sampled_from(('+x+y', '+x-y')),
    st.sampled_from(METHODS),
    st.integers(2, 9),
    st.integers(2, 9),
)
def test_uniform_patch_gives_the_angle_of_the_e_vector(aop, dop, s0, layout, pol, method, h, w):
    m = malus_mosaic((h, w), aop, dop, s0, layout, pol)
    a, d, ok = polarization_from_mosaic(m, layout, pol, method)
    assert a.shape == ((h // 2, w // 2) if method == 'superpixel' else (h, w))
    assert ok.all()
    assert ang_err_deg(a, aop).max() < 2e-4 / dop + 1e-4
    np.testing.assert_allclose(d, dop, atol=2e-6)
    assert np.all((a >= -np.pi / 2) & (a < np.pi / 2))


@given(
    st.floats(-math.pi / 2, math.pi / 2),
    st.floats(0.0, 1.0),
    st.floats(1.0, 1000.0),
    st.sampled_from(LAYOUTS),
    st.sampled_from(('+x+y', '+x-y')),
    st.sampled_from(METHODS),
)
def test_stokes_of_a_uniform_patch_match_the_closed_form(aop, dop, s0, layout, pol, method):
    """
    Camera-frame Stokes of a uniform patch match the closed form.

    Camera-frame Stokes: S1 = S0 P cos 2b, S2 = S0 P sin 2b, b the E-vector's angle from +x to +y.
    """
    m = malus_mosaic((6, 8), aop, dop, s0, layout, pol)
    S0, S1, S2 = stokes_from_mosaic(m, layout, pol, method)
    beta = math.atan2(math.cos(aop), math.sin(aop))
    if dop * s0 < 1e-3:  # unpolarized: AoP undefined, the pixel is marked invalid (zeros)
        return
    np.testing.assert_allclose(S0, s0, rtol=1e-6)
    np.testing.assert_allclose(S1, s0 * dop * math.cos(2 * beta), atol=2e-6 * s0)
    np.testing.assert_allclose(S2, s0 * dop * math.sin(2 * beta), atol=2e-6 * s0)


def test_wrong_pol45_direction_mirrors_the_angle():
    """The test above can fail: reading a '+x+y' sensor as '+x-y' mirrors AoP about the y axis."""
    m = malus_mosaic((4, 4), math.radians(30), 0.5, 100, IMX250MZR_LAYOUT, '+x+y')
    a, _, _ = polarization_from_mosaic(m, IMX250MZR_LAYOUT, '+x-y')
    np.testing.assert_allclose(np.degrees(a), -30, atol=1e-4)


def test_aop_dop_from_stokes_against_numpy():
    rng = np.random.default_rng(3)
    s1, s2 = rng.normal(size=(2, 50000)).astype(np.float32)
    s0 = (np.hypot(s1, s2) * rng.uniform(0.8, 3, 50000)).astype(np.float32)
    a, d, ok = aop_dop_from_stokes(s0, s1, s2)
    # the other formula: AoLP from +x, then 90 deg minus it (physics notes 1)
    ref = np.pi / 2 - 0.5 * np.arctan2(s2.astype(float), s1.astype(float))
    assert ok.all()
    assert ang_err_deg(a, ref).max() < 2e-5
    np.testing.assert_allclose(d, np.minimum(np.hypot(s1, s2) / s0, 1), rtol=2e-6)
    assert np.all((a >= -np.pi / 2) & (a < np.pi / 2))


@pytest.mark.parametrize(
    's1, s2',
    [(0.0, 1.0), (-0.0, 1.0), (0.0, -1.0), (-0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (-1.0, -0.0)],
)
def test_stokes_on_the_axes_give_the_exact_angle(s1, s2):
    """
    Stokes on the axes give the exact angle.

    Exact zeros (integer mosaics tie often): same answer as the arctan2 reference, AoP +-45 deg
    kept apart.
    """
    a, d, ok = aop_dop_from_stokes(np.float32([2.0]), np.float32([s1]), np.float32([s2]))
    ref = np.pi / 2 - 0.5 * math.atan2(s2, s1)
    assert ok.all()
    assert ang_err_deg(a, ref).max() < 1e-5, (np.degrees(a), math.degrees(ref))


@pytest.mark.parametrize('aop_deg', [45.0, -45.0])
@pytest.mark.parametrize('method', METHODS)
def test_integer_mosaic_with_a_tie_keeps_the_sign_of_45_deg(aop_deg, method):
    """Rounded to integer counts, the 0 and 90 deg samples tie exactly (S1 = 0)."""
    m = np.round(
        malus_mosaic((4, 4), math.radians(aop_deg), 0.5, 1000.0, IMX250MZR_LAYOUT, '+x+y')
    )
    a, d, ok = polarization_from_mosaic(m.astype(np.uint16), IMX250MZR_LAYOUT, '+x+y', method)
    assert ok.all()
    assert ang_err_deg(a, math.radians(aop_deg)).max() < 0.1


def test_aop_at_the_branch_cut_is_folded_into_range():
    # AoP = +-90 deg: E along x. S1 > 0, S2 = +-0 -> AoP must be -pi/2 exactly, never +pi/2
    a, d, ok = aop_dop_from_stokes(
        np.float32([2, 2, 2]), np.float32([1, 1, 1]), np.float32([0.0, -0.0, 1e-30])
    )
    assert ok.all() and np.all(a >= -np.pi / 2) and np.all(a < np.pi / 2)
    np.testing.assert_allclose(np.abs(a), np.pi / 2, atol=1e-6)


def test_stokes_validity_never_gives_nan():
    s0 = np.float32([0, -1, 1, 1, np.nan, 1, np.inf, 1])
    s1 = np.float32([0, 0.5, 0, np.nan, 0.1, np.inf, 0.1, 0.2])
    s2 = np.float32([0, 0.5, 0, 0.1, 0.1, 0.1, 0.1, 0.1])
    a, d, ok = aop_dop_from_stokes(s0, s1, s2)
    assert ok.tolist() == [False] * 7 + [True]
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(d))
    assert np.all(a[~ok] == 0) and np.all(d[~ok] == 0)
    with pytest.raises(SensorError, match='same shape'):
        aop_dop_from_stokes(np.zeros(3), np.zeros(3), np.zeros(4))


def _bilinear_reference(m, layout, pol):
    """
    Interpolate each channel bilinearly with OpenCV, then compute Stokes.

    Per-channel bilinear interpolation with OpenCV (normalized convolution of each channel's sparse
    samples), then Stokes from the four full-resolution channels. Independent of the numba kernel.
    """
    k = np.outer([0.5, 1, 0.5], [0.5, 1, 0.5])
    chans = {}
    for r in range(2):
        for c in range(2):
            mask = np.zeros(m.shape)
            mask[r::2, c::2] = 1
            num = cv2.filter2D(m * mask, cv2.CV_64F, k, borderType=cv2.BORDER_REFLECT_101)
            den = cv2.filter2D(mask, cv2.CV_64F, k, borderType=cv2.BORDER_REFLECT_101)
            chans[layout[r][c]] = num / den
    sgn = 1 if pol == '+x+y' else -1
    s0 = 0.5 * sum(chans.values())
    return s0, chans[0] - chans[90], sgn * (chans[45] - chans[135])


@given(
    st.integers(2, 40),
    st.integers(2, 40),
    st.sampled_from(LAYOUTS),
    st.sampled_from(('+x+y', '+x-y')),
)
def test_bilinear_equals_an_opencv_per_channel_reference(h, w, layout, pol):
    rng = np.random.default_rng(h * 100 + w)
    m = rng.uniform(100, 1000, (h, w))
    S = stokes_from_mosaic(m, layout, pol, 'bilinear')
    R = _bilinear_reference(m, layout, pol)
    for s, r in zip(S, R):
        np.testing.assert_allclose(s, r, rtol=1e-5, atol=1e-3)


def test_superpixel_equals_slicing():
    rng = np.random.default_rng(0)
    m = rng.integers(0, 4000, (7, 11)).astype(np.uint16)  # odd: last row and column dropped
    S0, S1, S2 = stokes_from_mosaic(m, IMX250MZR_LAYOUT, '+x+y', 'superpixel')
    f = m[:6, :10].astype(float)
    i90, i45, i135, i0 = f[0::2, 0::2], f[0::2, 1::2], f[1::2, 0::2], f[1::2, 1::2]
    np.testing.assert_allclose(S0, (i0 + i45 + i90 + i135) / 2, rtol=1e-6)
    np.testing.assert_allclose(S1, i0 - i90, atol=1e-3)
    np.testing.assert_allclose(S2, i45 - i135, atol=1e-3)


@given(
    st.sampled_from(LAYOUTS),
    st.sampled_from(('+x+y', '+x-y')),
    st.lists(st.floats(-1, 1), min_size=12, max_size=12),
)
def test_bilinear_is_exact_on_linear_fields(layout, pol, coef):
    """
    Bilinear demosaicing is exact on linear fields away from the border.

    Each channel linear in (row, col): bilinear interpolation reproduces it exactly away from the
    border. (I0 - I90 stays above 120 - 48 > 0, so every pixel is polarized and valid.)
    """
    h, w = 12, 14
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    true = {}
    for n, ang in enumerate((0, 45, 90, 135)):
        a, b, c = coef[3 * n : 3 * n + 3]
        true[ang] = 500 + (60, 20, -60, 0)[n] + 10 * a + b * yy + c * xx
    m = np.empty((h, w))
    for r in range(2):
        for c in range(2):
            m[r::2, c::2] = true[layout[r][c]][r::2, c::2]
    S0, S1, S2 = stokes_from_mosaic(m, layout, pol, 'bilinear')
    sgn = 1 if pol == '+x+y' else -1
    inner = (slice(1, -1), slice(1, -1))
    np.testing.assert_allclose(S0[inner], (0.5 * sum(true.values()))[inner], rtol=1e-6)
    np.testing.assert_allclose(S1[inner], (true[0] - true[90])[inner], atol=2e-3)
    np.testing.assert_allclose(S2[inner], sgn * (true[45] - true[135])[inner], atol=2e-3)


@pytest.mark.parametrize('dy,dx', [(0, 1), (1, 0), (1, 1)])
def test_shifted_layout_describes_a_cropped_mosaic(dy, dx):
    rng = np.random.default_rng(1)
    m = rng.uniform(10, 100, (20, 22))
    lay = parse_layout(IMX250MZR_LAYOUT, '+x+y')
    a_full, d_full, _ = polarization_from_mosaic(m, lay, method='bilinear')
    a_crop, d_crop, _ = polarization_from_mosaic(
        m[dy:, dx:], lay.shifted(dy, dx), method='bilinear'
    )
    # equal up to float32 rounding (vectorised and scalar loop tails may contract to FMA
    # differently)
    assert ang_err_deg(a_crop[1:-1, 1:-1], a_full[dy + 1 : -1, dx + 1 : -1]).max() < 1e-5
    np.testing.assert_allclose(d_crop[1:-1, 1:-1], d_full[dy + 1 : -1, dx + 1 : -1], rtol=1e-6)


@pytest.mark.parametrize(
    'dtype,scale',
    [(np.uint8, 200), (np.uint16, 4000), (np.int32, 4000), (np.float32, 1.0), (np.float64, 1.0)],
)
@pytest.mark.parametrize('method', METHODS)
def test_integer_and_float_inputs_agree(dtype, scale, method):
    m = malus_mosaic((10, 12), 0.4, 0.6, 1.0, IMX250MZR_LAYOUT, IMX250MZR_POL45)
    mi = (
        np.rint(m * scale).astype(dtype)
        if np.dtype(dtype).kind in 'ui'
        else (m * scale).astype(dtype)
    )
    a, d, ok = polarization_from_mosaic(mi, method=method)
    assert ok.all()
    tol = 0.5 if np.dtype(dtype).kind in 'ui' and scale < 1000 else 0.02
    assert ang_err_deg(a, 0.4).max() < tol
    assert np.abs(d - 0.6).max() < tol / 20


@pytest.mark.parametrize('method', METHODS)
def test_all_zero_and_saturated_images_are_invalid_without_nan(method):
    for m, sat in [
        (np.zeros((8, 10), np.uint16), None),
        (np.full((8, 10), 65535, np.uint16), None),
        (np.full((8, 10), 4095, np.uint16), 4095),
        (np.full((8, 10), 255, np.uint8), None),
        (np.zeros((8, 10), np.float32), None),
        (np.full((8, 10), 7.0), None),
    ]:
        a, d, ok = polarization_from_mosaic(m, method=method, saturation_level=sat)
        assert not ok.any()
        assert np.all(a == 0) and np.all(d == 0)
        S = stokes_from_mosaic(m, method=method, saturation_level=sat)
        assert all(np.all(s == 0) for s in S)


@pytest.mark.parametrize('bad', [np.nan, np.inf, -np.inf])
def test_a_non_finite_sample_invalidates_exactly_its_footprint(bad):
    m = malus_mosaic((10, 12), 0.3, 0.5, 100.0, IMX250MZR_LAYOUT, IMX250MZR_POL45)
    m[4, 6] = bad
    a, d, ok = polarization_from_mosaic(m, method='bilinear')
    expect = np.ones_like(ok)
    expect[3:6, 5:8] = False  # the 3 x 3 neighbourhood
    np.testing.assert_array_equal(ok, expect)
    a2, d2, ok2 = polarization_from_mosaic(m, method='superpixel')
    expect2 = np.ones_like(ok2)
    expect2[2, 3] = False  # the 2 x 2 block holding (4, 6)
    np.testing.assert_array_equal(ok2, expect2)
    for x in (a, d, a2, d2):
        assert np.all(np.isfinite(x))
    assert ang_err_deg(a[ok], 0.3).max() < 1e-3


def test_one_saturated_sample_invalidates_its_footprint():
    m = np.rint(malus_mosaic((8, 8), -1.0, 0.4, 1000.0, IMX250MZR_LAYOUT, IMX250MZR_POL45)).astype(
        np.uint16
    )
    m[0, 0] = 4095  # image corner: mirrored footprint
    _, _, ok = polarization_from_mosaic(m, method='bilinear', saturation_level=4095)
    assert set(zip(*np.nonzero(~ok))) == {(0, 0), (0, 1), (1, 0), (1, 1)}


def test_bad_inputs_raise_sensor_errors():
    m = np.ones((4, 4))
    with pytest.raises(SensorError, match='2 x 2 pixels'):
        polarization_from_mosaic(np.ones((1, 9)), method='bilinear')
    with pytest.raises(SensorError, match='2-D'):
        polarization_from_mosaic(np.ones((4, 4, 3)))
    with pytest.raises(SensorError, match='dtype'):
        polarization_from_mosaic(np.ones((4, 4), np.complex64))
    with pytest.raises(SensorError, match='method'):
        polarization_from_mosaic(m, method='vng')
    with pytest.raises(SensorError, match='pol45_toward'):
        polarization_from_mosaic(m, pol45_toward='+y')
    for layout, match in [
        ([[0, 45], [90, 90]], 'once each'),
        ([[0, 45, 90, 135]], '2 x 2'),
        ([[0, 30], [90, 135]], '0, 45, 90 or 135'),
        (5, '2 x 2'),
        ([[True, 45], [90, 135]], '0, 45, 90 or 135'),
    ]:
        with pytest.raises(SensorError, match=match):
            polarization_from_mosaic(m, layout=layout)


def test_layout_object_round_trips():
    lay = parse_layout([[0, 45], [90, 135]], '+x-y')
    assert isinstance(lay, MosaicLayout) and parse_layout(lay) is lay
    assert lay.describe() == {'layout': [[0, 45], [90, 135]], 'pol45_toward': '+x-y'}
    assert lay.shifted(1, 1).shifted(1, 1) == lay
