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
Hard cases of error maps and the map-based tilt correction (docs/hard-cases.md).

Tilt or sun outside the map, non-finite inputs, nodes without a valid estimate, the yaw wrap at
+-180 deg, and corrupt or malicious map files.

The maps here are synthetic: an analytic error e(psi, h, pitch, roll) written out below is sampled
on the grid, so the correction can be checked against the exact inverse (psi_meas = psi + e(psi) is
generated from a known psi) instead of against the module's own output.
"""

import json
import math
import pickle

from hard_cases_npz import assert_no_leaked_handle, assert_refused, npy_named_npz, truncate_half
from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.correction import CorrectionStatus, TiltCorrector
from polarization_compass.errormap import ErrorMap, ErrorMapError
from polarization_compass.errormap_io import load_error_map
import pytest

ALT = np.arange(0.0, 55.0, 10.0)
YAW = np.arange(-180.0, 180.0, 5.0)
TILT = np.arange(-30.0, 31.0, 5.0)


def analytic_error_deg(psi, h, p, r):
    """
    Return a smooth tilt error, small enough that psi + e(psi) is monotonic.

    Its slope is bounded: |de/dpsi| < 0.3.
    """
    s = 0.5 + h / 100.0
    return s * (
        8.0 * p / 30.0 * np.sin(np.radians(psi)) + 6.0 * r / 30.0 * np.cos(np.radians(psi))
    )


def synthetic_map(status_patch=None, meta=None):
    g = np.meshgrid(ALT, YAW, TILT, TILT, indexing='ij')
    err = analytic_error_deg(g[1], g[0], g[2], g[3])[None]
    status = np.zeros(err.shape, np.int8)
    if status_patch:
        status_patch(status)
    return ErrorMap(
        err,
        status,
        ('least_squares',),
        ALT.copy(),
        YAW.copy(),
        TILT.copy(),
        TILT.copy(),
        meta=meta
        if meta is not None
        else {'domain': {'tilt_limit_deg': 30.0, 'full_domain': False}},
    )


@pytest.fixture(scope='module')
def corrector():
    return TiltCorrector(synthetic_map(), 'least_squares')


# --------------------------------------------------------------------------------------------
# Inside the map: exact inverse, yaw wrap
# --------------------------------------------------------------------------------------------
@given(
    st.floats(-180, 180, exclude_min=True),
    st.floats(0, 50),
    st.floats(-15, 15),
    st.floats(-15, 15),
)
def test_invert_recovers_the_true_yaw(psi, h, p, r):
    c = TiltCorrector(_MAP, 'least_squares')
    meas = float(cv.wrap_180_deg(psi + analytic_error_deg(psi, h, p, r)))
    out = c.correct(meas, h, p, r)
    assert out.status == CorrectionStatus.OK, out.reason
    assert -180.0 < out.psi_deg <= 180.0
    assert abs(cv.wrap_180_deg(out.psi_deg - psi)) < 0.02
    assert abs(cv.wrap_180_deg(out.error_deg - analytic_error_deg(psi, h, p, r))) < 0.02


_MAP = synthetic_map()


@pytest.mark.parametrize('psi', [180.0, -180.0 + 1e-9, 180.0 - 1e-9, 179.0, -179.0, 177.5])
def test_correction_across_the_yaw_wrap(corrector, psi):
    h, p, r = 40.0, -20.0, 10.0
    meas = float(cv.wrap_180_deg(psi + analytic_error_deg(psi, h, p, r)))
    out = corrector.correct(meas, h, p, r)
    assert out.ok and -180.0 < out.psi_deg <= 180.0
    assert abs(cv.wrap_180_deg(out.psi_deg - psi)) < 0.02


def test_corrected_yaw_is_continuous_in_the_measurement(corrector):
    meas = np.linspace(-180.0, 180.0, 3601)
    psi, status, n = corrector.correct_many(meas, 30.0, 12.0, -7.0)
    assert np.all(status == 0) and np.all(n == 1)
    steps = np.abs(cv.wrap_180_deg(np.diff(psi)))
    assert steps.max() < 0.1 * 1.5 / (
        1 - 0.3
    )  # 0.1 deg of measurement, slope of the inverse <= 1/(1-0.3)


# --------------------------------------------------------------------------------------------
# Outside the map
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    'h, p, r, words',
    [
        (20.0, 31.0, 0.0, 'pitch'),
        (20.0, 0.0, -30.5, 'roll'),
        (55.0, 0.0, 0.0, 'sun altitude'),
        (-0.1, 0.0, 0.0, 'sun altitude'),
        (20.0, 20.0, 15.0, 'exceeds'),
        (20.0, -30.0, 0.5, 'exceeds'),
        (float('nan'), 0.0, 0.0, 'non-finite'),
        (20.0, float('inf'), 0.0, 'non-finite'),
        (20.0, 0.0, None, 'non-finite'),
    ],
)
def test_tilt_or_sun_outside_the_map_is_out_of_domain_with_a_reason(corrector, h, p, r, words):
    out = corrector.correct(10.0, h, p, r)
    assert (
        out.status == CorrectionStatus.OUT_OF_DOMAIN
        and out.psi_deg is None
        and out.error_deg is None
    )
    assert words in out.reason


def test_nan_measurement_is_out_of_domain(corrector):
    out = corrector.correct(float('nan'), 20.0, 0.0, 0.0)
    assert out.status == CorrectionStatus.OUT_OF_DOMAIN and 'non-finite' in out.reason


def test_vectorised_correction_never_returns_nan(corrector):
    meas = np.array([np.nan, 10.0, 10.0, 10.0, np.inf, 10.0])
    h = np.array([20.0, np.nan, 20.0, 80.0, 20.0, 20.0])
    p = np.array([0.0, 0.0, 45.0, 0.0, 0.0, 25.0])
    r = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 25.0])
    for mode in ('invert', 'subtract'):
        psi, status, _ = corrector.correct_many(meas, h, p, r, mode=mode)
        assert np.all(np.isfinite(psi)) and np.all(status == 1) and np.all(psi == 0.0)


def test_the_edges_of_the_tilt_domain_are_inside(corrector):
    for p, r in ((30.0, 0.0), (-15.0, -15.0), (0.0, -30.0), (29.999999, 0.0)):
        psi = 33.0
        meas = float(cv.wrap_180_deg(psi + analytic_error_deg(psi, 25.0, p, r)))
        out = corrector.correct(meas, 25.0, p, r)
        assert out.ok, (p, r, out.reason)
        assert abs(cv.wrap_180_deg(out.psi_deg - psi)) < 0.02


def test_nodes_without_a_valid_estimate_make_their_neighbourhood_out_of_domain():
    def patch(status):
        status[0, 2, :, 6, 6] = 4  # too_few_pixels at sun altitude 20, pitch = roll = 0

    c = TiltCorrector(synthetic_map(patch), 'least_squares')
    out = c.correct(10.0, 20.0, 0.0, 0.0)
    assert out.status == CorrectionStatus.OUT_OF_DOMAIN and 'valid estimate' in out.reason
    assert c.correct(10.0, 20.0, 20.0, 0.0).ok  # far from the bad nodes


def test_full_domain_maps_allow_large_combined_tilt():
    c = TiltCorrector(
        synthetic_map(meta={'domain': {'tilt_limit_deg': 30.0, 'full_domain': True}}),
        'least_squares',
    )
    psi = -60.0
    meas = float(cv.wrap_180_deg(psi + analytic_error_deg(psi, 25.0, 25.0, -25.0)))
    out = c.correct(meas, 25.0, 25.0, -25.0)
    assert out.ok and abs(cv.wrap_180_deg(out.psi_deg - psi)) < 0.02


@pytest.mark.parametrize(
    'kwargs, words',
    [
        ({'method': 'zenith'}, 'not in this map'),
        ({'order': 2}, 'order'),
        ({'yaw': np.array([0.0, 5.0, 10.0, 15.0])}, 'full turn'),
        ({'yaw': np.arange(-180.0, 180.0, 7.0)}, 'divide'),
    ],
)
def test_unusable_maps_for_correction_are_error_map_errors(kwargs, words):
    m = _MAP
    if 'yaw' in kwargs:
        y = kwargs['yaw']
        m = ErrorMap(
            np.zeros((1, ALT.size, y.size, TILT.size, TILT.size)),
            np.zeros((1, ALT.size, y.size, TILT.size, TILT.size), np.int8),
            ('least_squares',),
            ALT,
            y,
            TILT,
            TILT,
            meta={},
        )
    with pytest.raises(ErrorMapError, match=words):
        TiltCorrector(m, kwargs.get('method', 'least_squares'), kwargs.get('order', 3))


# --------------------------------------------------------------------------------------------
# Map files: corrupt, inconsistent, malicious
# --------------------------------------------------------------------------------------------
class _Payload:
    """A pickle payload that would create a file if unpickled."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, 'w'))


