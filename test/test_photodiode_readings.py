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
Readings that are not measurements: saturated, lone zeros, DoP above 1, duplicated channels.

Each makes its unit unusable in that sample, counted per reason in the result (never dropped
silently); dark offsets are subtracted. Simulated recordings with faults injected at known places.
"""

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
from polarization_compass.conventions import wrap_180_deg
from polarization_compass.estimators.base import Status
from polarization_compass.photodiode.geometry import (
    ArrayGeometryError,
    geometry_from_dict,
    geometry_to_dict,
)
from polarization_compass.photodiode.heading import estimate_recording, make_array_estimator
from polarization_compass.photodiode.readings import reading_flags
from polarization_compass.photodiode.simulate import simulate_readings
from polarization_compass.photodiode.stokes import design_matrix, fit_stokes
import pytest

AZ8 = (0, 90, 180, 270, 45, 135, 225, 315)
LIMITS = (-32768.0, 32767.0)


def geom(saturation=LIMITS, channels=(135, 45, 90, 0), **unit_extra):
    d = {
        'angle_zero': 'horizontal',
        'angle_sense': 'ccw',
        'units': [
            {
                'azimuth_deg': a,
                'elevation_deg': 45.0,
                'channels_deg': list(channels),
                'acceptance_deg': 30.0,
                **unit_extra,
            }
            for a in AZ8
        ],
    }
    if saturation is not None:
        d['saturation'] = list(saturation)
    return geometry_from_dict(d)


def test_geometry_keys_validate_and_round_trip():
    g = geom(dark_offset=[1.0, 2.0, 3.0, 4.0])
    assert g.saturation == LIMITS
    assert g.units[0].dark_offset == (1.0, 2.0, 3.0, 4.0)
    g2 = geometry_from_dict(geometry_to_dict(g))
    assert g2.saturation == LIMITS and g2.units[3].dark_offset == (1.0, 2.0, 3.0, 4.0)
    # survives a gain or convention change
    assert g.with_gains([[1.0] * 4] * 8).units[0].dark_offset == (1.0, 2.0, 3.0, 4.0)
    assert g.with_convention('meridian', 'cw').saturation == LIMITS
    assert geom(saturation=None).saturation is None
    assert geometry_from_dict({**geometry_to_dict(g), 'saturation': 1000}).saturation == (
        -1000.0,
        1000.0,
    )
    for bad in ([5, 1], [1, 2, 3], 'high', -3):
        with pytest.raises(ArrayGeometryError, match='saturation'):
            geometry_from_dict({**geometry_to_dict(g), 'saturation': bad})
    with pytest.raises(ArrayGeometryError, match=r'units\[0\]\.dark_offset'):
        geom(dark_offset=[1.0, 2.0])


def test_flags_by_hand():
    g = geom()
    x = np.random.default_rng(3).uniform(100.0, 2000.0, (12, 8, 4)).round()
    x[0, 1, 2] = 32767.0  # at the high limit
    x[1, 2, 0] = 32768.0  # |-32768| beyond it
    x[2, 3, 3] = 0.0  # a lone zero
    x[3, 4, :] = 0.0  # all dark: not a lone zero (no light), left to the S0 test
    x[4, 5, 1] = np.nan
    x[5, 6, 0] = -1.0
    x[:, 7, 3] = x[:, 7, 2]  # unit 7 reads one signal twice, in every sample
    f = reading_flags(x, g)
    expect = {k: np.zeros((12, 8), dtype=bool) for k in f}
    expect['saturated'][0, 1] = expect['saturated'][1, 2] = True
    expect['zero_channel'][2, 3] = True
    expect['bad_value'][4, 5] = expect['bad_value'][5, 6] = True
    expect['duplicated_channels'][:, 7] = True
    for k in f:
        np.testing.assert_array_equal(f[k], expect[k], err_msg=k)
    # no saturation limits in the geometry: nothing is saturated
    assert not reading_flags(x, geom(saturation=None))['saturated'].any()
    # too short a recording to tell a duplicate from chance
    assert not reading_flags(x[:5], g)['duplicated_channels'].any()


def test_dop_above_one_and_channel_misfit():
    # three channels at 0/60/120 deg: any non-negative readings fit exactly; one bright channel
    # and two nearly dark ones give DoP ~2
    g = geom(channels=(0, 60, 120))
    x = np.tile(np.array([500.0, 300.0, 200.0]), (2, 8, 1))
    x[1, 2] = [1000.0, 1.0, 1.0]
    st_ = fit_stokes(x, g)
    assert st_.dop[1, 2] > 1.5
    assert st_.unusable['dop_above_1'][1, 2] and not st_.valid[1, 2]
    assert st_.unusable['dop_above_1'].sum() == 1 and st_.valid.sum() == 15
    # four channels that no Stokes vector explains (one channel 3x too bright)
    g4 = geom()
    x4 = simulate_readings(g4, 100.0, 40.0, [0.0, 90.0])
    x4[1, 0, 0] *= 3.0
    st4 = fit_stokes(x4, g4)
    assert st4.misfit[1, 0] > 0.15 and st4.unusable['channel_misfit'][1, 0]
    assert st4.unusable['channel_misfit'].sum() == 1 and st4.valid.sum() == 15


def test_dark_offset_is_subtracted():
    g0 = geom()
    x = simulate_readings(g0, 120.0, 35.0, [10.0, 200.0])
    dark = np.array([7.0, 11.0, 13.0, 17.0])
    gd = geom(dark_offset=[float(v) for v in dark])
    a, b = fit_stokes(x, g0), fit_stokes(x + dark, gd)
    np.testing.assert_allclose(b.aop_rad, a.aop_rad, atol=1e-12)
    np.testing.assert_allclose(b.dop, a.dop, rtol=1e-12)
    # without the offset the dark current changes the fit: the test can fail
    assert np.max(np.abs(fit_stokes(x + dark, g0).dop - a.dop)) > 1e-3


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    n_sat=st.integers(0, 6),
    n_zero=st.integers(0, 6),
    sun_alt=st.floats(20.0, 70.0),
)
def test_injected_faults_are_counted_per_sample(seed, n_sat, n_zero, sun_alt):
    """Saturated and zero channels land in the unusable counts of exactly their samples."""
    rng = np.random.default_rng(seed)
    g = geom()
    bearings = rng.uniform(0.0, 360.0, 6)
    x = simulate_readings(g, 150.0, sun_alt, bearings, brightness=3000.0, noise_rel=0.002, rng=rng)
    x = np.abs(x)
    cells = rng.choice(6 * 8, size=n_sat + n_zero, replace=False)
    sat = np.zeros((6, 8), dtype=bool)
    zero = np.zeros((6, 8), dtype=bool)
    for j, c in enumerate(cells):
        i, u = divmod(int(c), 8)
        ch = int(rng.integers(0, 4))
        if j < n_sat:
            x[i, u, ch] = rng.choice([32767.0, 32768.0, 40000.0])
            sat[i, u] = True
        else:
            x[i, u, ch] = 0.0
            zero[i, u] = True
    st_ = fit_stokes(x, g)
    np.testing.assert_array_equal(st_.unusable['saturated'], sat)
    np.testing.assert_array_equal(st_.unusable['zero_channel'], zero)
    assert not np.any(st_.valid & (sat | zero))
    res = estimate_recording(make_array_estimator('tilt_aware', g), x, 150.0, sun_alt, 0.0, 0.0)
    for i, r in enumerate(res):
        counts = r.extras.get('units_unusable', {})
        assert counts.get('saturated', 0) == sat[i].sum()
        assert counts.get('zero_channel', 0) == zero[i].sum()
        if sat[i].any():
            assert f'saturated {sat[i].sum()}' in r.reason
        if r.status == Status.OK:  # what remains measures the heading
            assert abs(wrap_180_deg(r.bearing_deg - bearings[i])) < 5.0


def test_a_saturated_unit_no_longer_turns_the_heading():
    """Without the check a unit pinned at the limit pulls the heading off; with it, it does not."""
    g = geom()
    bearings = np.arange(0.0, 360.0, 30.0)
    x = simulate_readings(g, 200.0, 45.0, bearings, brightness=20000.0)
    x[:, 2, 1] = 32767.0  # unit 2's 45 deg channel saturated in every sample
    off = estimate_recording(
        make_array_estimator('tilt_aware', geom(saturation=None)), x, 200.0, 45.0, 0.0, 0.0
    )
    on = estimate_recording(make_array_estimator('tilt_aware', g), x, 200.0, 45.0, 0.0, 0.0)
    err_off = [abs(wrap_180_deg(r.bearing_deg - b)) for r, b in zip(off, bearings) if r.ok]
    assert max(err_off) > 1.0  # the fault matters
    for r, b in zip(on, bearings):
        assert r.status == Status.OK and abs(wrap_180_deg(r.bearing_deg - b)) < 1e-6
        assert r.extras['units_unusable'] == {'saturated': 1}


def test_design_matrix_rows_are_malus():
    # the independent form of Malus's law the flags' fits rest on
    t = np.radians(30.0)
    np.testing.assert_allclose(
        design_matrix([30.0])[0], 0.5 * np.array([1.0, np.cos(2 * t), np.sin(2 * t)])
    )
