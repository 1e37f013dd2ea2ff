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
Property-based and hard-case tests of every heading estimator.

Inputs are random suns, attitudes, pixel masks, priors and AoP noise (numpy warnings are errors,
pytest.ini).

Promises checked (estimators/base.py): a HeadingResult never carries NaN/inf; a usable result has
psi in (-180, 180], bearing in [0, 360), REP-103 yaw = 90 - bearing, bearing = psi + sun azimuth, a
finite sigma >= 0 and quality in [0, 1]; a failed one has no numbers and a reason; ``axial`` iff
status ``ambiguous``. Estimates follow the truth without 180 deg flips: a resolved (non-axial)
heading is never the wrong sun side, and along a continuous sweep of the yaw the estimate moves
continuously. The truth here is the renderer's attitude (the renderer is checked against the
paper's formulas in test_render.py); the tilt error of the level-camera methods is bounded by the
notes' section 3 curve.
"""

import math

from hypothesis import assume, given, settings
from hypothesis import strategies as st
import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.estimators import estimator_names, make_estimator, Observation, Status
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, Validity
import pytest

CAM = CameraModel(
    'pinhole', 612, 512, 4.0, 13.8, 13.8
)  # the paper's field of view with 1/16 of the pixels
RENDERER = Renderer(
    Scene(camera=CAM, validity=Validity(3.0, 0.0, 0.0)), pixels=PixelSelection.strided(8)
)
METHODS = estimator_names()
ESTIMATORS = {m: make_estimator(m) for m in METHODS}
AXIAL_ONLY = {m for m in METHODS if ESTIMATORS[m].axial}


def observe(
    bearing,
    pitch,
    roll,
    sun_az,
    sun_alt,
    noise_deg=0.0,
    drop=0.0,
    seed=0,
    prior=None,
    tilt_known=True,
):
    f = RENDERER.render(
        attitude=cv.CameraAttitude(bearing, pitch, roll), sun=SunDirection(sun_az, sun_alt)
    )
    obs = Observation.from_frame(
        f,
        pitch_deg=pitch if tilt_known else None,
        roll_deg=roll if tilt_known else None,
        prior_bearing_deg=prior,
    )
    rng = np.random.default_rng(seed)
    if noise_deg > 0:
        obs.aop_rad = cv.fold_aop_rad(
            (obs.aop_rad + np.radians(noise_deg) * rng.standard_normal(obs.aop_rad.shape)).astype(
                np.float32
            )
        )
    if drop > 0:
        obs.valid = obs.valid & (rng.random(obs.valid.shape) >= drop)
    return obs, f


def check_result(res, obs):
    """Check the HeadingResult contract, field by field."""
    assert isinstance(res.status, Status)
    for name in ('psi_deg', 'bearing_deg', 'yaw_enu_deg', 'sigma_deg', 'sun_altitude_deg'):
        v = getattr(res, name)
        assert v is None or math.isfinite(v), (name, v)
    assert math.isfinite(res.quality) and 0.0 <= res.quality <= 1.0
    assert res.axial == (res.status == Status.AMBIGUOUS)
    for k, v in res.extras.items():
        if isinstance(v, float):
            assert math.isfinite(v), (k, v)
    if res.ok:
        assert -180.0 < res.psi_deg <= 180.0
        assert 0.0 <= res.bearing_deg < 360.0
        assert -180.0 < res.yaw_enu_deg <= 180.0
        assert abs(cv.wrap_180_deg(res.yaw_enu_deg - (90.0 - res.bearing_deg))) < 1e-9
        assert abs(cv.wrap_180_deg(res.bearing_deg - (res.psi_deg + obs.sun_azimuth_deg))) < 1e-9
        assert res.sigma_deg >= 0.0 and res.pixels > 0
    else:
        assert res.psi_deg is None and res.bearing_deg is None and res.yaw_enu_deg is None
        assert res.reason


def heading_error_deg(res, true_bearing):
    d = cv.wrap_180_deg(res.bearing_deg - true_bearing)
    return float(cv.fold_axial_deg(d)) if res.axial else float(d)


def tilt_bound_deg(pitch, roll, sun_alt):
    """
    Return the largest |tilt error| of a level-camera method.

    The notes' section 3 curve peaks at 25.9 deg for pitch -20 and sun altitude 50 and grows with
    tilt and sun altitude; for |pitch| + |roll| <= 30 and the sun below 60 deg, 60 deg is a safe
    bound that still separates any error from a 180 deg flip.
    """
    return 1e-3 if pitch == 0.0 and roll == 0.0 else 60.0


attitudes = st.tuples(
    st.floats(0.0, 360.0, exclude_max=True), st.floats(-20.0, 20.0), st.floats(-10.0, 10.0)
)


# --------------------------------------------------------------------------------------------
# Properties over random inputs
# --------------------------------------------------------------------------------------------
@settings(max_examples=80)
@given(
    att=attitudes,
    sun_az=st.floats(0.0, 360.0, exclude_max=True),
    sun_alt=st.floats(-10.0, 90.0),
    noise=st.sampled_from([0.0, 0.5, 5.0, 40.0]),
    drop=st.sampled_from([0.0, 0.5, 0.995]),
    prior_off=st.one_of(st.none(), st.floats(-170.0, 170.0)),
    seed=st.integers(0, 1000),
    method=st.sampled_from(METHODS),
)
def test_every_result_keeps_the_contract(
    att, sun_az, sun_alt, noise, drop, prior_off, seed, method
):
    bearing, pitch, roll = att
    prior = None if prior_off is None else float(cv.wrap_360_deg(bearing + prior_off))
    obs, _ = observe(bearing, pitch, roll, sun_az, sun_alt, noise, drop, seed, prior)
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    if sun_alt > 89.0:
        assert res.status == Status.SUN_NEAR_ZENITH
    if sun_alt < 0.0:
        assert res.status == Status.SUN_BELOW_HORIZON


@given(
    att=attitudes,
    sun_az=st.floats(0.0, 360.0, exclude_max=True),
    sun_alt=st.floats(2.0, 60.0),
    noise=st.sampled_from([0.0, 0.5]),
    prior_off=st.one_of(st.none(), st.floats(-30.0, 30.0)),
    method=st.sampled_from(METHODS),
)
def test_a_resolved_heading_is_never_on_the_wrong_sun_side(
    att, sun_az, sun_alt, noise, prior_off, method
):
    """
    A resolved heading is never on the wrong sun side.

    No 180 deg flip away from the documented ambiguity: a non-axial result is within the method's
    tilt error of the truth (tilt_aware: exact), an axial one within it modulo 180 deg.
    """
    bearing, pitch, roll = att
    prior = None if prior_off is None else float(cv.wrap_360_deg(bearing + prior_off))
    obs, _ = observe(bearing, pitch, roll, sun_az, sun_alt, noise, prior=prior)
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    assume(res.ok)
    err = abs(heading_error_deg(res, bearing))
    bound = 0.05 if method == 'tilt_aware' else tilt_bound_deg(pitch, roll, sun_alt)
    assert err <= bound + 3 * noise + 0.05, (res.status, res.reason, err)


@settings(max_examples=20)
@given(sun_alt=st.floats(2.0, 60.0), method=st.sampled_from(METHODS), level=st.booleans())
def test_level_noise_free_sky_gives_the_truth(sun_alt, method, level):
    """
    A level, noise-free sky gives the truth.

    Level camera (or tilt_aware at a tilt), noise-free Rayleigh sky: every method is exact to 0.01
    deg (mod 180 deg when it reports ambiguity).
    """
    pitch, roll = (0.0, 0.0) if level or method != 'tilt_aware' else (-15.0, 10.0)
    for bearing in (0.0, 179.9, 180.0, 359.99):
        obs, _ = observe(bearing, pitch, roll, 123.0, sun_alt, prior=bearing)
        res = ESTIMATORS[method].estimate(obs)
        check_result(res, obs)
        assert res.ok, res.reason
        assert abs(heading_error_deg(res, bearing)) < 0.01


@pytest.mark.parametrize('method', METHODS)
def test_estimate_is_continuous_along_a_yaw_sweep(method):
    """
    The estimate is continuous along a yaw sweep.

    Bearing swept in 5 deg steps at pitch -20 deg, sun altitude 30, prior = truth: consecutive
    estimates differ by 5 deg +- the change of the tilt error (its slope is < 1 deg/deg, notes
    section 3): a jump of ~180 deg would be a flip. Axial results are compared modulo 180 deg.
    """
    step = 5.0
    prev = None
    for b in np.arange(0.0, 360.0 + step, step):
        obs, _ = observe(
            float(b), -20.0, 0.0, 0.0, 30.0, prior=float(b), tilt_known=(method == 'tilt_aware')
        )
        res = ESTIMATORS[method].estimate(obs)
        check_result(res, obs)
        assert res.ok, res.reason
        if prev is not None:
            d = cv.wrap_180_deg(res.bearing_deg - prev.bearing_deg)
            if res.axial or prev.axial:
                d = cv.fold_axial_deg(d)
            assert abs(d - step) < 0.9 * step, (b, res.bearing_deg, prev.bearing_deg)
        prev = res


# --------------------------------------------------------------------------------------------
# Hard cases
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize(
    'alt, status',
    [
        (90.0, Status.SUN_NEAR_ZENITH),
        (89.5, Status.SUN_NEAR_ZENITH),
        (89.0 + 1e-9, Status.SUN_NEAR_ZENITH),
        (-1e-9, Status.SUN_BELOW_HORIZON),
        (-0.8334, Status.SUN_BELOW_HORIZON),
        (-90.0, Status.SUN_BELOW_HORIZON),
    ],
)
def test_sun_at_the_zenith_and_below_the_horizon_are_statuses(method, alt, status):
    obs, _ = observe(10.0, 0.0, 0.0, 45.0, alt)
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    assert res.status == status and 'altitude' in res.reason


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('alt', [0.0, 1e-9, 0.5, 88.99])
def test_sun_on_the_horizon_and_just_below_the_zenith_limit_give_headings(method, alt):
    """
    A sun on the horizon or just below the zenith limit gives headings.

    On the horizon and 0.01 deg below the zenith limit the level-camera solution still exists: a
    heading (mod 180 deg if ambiguous) within 0.05 deg, or an explicit status; never NaN.
    """
    obs, _ = observe(250.0, 0.0, 0.0, 300.0, alt, prior=250.0)
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    if (
        res.ok
    ):  # near the zenith the solar meridian is ill-conditioned: sm_asm is 0.13 deg off at 88.99
        assert abs(heading_error_deg(res, 250.0)) < (0.05 if alt < 80.0 else 0.3)


@pytest.mark.parametrize('method', METHODS)
def test_knob_allowing_the_sun_at_the_zenith_never_gives_nan(method):
    """
    A knob allowing the sun at the zenith never gives NaN.

    With max_sun_altitude_deg 90, a sun 0.01 deg from the zenith gives a finite heading or a
    status.
    """
    e = make_estimator(method, max_sun_altitude_deg=90.0)
    for alt in (89.99, 90.0):
        obs, _ = observe(30.0, 0.0, 0.0, 45.0, alt, prior=30.0)
        check_result(e.estimate(obs), obs)


def _blank(obs, aop=None, dop=None, valid=None):
    if aop is not None:
        obs.aop_rad = np.full_like(obs.aop_rad, aop)
    if dop is not None:
        obs.dop = np.full_like(obs.dop, dop)
    if valid is not None:
        obs.valid = np.full_like(obs.valid, valid)
    return obs


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize(
    'case',
    [
        'no_valid_pixel',
        'dop_zero',
        'constant_aop',
        'nan_aop',
        'inf_dop',
        'huge_aop',
        'dop_above_one',
    ],
)
def test_degenerate_images_give_a_status_or_a_finite_heading(method, case):
    obs, _ = observe(60.0, 0.0, 0.0, 200.0, 35.0, prior=60.0)
    if case == 'no_valid_pixel':
        _blank(obs, valid=False)
    elif case == 'dop_zero':
        _blank(obs, dop=0.0)
    elif case == 'constant_aop':
        _blank(obs, aop=0.3)
    elif case == 'nan_aop':
        obs.aop_rad = obs.aop_rad.copy()
        obs.aop_rad[::3, ::3] = np.nan
    elif case == 'inf_dop':
        obs.dop = obs.dop.copy()
        obs.dop[::5, ::5] = np.inf
    elif case == 'huge_aop':
        obs.aop_rad = (obs.aop_rad + np.float32(1000 * np.pi)).astype(np.float32)
    elif case == 'dop_above_one':
        _blank(obs, dop=3.0)
    # zenith defaults to min_dop 0 (its window is near the zenith, where DoP is high when the sun
    # is low): with DoP 0 everywhere it uses the pixels. Demosaicking marks DoP-0 pixels invalid,
    # so a sensor never hands it such pixels; with the common min_dop knob every method refuses
    # them.
    est = make_estimator(method, min_dop=0.02) if case == 'dop_zero' else ESTIMATORS[method]
    res = est.estimate(obs)
    check_result(res, obs)
    if case in ('no_valid_pixel', 'dop_zero'):
        assert res.status in (Status.TOO_FEW_PIXELS, Status.BAD_INPUT)


@pytest.mark.parametrize('method', METHODS)
def test_a_single_pixel_is_too_few(method):
    sel = PixelSelection.explicit([306], [256])
    f = Renderer(Scene(camera=CAM), pixels=sel).render(
        attitude=cv.CameraAttitude(0, 0, 0), sun=SunDirection(0, 30)
    )
    obs = Observation.from_frame(f, 0.0, 0.0, 0.0)
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    assert res.status in (Status.TOO_FEW_PIXELS, Status.BAD_INPUT)


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize(
    'att',
    [
        (0.0, 90.0, 0.0),
        (0.0, -90.0, 0.0),
        (0.0, 0.0, 90.0),
        (0.0, 0.0, -90.0),
        (200.0, -60.0, 0.0),
    ],
)
def test_pitch_or_roll_of_90_and_a_camera_facing_the_sun(method, att):
    """
    Pitch or roll of 90 deg and a camera facing the sun give a status or a heading.

    Half the view below the horizon (+-90) or the sun in the middle of the image (bearing 200 = sun
    azimuth, pitch -60 = -(90 - sun altitude 30)): a status or a finite heading; tilt_aware, which
    knows the tilt, must be right (within 0.05 deg, mod 180 if ambiguous).
    """
    obs, _ = observe(*att, 200.0, 30.0, prior=att[0])
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    if method == 'tilt_aware' and res.ok:
        assert abs(heading_error_deg(res, att[0])) < 0.05


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize(
    'field, value',
    [
        ('sun_azimuth_deg', float('nan')),
        ('sun_altitude_deg', float('inf')),
        ('sun_altitude_deg', 91.0),
        ('prior_bearing_deg', float('nan')),
        ('pitch_deg', float('nan')),
    ],
)
def test_non_finite_observation_scalars(method, field, value):
    obs, _ = observe(60.0, 0.0, 0.0, 200.0, 35.0, prior=60.0)
    setattr(obs, field, value)
    res = ESTIMATORS[method].estimate(obs)
    check_result(res, obs)
    if field.startswith('sun_'):
        assert res.status == Status.BAD_INPUT