def map_arrays():
    m = synthetic_map()
    return {
        'error_deg': m.error_deg,
        'status': m.status,
        'valid': m.valid,
        'methods': np.array(m.methods),
        'sun_altitude_deg': m.sun_altitude_deg,
        'yaw_deg': m.yaw_deg,
        'pitch_deg': m.pitch_deg,
        'roll_deg': m.roll_deg,
        'meta': np.array(json.dumps(m.meta)),
    }


def write_map(path, **over):
    a = map_arrays()
    a.update(over)
    np.savez(path, **{k: v for k, v in a.items() if v is not None})
    return path


def test_a_saved_map_round_trips(tmp_path):
    _MAP.save(tmp_path / 'm.npz')
    m = load_error_map(tmp_path / 'm.npz')
    np.testing.assert_array_equal(m.error_deg, _MAP.error_deg)
    assert m.methods == ('least_squares',)


@pytest.mark.parametrize('key', ['error_deg', 'methods', 'meta', 'status'])
def test_map_with_an_object_array_is_refused_and_never_unpickled(tmp_path, key):
    marker = tmp_path / 'EXECUTED'
    obj = np.empty(3, dtype=object)
    obj[:] = _Payload(marker)
    p = write_map(tmp_path / 'm.npz', **{key: obj})
    with pytest.raises(ErrorMapError, match='(?i)object arrays|pickle'):
        load_error_map(p)
    assert not marker.exists()


