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
The attitude's uncertainty propagated into sigma (issue 16, error budget).

The error map's gradient against finite differences and against the derivative of a smooth
analytic map; the corrected heading's sensitivity against re-correcting at a perturbed tilt;
tilt_aware's analytic sensitivity against re-estimating; the stated tilt sigma of MountingErrors
against the spread of its draws; and the budget's sigma calibration with a known IMU noise.
"""

import math

import numpy as np
from polarization_compass.budget import run_budget
from polarization_compass.budget_config import BudgetConfig
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.conventions import CameraAttitude
from polarization_compass.correction import TiltCorrector
from polarization_compass.errormap import ErrorMap
from polarization_compass.estimators import registry
from polarization_compass.estimators.base import Observation
from polarization_compass.estimators.sun_from_evectors import tilt_sensitivity
from polarization_compass.motion import MountingErrors
from polarization_compass.render import Renderer
from polarization_compass.scene import Scene
import pytest

ALT = np.arange(0.0, 55.0, 5.0)
YAW = np.arange(-180.0, 180.0, 5.0)
TILT = np.arange(-30.0, 31.0, 5.0)


def smooth_error(a, y, p, r):
    """Return a smooth tilt error [deg] (periodic in yaw); its derivatives are written below."""
    return 0.02 * (60 - a) * (p * np.sin(np.radians(y)) + 0.5 * r * np.cos(np.radians(2 * y)))


def smooth_grad(a, y, p, r):
    k = 0.02 * (60 - a)
    de_dy = k * (p * np.cos(np.radians(y)) - r * np.sin(np.radians(2 * y))) * math.pi / 180
    return de_dy, k * np.sin(np.radians(y)), k * 0.5 * np.cos(np.radians(2 * y))


@pytest.fixture(scope='module')
def smooth():
    A, Y, P, R = np.meshgrid(ALT, YAW, TILT, TILT, indexing='ij')
    e = smooth_error(A, Y, P, R)[None]
    m = ErrorMap(
        e,
        np.zeros(e.shape, np.int8),
        ('least_squares',),
        ALT,
        YAW,
        TILT,
        TILT,
        meta={'domain': {'full_domain': True}},
    )
    return TiltCorrector(m, 'least_squares')


def _queries(n=60, seed=0):
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(-180, 180, n),
        rng.uniform(2, 48, n),
        rng.uniform(-25, 25, n),
        rng.uniform(-25, 25, n),
    )


@pytest.mark.parametrize('order', [3, 1])
def test_error_gradient_is_the_interpolants_derivative(smooth, order):
    tc = TiltCorrector(smooth.map, 'least_squares', order=order)
    psi, h, p, r = _queries()
    g = tc.error_gradient(psi, h, p, r)
    assert g[3].all()
    d = 1e-5
    for k, (a, b, c) in enumerate(((1, 0, 0), (0, 1, 0), (0, 0, 1))):
        fd = (
            tc.predicted_error(psi + d * a, h, p + d * b, r + d * c)[0]
            - tc.predicted_error(psi - d * a, h, p - d * b, r - d * c)[0]
        ) / (2 * d)
        assert np.max(np.abs(g[k] - fd)) < 1e-5 * max(1.0, np.max(np.abs(fd)))


def test_cubic_gradient_approaches_the_smooth_maps_derivative(smooth):
    psi, h, p, r = _queries(seed=1)
    g = smooth.error_gradient(psi, h, p, r)
    exact = smooth_grad(h, psi, p, r)
    # 5 deg nodes: the cubic's derivative is within a few % of the function's
    for k in range(3):
        scale = np.max(np.abs(exact[k]))
        assert np.max(np.abs(g[k] - exact[k])) < 0.03 * scale, k


@pytest.mark.parametrize('mode', ['invert', 'subtract'])
def test_heading_sensitivity_matches_recorrecting_at_a_perturbed_tilt(smooth, mode):
    psi_true, h, p, r = _queries(40, seed=2)
    meas = psi_true + smooth.predicted_error(psi_true, h, p, r)[0]
    d = 1e-4
    c0, st, _ = smooth.correct_many(meas, h, p, r, mode)
    ok = st == 0
    assert ok.mean() > 0.8
    jp, jr, jok = smooth.heading_sensitivity(c0 if mode == 'invert' else meas, h, p, r, mode)
    for j, (dp, dr) in ((jp, (d, 0)), (jr, (0, d))):
        hi = smooth.correct_many(meas, h, p + dp, r + dr, mode)[0]
        lo = smooth.correct_many(meas, h, p - dp, r - dr, mode)[0]
        fd = (hi - lo) / (2 * d)
        assert np.max(np.abs(j[ok] - fd[ok])) < 1e-4


def test_attitude_sigma_is_the_quadrature_of_the_sensitivities(smooth):
    psi, h, p, r = _queries(10, seed=3)
    jp, jr, _ = smooth.heading_sensitivity(psi, h, p, r)
    s, ok = smooth.attitude_sigma_deg(psi, h, p, r, 0.5, 2.0)
    assert ok.all() and np.allclose(s, np.sqrt((0.5 * jp) ** 2 + (2.0 * jr) ** 2))


SMALL = Scene(
    camera=CameraModel(width_px=96, height_px=80),
    pixels=PixelSelection.full(),
    sun_fixed=(120.0, 40.0),
    sky={'model': 'rayleigh', 'dop_max': 0.75},
    seed=3,
)


def test_tilt_aware_sensitivity_matches_re_estimating():
    frame = Renderer(SMALL).render(attitude=CameraAttitude(30.0, 6.0, -4.0))
    est = registry.make('tilt_aware')

    def psi(p, r, a=None):
        o = Observation.from_frame(frame, pitch_deg=p, roll_deg=r, attitude_sigma_deg=a)
        return est.estimate(o)

    base = psi(6.2, -3.9, (0.5, 1.0))
    jp, jr = tilt_sensitivity(base.extras['sun_cam'], 6.2, -3.9)
    d = 1e-3
    fd_p = (psi(6.2 + d, -3.9).psi_deg - psi(6.2 - d, -3.9).psi_deg) / (2 * d)
    fd_r = (psi(6.2, -3.9 + d).psi_deg - psi(6.2, -3.9 - d).psi_deg) / (2 * d)
    assert jp == pytest.approx(fd_p, abs=1e-5) and jr == pytest.approx(fd_r, abs=1e-5)
    assert abs(jp) + abs(jr) > 0.1  # a real sensitivity, not a vacuous zero
    fit = base.extras['sigma_fit_deg']
    assert base.extras['sigma_attitude_deg'] == pytest.approx(math.hypot(0.5 * jp, 1.0 * jr))
    assert base.sigma_deg == pytest.approx(math.hypot(fit, math.hypot(0.5 * jp, jr)))
    assert psi(6.2, -3.9).sigma_deg == pytest.approx(fit)  # no stated uncertainty: as before


def test_tilt_sigma_matches_the_spread_of_the_measured_tilt():
    me = MountingErrors(
        noise_deg=0.3,
        pitch_bias_deg=0.2,
        boresight_roll_deg=0.4,
        time_offset_s=0.02,
        tilt_rate_deg_s=25.0,
    )
    rng = np.random.default_rng(5)
    true = CameraAttitude(40.0, 0.0, 0.0)
    m = [me.measured_attitude(true, rng.standard_normal(3)) for _ in range(3000)]
    rms_p = math.sqrt(np.mean([a.pitch_deg**2 for a in m]))
    rms_r = math.sqrt(np.mean([a.roll_deg**2 for a in m]))
    sp, sr = me.tilt_sigma_deg(0.0)
    # the stated sigma is the RMS of the error (bias and boresight of their stated size)
    assert sp == pytest.approx(rms_p, rel=0.05) and sr == pytest.approx(rms_r, rel=0.05)


def test_budget_sigma_calibration_is_one_under_a_known_imu_noise():
    cfg = BudgetConfig(
        SMALL,
        samples=40,
        tilt_max_deg=8.0,
        imu=MountingErrors(noise_deg=1.0),
        methods=('zenith', 'tilt_aware'),
    )
    r = run_budget(cfg)
    assert r['correction']['methods'] == ['zenith']
    for m in ('zenith', 'tilt_aware'):
        st = r['conditions']['all'][m]
        # 40 draws of chi^2_1: the mean has sd sqrt(2/40) = 0.22; without the propagation it
        # was > 50
        assert 0.5 < st['sigma_calibration'] < 1.7, (m, st)
        assert st['sigma_band'] == 'honest'
        assert st['rms_deg'] > 0.2  # the IMU noise dominates: the test is about its share
    # no IMU noise: the corrected zenith's error is the map's residual, a few hundredths
    assert r['conditions']['without imu']['zenith']['rms_deg'] < 0.1


def test_budget_flags_an_uncorrected_tilt_error_as_overconfident():
    cfg = BudgetConfig(
        SMALL,
        samples=8,
        tilt_max_deg=8.0,
        methods=('zenith',),
        correction='none',
    )
    st = run_budget(cfg)['conditions']['all']['zenith']
    # the raw tilt error (degrees) against a statistical sigma: flagged, not hidden
    assert st['rms_deg'] > 1.0 and st['sigma_band'] == 'overconfident'
