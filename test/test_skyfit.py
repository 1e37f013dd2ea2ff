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
The whole-sky check on simulated skies with known truth.

The whole-sky check (skyfit) on simulated skies with known truth: the robust fit recovers the sun,
the jackknife sigma grows with a sky that disagrees with itself, the 180 deg side is re-decided by
the whole sky, a wrong polarizer convention is poor_fit, disagreeing methods are inconsistent; and
the node front end applies the same check.
"""

import math

import numpy as np
from polarization_compass.camera import CameraModel, PixelSelection, select_pixels
from polarization_compass.conventions import CameraAttitude, wrap_180_deg
from polarization_compass.demosaic import parse_layout
from polarization_compass.estimators.base import HeadingResult, Status
from polarization_compass.pipeline import HeadingFrontEnd
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
from polarization_compass.skyfit import (
    assess_result,
    data_mask,
    fit_sky,
    jackknife_sigma_deg,
    mark_inconsistent,
    misfit_at,
    sample_sky,
    side_preference,
)
import pytest

N = 160
CAM = CameraModel(
    model='fisheye_equidistant',
    width_px=N,
    height_px=N,
    focal_length_mm=(N / 2) * 3.45e-3 / (math.pi / 2),
    max_field_angle_deg=85.0,
)
PSI, ALT, SUN_AZ = 37.0, 40.0, 120.0


@pytest.fixture(scope='module')
def frame():
    scene = Scene(
        camera=CAM, pixels=PixelSelection.full(), sky={'model': 'rayleigh', 'dop_max': 0.7}
    )
    return Renderer(scene).render(
        attitude=CameraAttitude(PSI + SUN_AZ, 0.0, 0.0), sun=SunDirection(SUN_AZ, ALT)
    )


def _sample(f, aop=None, intensity=None):
    sp = select_pixels(CAM, PixelSelection.full())
    return sample_sky(f.aop_rad if aop is None else aop, f.dop, f.valid, sp.rays_cam, intensity)


def test_robust_fit_recovers_the_sun_of_a_clean_sky(frame):
    s = _sample(frame)
    f = fit_sky(s)
    assert abs(wrap_180_deg(f.psi_deg - PSI)) < 0.1 and abs(f.sun_altitude_deg - ALT) < 0.6
    assert f.scatter_deg < 0.05 and f.inlier_fraction > 0.999
    assert jackknife_sigma_deg(s, f.psi_deg, ALT) < 0.06


def test_outliers_do_not_pull_the_fit_but_raise_the_jackknife(frame):
    """
    Outliers do not pull the fit but raise the jackknife sigma.

    A quarter of the sky (one side) with its AoP turned by 30 deg: a least-squares fit would move
    by degrees; the Cauchy fit stays within 0.5 deg, and the sector jackknife reports the
    disagreement.
    """
    sp = select_pixels(CAM, PixelSelection.full())
    x = sp.rays_cam[0].reshape(frame.aop_rad.shape)
    aop = frame.aop_rad.copy()
    bad = x > 0.5
    aop[bad] = aop[bad] + np.float32(math.radians(30.0))
    s = _sample(frame, aop)
    f = fit_sky(s, ALT)
    assert abs(wrap_180_deg(f.psi_deg - PSI)) < 0.5
    assert f.inlier_fraction < 0.95
    assert jackknife_sigma_deg(s, f.psi_deg, ALT) > 5 * jackknife_sigma_deg(
        _sample(frame), PSI, ALT
    )


def test_side_and_poor_fit_and_prior(frame):
    s = _sample(frame)
    pref = side_preference(s, PSI, ALT)
    assert pref['pattern'] > 0.1 and side_preference(s, PSI + 180.0, ALT)['pattern'] < -0.1
    wrong = HeadingResult.from_psi(
        'zenith', PSI + 180.0, SUN_AZ, 0.2, 100, 1.0, False, 'from a small window'
    )
    fixed = assess_result(wrong, s, ALT)
    assert fixed.status == Status.OK and abs(wrap_180_deg(fixed.psi_deg - PSI)) < 1e-9
    assert 're-decided' in fixed.reason and fixed.sigma_deg >= 0.2
    kept = assess_result(
        wrong, s, ALT, prior_bearing_deg=PSI + 180.0 + SUN_AZ
    )  # a prior decides: untouched side
    assert abs(wrap_180_deg(kept.psi_deg - PSI - 180.0)) < 1e-9
    mirrored = _sample(frame, -frame.aop_rad)  # the flipped 45 deg direction
    res = assess_result(
        HeadingResult.from_psi('least_squares', -PSI, SUN_AZ, 0.1, 100, 1.0, False), mirrored, ALT
    )
    assert res.status == Status.POOR_FIT and 'no single sun' in res.reason
    failed = HeadingResult.failed('symmetry', Status.TOO_FEW_PIXELS, 'none')
    assert assess_result(failed, s, ALT) is failed
    assert assess_result(wrong, None, ALT) is wrong


def test_a_heading_the_whole_sky_does_not_support_is_inconsistent(frame):
    """
    A heading the whole sky does not support is inconsistent.

    Same sun, same tilt: the whole sky's own best heading is the truth, so a result 8 deg off with
    a 0.1 deg sigma is inconsistent (a level-assumption heading under a known tilt looks like
    this); 0.05 deg off is ok.
    """
    s = _sample(frame)
    off = assess_result(
        HeadingResult.from_psi('least_squares', PSI + 8.0, SUN_AZ, 0.1, 100, 1.0, False), s, ALT
    )
    assert off.status == Status.INCONSISTENT and 'fits best' in off.reason
    near = assess_result(
        HeadingResult.from_psi('least_squares', PSI + 0.05, SUN_AZ, 0.1, 100, 1.0, False), s, ALT
    )
    assert near.status == Status.OK


def test_misfit_statistics_against_a_known_rotation(frame):
    """Every AoP turned by 10 deg: the robust scatter is 1.4826 x 10 deg, nothing within 8 deg."""
    s = _sample(frame, frame.aop_rad + np.float32(math.radians(10.0)))
    m = misfit_at(s, PSI, ALT)
    assert m.scatter_deg == pytest.approx(14.826, abs=0.05)


def test_inconsistent_methods_are_marked():

    def mk(name, psi, sig):
        return HeadingResult.from_psi(name, psi, 0.0, sig, 100, 1.0, False)

    out = mark_inconsistent([mk('a', 10.0, 0.5), mk('b', 10.5, 0.5), mk('c', 30.0, 0.5)])
    assert [r.status for r in out] == [Status.OK, Status.OK, Status.INCONSISTENT]
    assert '3 sigma' in out[2].reason
    out = mark_inconsistent([mk('a', 10.0, 0.5), mk('b', 190.5, 0.5)])  # side disagreement
    assert all(r.status == Status.INCONSISTENT for r in out)
    out = mark_inconsistent([mk('a', 10.0, 5.0), mk('b', 20.0, 5.0)])  # within 3 combined sigmas
    assert all(r.status == Status.OK for r in out)


def test_data_mask_grows_saturation_into_glare():
    i = np.full((200, 200), 0.4, np.float32)
    i[100:110, 100:110] = 1.0  # 0.25 % of the image at the maximum: a clipped plateau
    keep = data_mask(i, np.ones((200, 200), bool), glare_fraction=0.02)
    r = round(0.02 * math.hypot(200, 200))
    assert not keep[105, 105] and not keep[105, 109 + r] and keep[105, 109 + r + 2] and keep[0, 0]
    assert data_mask(np.full((50, 50), 0.4, np.float32), np.ones((50, 50), bool)).all()


@pytest.mark.parametrize('pol45', ['+x-y', '+x+y'])
def test_front_end_sky_check(pol45):
    """
    The front end's sky check is ok at the truth and poor_fit otherwise.

    The node's front end with sky_check: a mosaic read with its own convention is ok at the truth;
    read with the other one it is poor_fit, never ok.
    """
    scene = Scene(
        camera=CAM,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor={'mosaic': {'pol45_toward': '+x-y'}},
    )
    f = Renderer(scene).render(
        attitude=CameraAttitude(PSI + SUN_AZ, 0.0, 0.0), sun=SunDirection(SUN_AZ, ALT)
    )
    front = HeadingFrontEnd(
        'least_squares', layout=parse_layout().angles_deg, pol45_toward=pol45, sky_check=True
    )
    res = front.estimate(f.mosaic, CAM, SUN_AZ, ALT)
    if pol45 == '+x-y':
        assert res.status == Status.OK and abs(wrap_180_deg(res.psi_deg - PSI)) < 0.2
        assert 'sky_check' in res.extras
    else:
        assert res.status != Status.OK


@pytest.mark.parametrize('method', ['least_squares', 'tilt_aware'])
def test_least_squares_robust_refit_ignores_a_disagreeing_sector(frame, method):
    """
    The least-squares robust refit ignores a disagreeing sector.

    30 % of the sky (rays with x > 0.5) with its AoP turned by 30 deg, as a cloud bank or a
    reflecting obstacle could: the plain total least squares is pulled by degrees; with
    ``outlier_deg`` the consensus refit (seeded by the robust whole-view sun, not by the pulled
    fit) is back on the truth.
    """
    from polarization_compass.estimators import make_estimator, Observation

    sp = select_pixels(CAM, PixelSelection.full())
    aop = frame.aop_rad.copy()
    aop[sp.rays_cam[0].reshape(aop.shape) > 0.5] += np.float32(math.radians(30.0))
    obs = Observation(
        aop,
        frame.dop,
        frame.valid,
        sp.rays_cam,
        sp.x_px,
        sp.y_px,
        CAM,
        SUN_AZ,
        ALT,
        None,
        0.0,
        0.0,
    )
    plain = make_estimator(method, stride=1, max_aop_noise_deg=90.0).estimate(obs)
    robust = make_estimator(method, stride=1, max_aop_noise_deg=90.0, outlier_deg=10.0).estimate(
        obs
    )
    assert abs(wrap_180_deg(plain.psi_deg - PSI)) > 5.0
    assert robust.status == Status.OK and abs(wrap_180_deg(robust.psi_deg - PSI)) < 0.05
    assert robust.extras['outliers_dropped'] > 0.2 * robust.pixels
    clean = Observation(
        frame.aop_rad,
        frame.dop,
        frame.valid,
        sp.rays_cam,
        sp.x_px,
        sp.y_px,
        CAM,
        SUN_AZ,
        ALT,
        None,
        0.0,
        0.0,
    )
    a = make_estimator(method, stride=2).estimate(clean)
    b = make_estimator(method, stride=2, outlier_deg=10.0).estimate(clean)
    assert (
        b.extras['outliers_dropped'] == 0 and b.psi_deg == a.psi_deg
    )  # a clean sky: nothing changes


def test_outlier_trim_pass_matches_an_independent_aop_residual():
    """
    The outlier trim pass matches an independent AoP residual.

    The compiled trim (float32, doubled angles, no trig of the residual) drops exactly the pixels
    whose axial AoP residual against the Rayleigh AoP of E = S x P (eq 18, 28: atan2(E_x, E_y))
    exceeds the limit, away from the limit itself; invalid pixels stay invalid, NaN AoP is kept for
    the fit's own pass.
    """
    import dataclasses

    from polarization_compass.estimators._outlier_trim import _trim_outliers

    rng = np.random.default_rng(3)
    n = 20000
    rays = rng.normal(size=(3, n))
    rays[2] = np.abs(rays[2])
    rays = (rays / np.linalg.norm(rays, axis=0)).astype(np.float32)
    sun = np.array([0.3, -0.5, 0.81])
    sun /= np.linalg.norm(sun)
    E = np.cross(sun[None, :], rays.T.astype(np.float64))
    model = np.arctan2(E[:, 0], E[:, 1])
    resid = rng.uniform(-90.0, 90.0, n)
    aop = (model + np.radians(resid) + np.pi * rng.integers(-2, 3, n)).astype(np.float32)
    valid = rng.random(n) > 0.1
    aop[:5] = np.nan

    @dataclasses.dataclass
    class V:
        aop: np.ndarray
        valid: np.ndarray
        rays: np.ndarray

    out, dropped = _trim_outliers(V(aop, valid, rays), sun, 15.0)
    far = np.abs(resid) > 15.0
    clear = np.abs(np.abs(resid) - 15.0) > 1e-3
    want = valid & ~(far & np.isfinite(aop))
    assert np.array_equal(out.valid[clear], want[clear])
    assert dropped == int((valid & ~out.valid).sum()) and dropped > 0.5 * valid.sum()
    assert out.valid[:5].tolist() == valid[:5].tolist()