def test_a_pickle_named_npz_map_is_refused(tmp_path):
    marker = tmp_path / 'EXECUTED'
    p = tmp_path / 'm.npz'
    p.write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(ErrorMapError):
        load_error_map(p)
    assert not marker.exists()


def _bad(**over):
    return over


@pytest.mark.parametrize(
    'over, words',
    [
        (_bad(error_deg=None), 'missing'),
        (_bad(meta=np.array('{oops')), 'JSON'),
        (_bad(meta=np.array('[1]')), 'JSON'),
        (_bad(methods=np.array([1, 2])), 'names'),
        (_bad(error_deg=np.zeros((1, 2, 3, 4, 5))), 'shape'),
        (_bad(yaw_deg=YAW[::-1].copy()), 'increasing'),
        (_bad(pitch_deg=np.where(TILT == 0, np.nan, TILT)), 'NaN'),
        (
            _bad(status=np.full((1, ALT.size, YAW.size, TILT.size, TILT.size), 99, np.int8)),
            'unknown codes',
        ),
        (_bad(sun_altitude_deg=ALT + 60.0), 'sun_altitude'),
    ],
)
def test_inconsistent_map_files_name_the_problem(tmp_path, over, words):
    with pytest.raises(ErrorMapError, match=words) as ei:
        load_error_map(write_map(tmp_path / 'm.npz', **over))
    assert '\n' not in str(ei.value)


@pytest.mark.parametrize('value', [np.nan, np.inf, 95.0])
def test_map_errors_must_be_finite_and_folded(tmp_path, value):
    e = map_arrays()['error_deg'].copy()
    e[0, 1, 2, 3, 4] = value
    with pytest.raises(ErrorMapError, match='error_deg'):
        load_error_map(write_map(tmp_path / 'm.npz', error_deg=e))


@pytest.mark.parametrize('content', [b'', b'not a zip', b'PK\x05\x06' + bytes(18)])
def test_garbage_map_files(tmp_path, content):
    p = tmp_path / 'm.npz'
    p.write_bytes(content)
    with pytest.raises(ErrorMapError):
        load_error_map(p)


def test_missing_map_file_and_directory(tmp_path):
    with pytest.raises(ErrorMapError, match='does not exist'):
        load_error_map(tmp_path / 'nope.npz')
    with pytest.raises(ErrorMapError, match='does not exist'):
        load_error_map(tmp_path)


def test_a_npy_file_named_npz_is_an_error_map_error(tmp_path):
    with pytest.raises(ErrorMapError):
        load_error_map(npy_named_npz(tmp_path / 'm.npz'))


def _truncated_map(tmp_path):
    return truncate_half(_MAP.save(tmp_path / 'm.npz'))


def test_truncated_map_is_an_error_map_error(tmp_path):
    assert_refused(load_error_map, _truncated_map(tmp_path), ErrorMapError, match='corrupt')


def test_corrupt_map_does_not_leak_a_file_handle(tmp_path):
    assert_no_leaked_handle(load_error_map, _truncated_map(tmp_path), ErrorMapError)


def test_float32_maps_load_as_float64(tmp_path):
    p = _MAP.save(tmp_path / 'm.npz', float32=True)
    m = load_error_map(p)
    assert m.error_deg.dtype == np.float64
    assert np.abs(m.error_deg - _MAP.error_deg).max() < 1e-5
    assert math.isfinite(float(m.error_deg.sum()))
