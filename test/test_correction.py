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
Map-based tilt correction against the truth.

True yaws are drawn off the grid, the measured heading comes from rendering and running the real
estimator (or from the closed-form level-assumption heading, which the four methods reproduce to
~0.002 deg under an ideal Rayleigh sky), and the corrected heading is compared with the drawn truth
-- never with the corrector's own output.
"""

import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.conventions import CameraAttitude
from polarization_compass.correction import (
    CorrectionStatus,
    default_map_path,
    REGENERATE_DEFAULT_MAP,
    STATUS_INT,
    TiltCorrector,
)
from polarization_compass.errormap import ErrorMap, ErrorMapError
from polarization_compass.errormap_io import load_error_map
from polarization_compass.estimators import make_estimator, registry
from polarization_compass.estimators.base import Observation
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene_load import default_scene
from polarization_compass.sweep import run_sweep, SweepSpec
import pytest
from test_errormap import level_assumption_error_deg

PAPER_METHODS = registry.paper_methods()


@pytest.fixture(scope='module')
def shipped():
    return load_error_map(default_map_path())


def domain_points(n, seed, corner_fraction=0.3):
    """
    Draw random (psi, h, pitch, roll) inside the map's domain, many in the hardest corner.

    The domain: sun 0-50 deg, |pitch|+|roll| <= 30 deg; the hardest corner: sun 45-50 deg, tilt
    25-30 deg mostly along one axis.
    """
    rng = np.random.default_rng(seed)
    k = int(n * corner_fraction)
    psi = rng.uniform(-180, 180, n)
    h = np.concatenate([rng.uniform(0, 50, n - k), rng.uniform(45, 50, k)])
    a = rng.uniform(-1, 1, (n - k) * 3)
    b = rng.uniform(-1, 1, (n - k) * 3)
    keep = np.abs(a) + np.abs(b) <= 1
    p = np.concatenate([30 * a[keep][: n - k], rng.choice([-1, 1], k) * rng.uniform(25, 29.9, k)])
    r_corner = rng.uniform(-1, 1, k) * (29.99 - np.abs(p[n - k :]))
    r = np.concatenate([30 * b[keep][: n - k], r_corner])
    return psi, h, p, r


def measured_by_estimator(method, psi, h, p, r, knobs):
    """Render each point and run the method: the heading a tilted camera would report."""
    scene = default_scene()
    est = make_estimator(method, **knobs)
    renderer = Renderer(scene, pixels=est.pixels_needed(scene.camera))
    out = []
    for y, hh, pp, rr in zip(psi, h, p, r):
        f = renderer.render(
            attitude=CameraAttitude(float(y), float(pp), float(rr)),
            sun=SunDirection(0.0, float(hh)),
        )
        obs = Observation(
            f.aop_rad,
            f.dop,
            f.valid,
            f.rays_cam,
            f.x_px,
            f.y_px,
            scene.camera,
            0.0,
            float(hh),
            f.intensity,
            float(pp),
            float(rr),
            None,
        )
        res = est.estimate(obs)
        assert res.ok, res.reason
        # the estimators are axial: take the end of the axis nearest the truth, as a resolved
        # compass would
        out.append(float(y) + float(cv.fold_axial_deg(res.psi_deg - y)))
    return np.array(out)


# --------------------------------------------------------------------------------------------
# The shipped map
# --------------------------------------------------------------------------------------------
def test_shipped_map_is_small_and_documented(shipped):
    assert default_map_path().stat().st_size < 2_000_000
    assert set(PAPER_METHODS) <= set(shipped.methods)
    np.testing.assert_allclose(shipped.sun_altitude_deg, np.arange(0, 51, 5))
    np.testing.assert_allclose(shipped.yaw_deg, np.arange(-180, 176, 5))
    np.testing.assert_allclose(shipped.pitch_deg, np.arange(-30, 31, 5))
    np.testing.assert_allclose(shipped.roll_deg, np.arange(-30, 31, 5))
    for arg in (
        '--sun-altitude 0:50:5',
        '--yaw -180:175:5',
        '--pitch -30:30:5',
        '--roll -30:30:5',
    ):
        assert arg in REGENERATE_DEFAULT_MAP
    inside = np.abs(shipped.pitch_deg)[:, None] + np.abs(shipped.roll_deg)[None, :] <= 30
    assert shipped.valid[:, :, :, inside].all()


def test_a_regenerated_slice_matches_the_shipped_map(shipped):
    """Recompute a coarse slice with the sampling recorded in the meta: same errors, statuses."""
    methods = list(PAPER_METHODS)
    knobs = {m: shipped.meta['sampling'][m]['knobs'] for m in methods}
    yaw = shipped.yaw_deg[::6]
    spec = SweepSpec(methods, [50.0], yaw, [-20.0], [-10.0, 0.0, 10.0], knobs=knobs)
    fresh = run_sweep(spec, workers=1, progress=False)
    ia = shipped.axis_index(shipped.sun_altitude_deg, 50.0, 'sun altitude')
    ip = shipped.axis_index(shipped.pitch_deg, -20.0, 'pitch')
    irs = [shipped.axis_index(shipped.roll_deg, r, 'roll') for r in (-10.0, 0.0, 10.0)]
    for i, m in enumerate(methods):
        j = shipped.method_index(m)
        old = shipped.error_deg[j, ia][::6][:, ip][:, irs]
        # The shipped map stores float32 errors (|e| < 90 deg: a rounding of at most 4e-6 deg);
        # the slice is computed here in float64, in this process, without Dask (issue 17).
        assert np.abs(fresh.error_deg[i, 0, :, 0, :] - old).max() < 1e-5, m
        old_status = shipped.status[j, ia][::6][:, ip][:, irs]
        np.testing.assert_array_equal(fresh.status[i, 0, :, 0, :], old_status, err_msg=m)


# --------------------------------------------------------------------------------------------
# Accuracy inside the domain
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('method', PAPER_METHODS)
def test_inversion_is_within_0p2_deg_with_the_real_estimator(shipped, method):
    psi, h, p, r = domain_points(24, seed=hash(method) % 1000)
    meas = measured_by_estimator(method, psi, h, p, r, shipped.meta['sampling'][method]['knobs'])
    c = TiltCorrector(shipped, method)
    est, status, n_roots = c.correct_many(meas, h, p, r)
    assert np.all(status == STATUS_INT[CorrectionStatus.OK]) and np.all(n_roots == 1)
    resid = np.abs(cv.wrap_180_deg(est - psi))
    raw = np.abs(cv.wrap_180_deg(meas - psi))
    assert resid.max() < 0.2, (
        resid.max(),
        psi[resid.argmax()],
        h[resid.argmax()],
        p[resid.argmax()],
    )
    assert raw.max() > 10.0  # the points do exercise large tilt errors


@pytest.mark.parametrize('method', PAPER_METHODS)
def test_inversion_beats_subtraction_everywhere_in_the_domain(shipped, method):
    """Dense check against the closed-form level-assumption heading (20 000 off-grid points)."""
    psi, h, p, r = domain_points(20000, seed=7)
    meas = cv.wrap_180_deg(psi + level_assumption_error_deg(psi, h, p, r))
    c = TiltCorrector(shipped, method)
    inv, st_i, _ = c.correct_many(meas, h, p, r, mode='invert')
    sub, st_s, _ = c.correct_many(meas, h, p, r, mode='subtract')
    assert np.all(st_i == 0) and np.all(st_s == 0)
    e_inv = np.abs(cv.wrap_180_deg(inv - psi))
    e_sub = np.abs(cv.wrap_180_deg(sub - psi))
    assert e_inv.max() < 0.2
    assert e_sub.max() > 5.0 and np.sqrt(np.mean(e_sub**2)) > 20 * np.sqrt(np.mean(e_inv**2))


def test_cubic_is_needed_at_the_default_grid(shipped):
    """
    Multilinear interpolation misses 0.2 deg in a corner: the corrector must be cubic.

    Multilinear interpolation of the same map misses 0.2 deg in the sun-50/tilt-30 corner: the
    reason the corrector is cubic.
    """
    psi, h, p, r = domain_points(20000, seed=8, corner_fraction=0.5)
    meas = cv.wrap_180_deg(psi + level_assumption_error_deg(psi, h, p, r))
    lin, _, _ = TiltCorrector(shipped, 'least_squares', order=1).correct_many(meas, h, p, r)
    cub, _, _ = TiltCorrector(shipped, 'least_squares', order=3).correct_many(meas, h, p, r)
    assert (
        np.abs(cv.wrap_180_deg(lin - psi)).max() > 0.2 > np.abs(cv.wrap_180_deg(cub - psi)).max()
    )


def test_imu_noise_residual_grows_with_sigma(shipped):
    """The residual after correction with noisy pitch/roll (docs/error-maps.md tabulates it)."""
    psi, h, p, r = domain_points(20000, seed=9, corner_fraction=0.0)
    meas = cv.wrap_180_deg(psi + level_assumption_error_deg(psi, h, p, r))
    c = TiltCorrector(shipped, 'least_squares')
    rng = np.random.default_rng(10)
    rms = []
    for sigma in (0.0, 0.1, 0.5, 1.0):
        pn = np.clip(p + rng.normal(0, sigma, p.size), -30, 30)
        rn = r + rng.normal(0, sigma, r.size)
        over = np.abs(pn) + np.abs(rn) > 30
        rn = np.where(over, np.sign(rn) * (30 - np.abs(pn)), rn)
        est, st, _ = c.correct_many(meas, h, pn, rn)
        assert np.all(st == 0)
        rms.append(float(np.sqrt(np.mean(cv.wrap_180_deg(est - psi) ** 2))))
    assert rms[0] < 0.02
    assert rms[0] < rms[1] < rms[2] < rms[3] < 2.0, rms


# --------------------------------------------------------------------------------------------
# Domain and statuses
# --------------------------------------------------------------------------------------------
def test_outside_the_domain_is_a_status_not_an_extrapolation(shipped):
    c = TiltCorrector(shipped, 'least_squares')
    cases = [
        (10.0, 55.0, 0.0, 0.0, 'sun altitude'),
        (10.0, -1.0, 0.0, 0.0, 'sun altitude'),
        (10.0, 30.0, 31.0, 0.0, 'pitch'),
        (10.0, 30.0, 0.0, -31.0, 'roll'),
        (10.0, 30.0, 20.0, 10.5, 'exceeds'),
        (math.nan, 30.0, 0.0, 0.0, 'non-finite'),
        (10.0, 30.0, math.inf, 0.0, 'non-finite'),
    ]
    for meas, h, p, r, why in cases:
        out = c.correct(meas, h, p, r)
        assert out.status == CorrectionStatus.OUT_OF_DOMAIN and out.psi_deg is None, (h, p, r)
        assert why in out.reason
    for mode in ('invert', 'subtract'):
        psi, st, _ = c.correct_many(
            [10.0, 10.0], [30.0, 50.0001], [20.0, 0.0], [10.0, 0.0], mode=mode
        )
        assert list(st) == [0, STATUS_INT[CorrectionStatus.OUT_OF_DOMAIN]] and psi[1] == 0.0
    assert (
        c.correct(10.0, 50.0, 30.0, 0.0).ok and c.correct(10.0, 0.0, -15.0, -15.0).ok
    )  # the edges are inside
    with pytest.raises(ErrorMapError):
        c.correct_many(0.0, 10.0, 0.0, 0.0, mode='guess')


def _synthetic(err_fn, valid_fn=None, limit=30.0):
    A = np.arange(0.0, 51.0, 10.0)
    Y = np.arange(-180.0, 180.0, 5.0)
    T = np.arange(-30.0, 31.0, 5.0)
    h, y, p, r = np.meshgrid(A, Y, T, T, indexing='ij')
    e = cv.fold_axial_deg(err_fn(y, h, p, r))[None]
    st = np.zeros(e.shape, np.int8)
    if valid_fn is not None:
        st[0][~valid_fn(y, h, p, r)] = 2
    e = np.where(st == 0, e, 0.0)
    return ErrorMap(
        e, st, ('m',), A, Y, T, T, {'domain': {'tilt_limit_deg': limit, 'full_domain': False}}
    )


def test_correct_bearing_goes_through_psi_and_back_across_north():
    """
    The correction of a true bearing goes through psi and back across North.

    The nodes' and the replay's correction of a true bearing: truth 20 deg with the sun at azimuth
    300 (psi = 80, the wrap at North on the way), a gentle synthetic error; the corrected bearing
    is the truth in [0, 360). Out of the map: no bearing, the status says why.
    """
    m = _synthetic(lambda y, h, p, r: 0.1 * h * np.sin(np.radians(2 * y)) * (1 + 0 * p))
    c = TiltCorrector(m, 'm')
    truth, az, h = 20.0, 300.0, 40.0
    psi = truth - az + 360.0
    measured = (az + psi + 0.1 * h * math.sin(math.radians(2 * psi))) % 360.0
    bearing, corr = c.correct_bearing(measured, az, h, 0.0, 0.0)
    assert corr.ok and 0.0 <= bearing < 360.0 and abs(bearing - truth) < 0.01
    bearing, corr = c.correct_bearing(measured, az, h, 0.0, 31.0)
    assert bearing is None and corr.status == CorrectionStatus.OUT_OF_DOMAIN


def test_several_yaws_predicting_the_measurement_are_reported():
    """De/dpsi < -1 folds psi + e(psi): two or three true yaws give the same reading."""
    m = _synthetic(lambda y, h, p, r: 0.8 * h * np.sin(np.radians(2 * y)) * (1 + 0 * p))
    c = TiltCorrector(m, 'm')
    truth = 90.0
    e = 0.8 * 40 * math.sin(math.radians(2 * truth))
    out = c.correct(truth + e, 40.0, 0.0, 0.0)
    assert out.status == CorrectionStatus.MULTIPLE_SOLUTIONS and len(out.candidates_deg) >= 2
    assert min(abs(cv.wrap_180_deg(x - truth)) for x in out.candidates_deg) < 0.05
    assert out.psi_deg in out.candidates_deg
    # the same reading with a gentle slope has a single root
    m2 = _synthetic(lambda y, h, p, r: 0.1 * h * np.sin(np.radians(2 * y)) * (1 + 0 * p))
    assert TiltCorrector(m2, 'm').correct(truth, 40.0, 0.0, 0.0).ok


def test_nodes_without_estimates_fall_back_to_linear_or_refuse():
    def err(y, h, p, r):
        return 0.1 * h * (p * np.sin(np.radians(y)) + r * np.cos(np.radians(y))) / 30

    def hole(y, h, p, r):
        return ~((np.abs(p - 10) < 1e-9) & (np.abs(r - 5) < 1e-9) & (np.abs(h - 30) < 1e-9))

    m = _synthetic(err, hole)
    c = TiltCorrector(m, 'm')
    psi = 33.0
    # next to the hole: the cubic stencil reads it, the linear cell does not -> still corrected
    meas = psi + err(psi, 25.0, 3.0, -2.0)
    out = c.correct(meas, 25.0, 3.0, -2.0)
    assert out.ok and abs(out.psi_deg - psi) < 0.05
    # a cell with the hole as a corner: refused
    out = c.correct(meas, 32.0, 8.0, 6.0)
    assert out.status == CorrectionStatus.OUT_OF_DOMAIN and 'no valid estimate' in out.reason


def test_a_partial_yaw_axis_is_refused():
    m = _synthetic(lambda y, h, p, r: 0 * y)
    part = ErrorMap(
        m.error_deg[:, :, :36],
        m.status[:, :, :36],
        m.methods,
        m.sun_altitude_deg,
        m.yaw_deg[:36],
        m.pitch_deg,
        m.roll_deg,
        m.meta,
    )
    with pytest.raises(ErrorMapError, match='full turn'):
        TiltCorrector(part, 'm')
    with pytest.raises(ErrorMapError, match='not in this map'):
        TiltCorrector(m, 'zenith')


def test_correct_bearings_is_finite_with_an_explicit_status(shipped):
    """
    The vectorised correction is finite, with an explicit status per heading.

    The vectorised correction returns finite bearings, a validity mask and a status per heading: a
    heading without a valid correction (outside the map, non-finite input) is 0.0 with ``ok`` False
    and its status, never NaN; valid ones agree with the per-heading :meth:`correct_bearing` and,
    for a level camera (no tilt error), with the measured bearing itself.
    """
    c = TiltCorrector(shipped, 'least_squares')
    raw = np.array([10.0, 200.0, 10.0, math.nan, 10.0, 359.0])
    az = np.array([120.0, 300.0, 120.0, 120.0, math.inf, 15.0])
    h = np.array([30.0, 20.0, 55.0, 30.0, 30.0, 40.0])
    p = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    r = np.zeros(6)
    out = c.correct_bearings(raw, az, h, p, r)
    assert np.all(np.isfinite(out.bearing_deg))
    assert out.ok.tolist() == [True, True, False, False, False, True]
    assert out.status == ['ok', 'ok', 'out_of_domain', 'out_of_domain', 'out_of_domain', 'ok']
    assert np.all(out.bearing_deg[~out.ok] == 0.0)
    for i in np.flatnonzero(out.ok):
        one, corr = c.correct_bearing(raw[i], az[i], h[i], p[i], r[i])
        assert corr.ok and one == pytest.approx(out.bearing_deg[i], abs=1e-9)
        # level camera: the level-assumption heading has no tilt error to correct
        assert abs(cv.wrap_180_deg(out.bearing_deg[i] - raw[i])) < 0.05
    for i in np.flatnonzero(~out.ok):
        assert c.correct_bearing(raw[i], az[i], h[i], p[i], r[i])[0] is None
