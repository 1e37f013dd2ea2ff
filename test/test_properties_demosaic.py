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
Property-based and hard-case tests of demosaicking raw DoFP images.

Any 2-D input, of any size, dtype and content (zeros, saturation, NaN, inf, negative, huge), gives
finite AoP/DoP in range with invalid pixels at 0/0, or one SensorError. numpy warnings are errors
(pytest.ini).

Covered in test/test_demosaic.py and not repeated: all-zero and saturated images
(test_all_zero_and_saturated_images_are_invalid_without_nan), one NaN/inf sample
(test_a_non_finite_sample_invalidates_exactly_its_footprint), a 1 x 9 image, 3-D input and complex
dtype (test_bad_inputs_raise_sensor_errors), odd sizes against OpenCV
(test_bilinear_equals_an_opencv_per_channel_reference), the +-90 deg fold
(test_aop_at_the_branch_cut_is_folded_into_range).
"""

import math

from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.demosaic import (
    aop_dop_from_stokes,
    polarization_from_mosaic,
    stokes_from_mosaic,
)
from polarization_compass.mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45, SensorError
import pytest

METHODS = ('superpixel', 'bilinear')
HALF_PI = np.float32(np.pi / 2)


def check(aop, dop, valid, shape):
    assert aop.shape == dop.shape == valid.shape == shape
    assert aop.dtype == np.float32 and dop.dtype == np.float32 and valid.dtype == np.bool_
    assert np.all(np.isfinite(aop)) and np.all(np.isfinite(dop))
    assert np.all(aop >= -HALF_PI) and np.all(aop < HALF_PI)
    assert np.all(dop >= 0) and np.all(dop <= 1)
    assert np.all(aop[~valid] == 0) and np.all(dop[~valid] == 0)


def malus(h, w, aop_rad, dop, s0, layout=IMX250MZR_LAYOUT):
    """
    Return ideal Malus samples I(phi) for the default layout.

    Ideal samples I(phi) = S0/2 (1 + DoP cos(2 (phi - AoLP_x))) with phi the polarizer angle from
    +x towards +y in the camera frame and AoLP_x = pi/2 - AoP (physics notes section 1), written
    out here. The default (IMX250MZR as delivered) has its 45 deg polarizer towards +x-y: camera
    angle = -label.
    """
    sign = 1.0 if IMX250MZR_POL45 == '+x+y' else -1.0
    phi = sign * np.radians(np.tile(np.array(layout, float), (h // 2 + 1, w // 2 + 1))[:h, :w])
    aolp = np.pi / 2 - aop_rad
    return s0 / 2 * (1 + dop * np.cos(2 * (phi - aolp)))


finite_or_not = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.sampled_from([0.0, -0.0, 1.0, 4095.0, 65535.0, np.nan, np.inf, -np.inf, -1.0]),
)


@given(
    st.sampled_from(METHODS),
    st.integers(2, 9),
    st.integers(2, 9),
    st.data(),
    st.sampled_from(['uint8', 'uint16', 'int16', 'int32', 'float32']),
)
def test_any_2d_image_gives_finite_in_range_outputs(method, h, w, data, dtype):
    dt = np.dtype(dtype)
    if dt.kind == 'f':
        m = data.draw(hnp.arrays(dt, (h, w), elements=finite_or_not))
    else:
        m = data.draw(hnp.arrays(dt, (h, w)))
    sat = data.draw(st.one_of(st.none(), st.floats(-1e6, 1e6)))
    a, d, ok = polarization_from_mosaic(m, method=method, saturation_level=sat)
    check(a, d, ok, (h // 2, w // 2) if method == 'superpixel' else (h, w))
    S = stokes_from_mosaic(m, method=method, saturation_level=sat)
    assert all(np.all(np.isfinite(s)) for s in S)
    assert all(np.all(s[~ok] == 0) for s in S)


@pytest.mark.parametrize('method', METHODS)
def test_a_huge_float64_sample_is_an_invalid_pixel_not_a_numpy_warning(method):
    m = malus(4, 4, 0.3, 0.5, 100.0)
    m[0, 0] = 1e300
    a, d, ok = polarization_from_mosaic(m, method=method)
    assert not ok.reshape(-1)[0]


@given(
    st.sampled_from(METHODS),
    st.integers(2, 9),
    st.integers(2, 9),
    st.sampled_from([np.float32, np.float64]),
    st.floats(-1e300, 1e300),
)
def test_float64_inputs_within_float32_range_never_warn(method, h, w, dtype, v):
    m = np.full((h, w), np.clip(v, -3e38, 3e38), dtype=dtype)
    a, d, ok = polarization_from_mosaic(m, method=method)
    check(a, d, ok, (h // 2, w // 2) if method == 'superpixel' else (h, w))
    assert not ok.any()  # a uniform image is unpolarized (S1 = S2 = 0): invalid


@pytest.mark.parametrize('method', METHODS)
def test_an_all_nan_image_is_all_invalid(method):
    for fill in (np.nan, np.inf, -np.inf):
        a, d, ok = polarization_from_mosaic(np.full((6, 8), fill, np.float32), method=method)
        check(a, d, ok, (3, 4) if method == 'superpixel' else (6, 8))
        assert not ok.any()


@pytest.mark.parametrize('shape', [(1, 1), (0, 0), (1, 2), (2, 1), (0, 4)])
@pytest.mark.parametrize('method', METHODS)
def test_images_smaller_than_one_superpixel_are_sensor_errors(shape, method):
    with pytest.raises(SensorError, match='2 x 2'):
        polarization_from_mosaic(np.ones(shape, np.uint16), method=method)


@pytest.mark.parametrize(
    'dtype', [np.bool_, np.float16, np.complex128, object, 'U3', 'datetime64[s]']
)
def test_wrong_dtypes_are_sensor_errors(dtype):
    with pytest.raises(SensorError, match='dtype'):
        polarization_from_mosaic(np.zeros((4, 4), dtype=dtype))


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('aop_deg', [-90.0, -45.0, 0.0, 30.0, 89.999])
def test_a_single_superpixel_recovers_malus_law(method, aop_deg):
    """
    A single superpixel recovers Malus's law.

    A 2 x 2 image is the smallest mosaic: one superpixel, or four bilinear pixels (mirrored
    borders).
    """
    m = malus(2, 2, math.radians(aop_deg), 0.4, 1000.0)
    a, d, ok = polarization_from_mosaic(m, method=method)
    assert ok.all()
    assert (
        np.degrees(np.abs(cv.fold_axial_rad(a.astype(float) - math.radians(aop_deg)))).max() < 1e-3
    )
    np.testing.assert_allclose(d, 0.4, atol=1e-5)


@pytest.mark.parametrize('h, w', [(5, 7), (3, 3), (7, 2), (2, 9)])
def test_odd_mosaic_sizes(h, w):
    """
    Odd mosaic sizes are handled by both demosaics.

    Superpixel drops the trailing odd row/column; bilinear keeps every pixel and stays exact on a
    uniform polarized field (mirrored borders keep the 2 x 2 phase at odd edges).
    """
    m = malus(h, w, 0.7, 0.3, 500.0)
    a, d, ok = polarization_from_mosaic(m, method='superpixel')
    check(a, d, ok, (h // 2, w // 2))
    a, d, ok = polarization_from_mosaic(m, method='bilinear')
    check(a, d, ok, (h, w))
    assert ok.all()
    assert np.degrees(np.abs(cv.fold_axial_rad(a.astype(float) - 0.7))).max() < 1e-3


@given(
    st.floats(-math.pi, math.pi),
    st.floats(0.05, 1.0),
    st.floats(1.0, 4000.0),
    st.sampled_from(METHODS),
    st.integers(0, 2**31),
)
def test_aop_is_continuous_in_the_true_angle_with_noise(aop, dop, s0, method, seed):
    """
    The recovered AoP is continuous in the true angle with noise.

    Property: with shot-like noise the recovered AoP stays axially close to the truth, never
    flipping by 90 deg (S1/S2 sign confusion) or jumping at the +-90 deg fold. Bound: 4 sigma of
    sigma_AoP = 1 / (DoP sqrt(8 N)) per superpixel (physics notes), N = S0 / 2 photons per sample.
    """
    m = malus(8, 8, aop, dop, s0)
    rng = np.random.default_rng(seed)
    noisy = rng.poisson(m).astype(np.float64)
    a, d, ok = polarization_from_mosaic(noisy, method=method)
    check(a, d, ok, (4, 4) if method == 'superpixel' else (8, 8))
    sigma = 1.0 / (dop * math.sqrt(8 * s0 / 2))
    if sigma > 0.05:  # too noisy to speak of a single angle
        return
    err = np.abs(cv.fold_axial_rad(a[ok].astype(float) - aop))
    assert err.max() < 6 * sigma + 1e-4


@given(
    hnp.arrays(np.float32, st.integers(1, 20), elements=finite_or_not),
    hnp.arrays(np.float32, st.integers(1, 20), elements=finite_or_not),
)
def test_stokes_to_aop_never_gives_nan(s1, s2):
    n = min(s1.size, s2.size)
    s0 = np.abs(s1[:n]) + np.abs(s2[:n])
    with np.errstate(all='ignore'):  # building the test input only
        s0 = np.where(np.isfinite(s0), s0, np.float32(1.0)).astype(np.float32)
    a, d, ok = aop_dop_from_stokes(s0, s1[:n], s2[:n])
    check(a, d, ok, (n,))
