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
Heading from simulated photodiode arrays with known truth.

What is checked: exactness, tilt, the 180 deg ambiguity, statuses, sigma coverage, gain
calibration, convention self-check and the simulator's acceptance cone.
"""

import numpy as np
from polarization_compass.conventions import fold_axial_deg, wrap_180_deg
from polarization_compass.estimators.base import Status
from polarization_compass.photodiode.calibrate import calibrate_gains
from polarization_compass.photodiode.geometry import geometry_from_dict
from polarization_compass.photodiode.heading import (
    array_methods,
    ArrayMethodError,
    estimate_recording,
    make_array_estimator,
    warm_up_array,
)
from polarization_compass.photodiode.selfcheck import check_convention
from polarization_compass.photodiode.simulate import (
    simulate_readings,
    simulate_unit_stokes,
    sun_body,
)
from polarization_compass.photodiode.stokes import fit_stokes
import pytest

AZ8 = (0, 90, 180, 270, 45, 135, 225, 315)


def geom(
    zero='horizontal',
    sense='ccw',
    el=45.0,
    acceptance=30.0,
    gains=None,
    channels=(135, 45, 90, 0),
    az=AZ8,
    **unit_extra,
):
    units = []
    for i, a in enumerate(az):
        u = {
            'azimuth_deg': a,
            'elevation_deg': el,
            'channels_deg': list(channels),
            'acceptance_deg': acceptance,
        }
        if gains is not None:
            u['gains'] = [float(v) for v in gains[i]]
        u.update(unit_extra)
        units.append(u)
    return geometry_from_dict({'angle_zero': zero, 'angle_sense': sense, 'units': units})


BEARINGS = np.arange(0.0, 360.0, 22.5)


@pytest.mark.parametrize('method', ['least_squares', 'tilt_aware'])
@pytest.mark.parametrize('sun_alt', [5.0, 35.0, 70.0])
@pytest.mark.parametrize('zero,sense', [('horizontal', 'ccw'), ('meridian', 'cw')])
def test_exact_when_level_and_noise_free(method, sun_alt, zero, sense):
    g = geom(zero, sense)
    x = simulate_readings(g, 210.0, sun_alt, BEARINGS)
    res = estimate_recording(make_array_estimator(method, g), x, 210.0, sun_alt, 0.0, 0.0)
    for r, b in zip(res, BEARINGS):
        if (
            sun_alt < 10.0 and r.status == Status.AMBIGUOUS
        ):  # within the sign margin of the prior-noise sigma
            assert abs(fold_axial_deg(r.bearing_deg - b)) < 1e-7
            continue
        assert r.status == Status.OK, r.reason
        assert abs(wrap_180_deg(r.bearing_deg - b)) < 1e-7
        assert r.yaw_enu_deg == pytest.approx(float(wrap_180_deg(90.0 - r.bearing_deg)), abs=1e-9)
        assert r.sun_altitude_deg == pytest.approx(sun_alt, abs=1e-6)
        assert r.pixels >= 6  # units looking (nearly) at the sun or anti-sun see DoP < min_dop


def test_acceptance_cone_lowers_dop_but_keeps_a_symmetric_units_angle():
    g_narrow, g_wide = geom(acceptance=1.0), geom(acceptance=80.0)
    s = sun_body(100.0, 40.0, 0.0)
    a, b = simulate_unit_stokes(g_narrow, s, 0.8), simulate_unit_stokes(g_wide, s, 0.8)
    dop_a = np.hypot(a[:, 1], a[:, 2]) / a[:, 0]
    dop_b = np.hypot(b[:, 1], b[:, 2]) / b[:, 0]
    assert np.all(dop_b < dop_a) and np.mean(dop_b / dop_a) < 0.9
    # the estimate stays exact when every unit's cone is integrated (the cone averages a smooth
    # field: second-order shifts of each unit's angle, not zero; bound them)
    x = simulate_readings(g_wide, 100.0, 40.0, BEARINGS)
    res = estimate_recording(make_array_estimator('tilt_aware', g_wide), x, 100.0, 40.0, 0.0, 0.0)
    assert max(abs(wrap_180_deg(r.bearing_deg - b)) for r, b in zip(res, BEARINGS)) < 1.0


def test_tilt_aware_exact_under_tilt_and_least_squares_is_not():
    g = geom()
    x = simulate_readings(g, 150.0, 40.0, BEARINGS, pitch_deg=12.0, roll_deg=-7.0)
    ta = estimate_recording(make_array_estimator('tilt_aware', g), x, 150.0, 40.0, 12.0, -7.0)
    ls = estimate_recording(make_array_estimator('least_squares', g), x, 150.0, 40.0)
    err_ta = [abs(wrap_180_deg(r.bearing_deg - b)) for r, b in zip(ta, BEARINGS)]
    err_ls = [abs(wrap_180_deg(r.bearing_deg - b)) for r, b in zip(ls, BEARINGS)]
    assert max(err_ta) < 1e-7
    assert max(err_ls) > 3.0  # the level assumption fails under a 14 deg tilt
    assert all(r.status == Status.OK for r in ta + ls)


@pytest.mark.parametrize('method', array_methods())
def test_the_warm_up_runs_every_method_and_leaves_no_trace(method):
    """
    The node's start-up warm-up runs every array method and changes none of its answers.

    After :func:`warm_up_array`, a recording gives the same headings, sigmas and statuses as on an
    estimator that never ran (the warm-up only compiles or loads kernels; no state is kept).
    """
    g = geom()
    x = simulate_readings(g, 200.0, 40.0, BEARINGS, noise_rel=0.01, rng=np.random.default_rng(3))
    fresh = estimate_recording(make_array_estimator(method, g), x, 200.0, 40.0, 0.0, 0.0)
    warmed = make_array_estimator(method, g)
    dt = warm_up_array(warmed)
    assert np.isfinite(dt) and dt > 0.0
    again = estimate_recording(warmed, x, 200.0, 40.0, 0.0, 0.0)
    assert [(r.status, r.psi_deg, r.sigma_deg) for r in again] == [
        (r.status, r.psi_deg, r.sigma_deg) for r in fresh
    ]
    assert all(r.status == Status.OK for r in fresh), [r.status for r in fresh]


def test_ambiguity_like_cameras():
    g = geom()
    # sun at 15 deg, below least_squares' max_tilt_deg 30: without the tilt the sun's side is
    # unknown
    x = simulate_readings(g, 80.0, 15.0, BEARINGS)
    est = make_array_estimator('least_squares', g)
    res = estimate_recording(est, x, 80.0, 15.0)
    assert all(r.status == Status.AMBIGUOUS and r.axial for r in res)
    assert max(abs(fold_axial_deg(r.bearing_deg - b)) for r, b in zip(res, BEARINGS)) < 1e-7
    # a prior within 60 deg resolves it; so does the known tilt
    res = estimate_recording(est, x, 80.0, 15.0, prior_bearing_deg=BEARINGS + 40.0)
    assert all(
        r.status == Status.OK and abs(wrap_180_deg(r.bearing_deg - b)) < 1e-7
        for r, b in zip(res, BEARINGS)
    )
    assert all(r.extras['ambiguity_resolved_by'] == 'prior' for r in res)
    res = estimate_recording(est, x, 80.0, 15.0, 0.0, 0.0)
    assert all(r.extras['ambiguity_resolved_by'] == 'sun_elevation' for r in res)


def test_brightness_resolves_the_side():
    # Rayleigh radiance is symmetric sun/anti-sun; make the sun's side brighter (a real sky is) by
    # scaling S0 with the cosine to the sun: the units' brightness gradient then picks the side.
    g = geom()
    s = sun_body(80.0, 15.0, 30.0)
    st = fit_stokes(simulate_readings(g, 80.0, 15.0, [30.0]), g)
    s0 = 1000.0 * (2.0 + g.axes_body() @ s)
    est = make_array_estimator('least_squares', g)
    r = est.estimate(st.aop_rad[0], st.dop[0], s0, st.valid[0], 80.0, 15.0)
    assert r.status == Status.OK and r.extras['ambiguity_resolved_by'] == 'brightness'
    assert abs(wrap_180_deg(r.bearing_deg - 30.0)) < 1e-7
    r = est.estimate(
        st.aop_rad[0], st.dop[0], 1000.0 * (2.0 - g.axes_body() @ s), st.valid[0], 80.0, 15.0
    )
    assert (
        abs(wrap_180_deg(r.bearing_deg - 210.0)) < 1e-7
    )  # darker on the sun's side: the other end


def test_statuses():
    g = geom()
    x = simulate_readings(g, 80.0, 40.0, [10.0])
    est = make_array_estimator('least_squares', g)
    st = fit_stokes(x, g)
    a, d, s0, v = st.aop_rad[0], st.dop[0], st.s0[0], st.valid[0]
    assert est.estimate(a, d, s0, v, 80.0, -3.0).status == Status.SUN_BELOW_HORIZON
    assert est.estimate(a, d, s0, v, 80.0, 88.0).status == Status.SUN_NEAR_ZENITH
    few = v.copy()
    few[2:] = False
    r = est.estimate(a, d, s0, few, 80.0, 40.0)
    assert r.status == Status.TOO_FEW_UNITS and '2 usable unit(s) < min_units 3' in r.reason
    r = est.estimate(a, np.zeros(8), s0, v, 80.0, 40.0)
    assert r.status == Status.TOO_FEW_UNITS and 'DoP < min_dop' in r.reason
    r = est.estimate(
        a + np.radians([0.0, 80.0] * 4), d, s0, v, 80.0, 40.0
    )  # every other unit turned 80 deg
    assert r.status == Status.POOR_FIT and r.bearing_deg is None
    # the fitted sun far below the ephemeris: poor fit
    r = est.estimate(a, d, s0, v, 80.0, 84.0)
    assert r.status == Status.POOR_FIT and 'ephemeris' in r.reason
    assert (
        make_array_estimator('tilt_aware', g).estimate(a, d, s0, v, 80.0, 40.0).status
        == Status.BAD_INPUT
    )
    r = est.estimate(a, d, s0, v, 80.0, 40.0, float('nan'), 0.0)
    assert r.status == Status.BAD_INPUT
    # all-dark readings: a status, never NaN
    res = estimate_recording(est, np.zeros((2, 8, 4)), 80.0, 40.0)
    assert all(r.status == Status.TOO_FEW_UNITS for r in res)


def test_disabled_units_are_not_used():
    g = geom(enabled=False)
    res = estimate_recording(
        make_array_estimator('least_squares', g),
        simulate_readings(g, 80.0, 40.0, [0.0]),
        80.0,
        40.0,
    )
    assert res[0].status == Status.TOO_FEW_UNITS


@pytest.mark.parametrize('name', ['zenith', 'sm_asm', 'symmetry'])
def test_image_only_methods_say_so(name):
    with pytest.raises(ArrayMethodError, match='needs an image'):
        make_array_estimator(name, geom())
    with pytest.raises(ArrayMethodError, match='unknown method'):
        make_array_estimator('compass', geom())
    with pytest.raises(ArrayMethodError, match='unknown array knob'):
        make_array_estimator('least_squares', geom(), stride=2)


def test_sigma_coverage_and_growth_with_noise():
    """
    Sigma covers the true error and grows with the noise.

    With the prior switched off, sigma comes from the residuals alone: coverage of the true error
    over many noisy samples must be near the normal (t, 6 dof) values; and sigma must grow with the
    noise.
    """
    g = geom(acceptance=5.0)
    rng = np.random.default_rng(11)
    b = rng.uniform(0, 360, 600)
    errs, sig = [], {}
    for noise in (0.002, 0.02):
        x = simulate_readings(g, 120.0, 35.0, b, dop_max=0.6, noise_rel=noise, rng=rng)
        est = make_array_estimator('tilt_aware', g, prior_dof=0.0, max_misfit_deg=90.0)
        res = estimate_recording(est, x, 120.0, 35.0, 0.0, 0.0)
        ok = [
            (wrap_180_deg(r.bearing_deg - bb), r.sigma_deg)
            for r, bb in zip(res, b)
            if r.status == Status.OK
        ]
        assert len(ok) > 550
        e, s = np.array(ok).T
        sig[noise] = np.median(s)
        if noise == 0.02:
            errs = (e, s)
    assert sig[0.02] > 5 * sig[0.002]
    e, s = errs
    cov1, cov2 = np.mean(np.abs(e) < s), np.mean(np.abs(e) < 2 * s)
    assert 0.55 < cov1 < 0.80, cov1
    assert cov2 > 0.85, cov2  # t with 6 dof: 0.91


def test_gain_calibration_recovers_known_gains():
    rng = np.random.default_rng(2)
    true = rng.uniform(0.7, 1.3, (8, 4))
    true /= true.mean(axis=1, keepdims=True)
    g = geom(gains=true)
    turns = [simulate_readings(g, 120.0, 35.0, np.linspace(0, 360, 90) + k) for k in range(3)]
    cal = calibrate_gains(turns, geom())
    np.testing.assert_allclose(np.array(cal.gains), true, atol=1e-8)
    assert all(c > 10 for c in cal.condition)
    noisy = [
        simulate_readings(
            g, 120.0, 35.0, np.linspace(0, 360, 200) + 7 * k, noise_rel=0.003, rng=rng
        )
        for k in range(6)
    ]
    cal = calibrate_gains(noisy, geom())
    err = np.array(cal.gains) - true
    sigma = np.array(cal.gains_sigma)
    assert np.all(sigma > 0)
    assert np.mean(np.abs(err) < 3 * sigma) > 0.85  # the jackknife sigma is of the right size
    assert np.max(np.abs(err)) < 0.03
    # calibrated gains bring back the heading that uncalibrated ones bias
    x = simulate_readings(g, 120.0, 35.0, BEARINGS)
    raw = estimate_recording(make_array_estimator('tilt_aware', geom()), x, 120.0, 35.0, 0.0, 0.0)
    fixed = estimate_recording(
        make_array_estimator('tilt_aware', geom(gains=np.array(cal.gains))),
        x,
        120.0,
        35.0,
        0.0,
        0.0,
    )
    e_raw = np.sqrt(np.mean([wrap_180_deg(r.bearing_deg - b) ** 2 for r, b in zip(raw, BEARINGS)]))
    e_fix = np.sqrt(
        np.mean([wrap_180_deg(r.bearing_deg - b) ** 2 for r, b in zip(fixed, BEARINGS)])
    )
    assert e_fix < 0.3 * e_raw


def test_gain_calibration_limits():
    from polarization_compass.photodiode.calibrate import CalibrationError

    g3 = geom(channels=(0, 60, 120))
    with pytest.raises(CalibrationError, match='3 channels: no redundancy'):
        calibrate_gains([simulate_readings(g3, 120.0, 35.0, np.linspace(0, 360, 50))], g3)
    g = geom()
    still = np.repeat(
        simulate_readings(g, 120.0, 35.0, [10.0]), 100, axis=0
    )  # no turn: one polarization
    with pytest.raises(CalibrationError, match='poorly conditioned'):
        calibrate_gains([still], g)


@pytest.mark.parametrize(
    'zero,sense',
    [('horizontal', 'ccw'), ('meridian', 'cw'), ('meridian', 'ccw'), ('horizontal', 'cw')],
)
def test_convention_self_check_finds_the_truth(zero, sense):
    truth = geom(zero, sense)
    x = simulate_readings(
        truth, 140.0, 40.0, np.linspace(0, 360, 24, endpoint=False), noise_rel=0.005
    )
    scores, verdict = check_convention(x, geom('meridian', 'cw'), 140.0, 40.0)
    assert (scores[0].angle_zero, scores[0].angle_sense) == (zero, sense)
    assert verdict.startswith('clear')
