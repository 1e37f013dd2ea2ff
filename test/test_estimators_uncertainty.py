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
The 1-sigma heading uncertainty of least_squares and tilt_aware is calibrated.

Over many noisy scenes mean(error^2 / sigma^2) lies in [0.7, 1.4] (issue 3), with independent
per-pixel AoP noise from the shot-noise formula sigma_AoP = 1 / (P sqrt(8 N)), with the sensor
noise of the IMX250MZR scene, with spatially correlated noise (as after bilinear demosaicing), and
on full frames through the sensor and both demosaics at 12 and 8 bit, level and tilted (slow).
"""

import math

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass.camera import CameraModel, PixelSelection
from polarization_compass.estimators import make_estimator, Observation, Status
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
import pytest
from test_estimators import _gauss_aop_noise, heading_error

SCENE = Scene()


def _z2(name, n_trials, noise, seed, selection, scene=SCENE, tilt=True, sigma_of=None, **knobs):
    rng = np.random.default_rng(seed)
    est = make_estimator(name, **knobs)
    r = Renderer(scene, pixels=selection)
    out = []
    for t in range(n_trials):
        alt, psi = rng.uniform(5, 70), rng.uniform(-180, 180)
        p, q = (rng.uniform(-15, 15), rng.uniform(-15, 15)) if tilt else (0.0, 0.0)
        f = r.render(attitude=cv.CameraAttitude(psi, p, q), sun=SunDirection(0.0, alt), seed=t)
        obs = Observation.from_frame(f, pitch_deg=p, roll_deg=q)
        if noise is not None:
            obs.aop_rad = noise(f, rng)
        res = est.estimate(obs)
        if res.status is Status.TOO_FEW_PIXELS:  # e.g. a small block next to the sun: no DoP left
            continue
        sigma = res.sigma_deg if sigma_of is None else sigma_of(res)
        out.append((heading_error(res, psi) / sigma) ** 2)
    assert len(out) >= 0.8 * n_trials
    return np.array(out)


@pytest.mark.parametrize('name,tilt', [('least_squares', False), ('tilt_aware', True)])
def test_uncertainty_calibrated_gaussian_aop_noise(name, tilt):
    scene = Scene(sky={'model': 'rayleigh', 'dop_max': 0.7})
    z2 = _z2(name, 250, _gauss_aop_noise(5000), 7, PixelSelection.grid(64, 54), scene, tilt=tilt)
    assert 0.8 <= z2.mean() <= 1.25, z2.mean()


@pytest.mark.parametrize('name,tilt', [('least_squares', False), ('tilt_aware', True)])
def test_uncertainty_calibrated_sensor_noise(name, tilt):
    """
    The uncertainty is calibrated under the noisy IMX250MZR scene.

    The scene config/scenes/imx250mzr_noisy.yaml (shot and read noise, extinction ratio, 12-bit
    quantisation, superpixel demosaic) on a 640 x 640 pixel block. Quantisation makes exact ties S1
    = 0 common, which once exposed a demosaic fold error (AoP -45 instead of +45 deg).
    """
    from polarization_compass.scene import load_scene

    scene = load_scene('config/scenes/imx250mzr_noisy.yaml')
    assert 'quantization' in scene.sensor
    z2 = _z2(name, 60, None, 3, PixelSelection.rect(905, 705, 640, 640), scene, tilt=tilt)
    assert 0.7 <= z2.mean() <= 1.4, z2.mean()


def test_correlated_noise_is_accounted_for():
    """
    Correlated noise is accounted for by the cluster-robust sigma.

    Noise smoothed over 3 x 3 pixels (like bilinear demosaicing): the cluster-robust sigma stays
    calibrated, while treating pixels as independent (block_px = 1) underestimates it; the
    delete-a-group jackknife (jackknife.jackknife_sigma_rad) then takes over. A small
    wide-angle camera (256 x 200 px, 82 deg across) keeps every pixel contiguous and the geometry
    well-conditioned.
    """
    import cv2

    def smooth_noise(f, rng):
        raw = rng.standard_normal(f.aop_rad.shape).astype(np.float32)
        k = np.array([0.5, 1.0, 0.5], np.float32)
        corr = cv2.sepFilter2D(raw, -1, k, k, borderType=cv2.BORDER_REFLECT_101) / 1.5
        sd = 1.0 / (np.maximum(f.dop, 1e-3) * math.sqrt(8.0 * 5000.0))
        return cv.fold_aop_rad((f.aop_rad + corr * sd).astype(np.float32))

    scene = Scene(camera=CameraModel(width_px=256, height_px=200, focal_length_mm=0.5))
    sel = PixelSelection.full()
    z_cluster = _z2('tilt_aware', 100, smooth_noise, 5, sel, scene, tilt=True, block_px=16)
    cluster_only = lambda res: res.extras['sigma_cluster_deg']  # noqa: E731
    z_naive = _z2(
        'tilt_aware', 40, smooth_noise, 5, sel, scene, tilt=True, block_px=1, sigma_of=cluster_only
    )
    z_naive_jk = _z2('tilt_aware', 40, smooth_noise, 5, sel, scene, tilt=True, block_px=1)
    assert 0.7 <= z_cluster.mean() <= 1.4, z_cluster.mean()
    assert z_naive.mean() > 2.0, z_naive.mean()
    # the delete-a-group jackknife over 16 sectors sees the correlation the 1 px blocks miss
    assert 0.7 <= z_naive_jk.mean() <= 1.4, z_naive_jk.mean()


# --------------------------------------------------------------------------------------------
# Full frames through the real sensor and demosaic path
# --------------------------------------------------------------------------------------------
def test_even_stride_reads_every_mosaic_phase_equally():
    """
    An even stride reads every mosaic phase equally.

    A full-resolution frame thinned by an even stride: least squares reads as many pixels as the
    plain stride, a quarter on each of the four 2 x 2 mosaic phases (a plain even stride reads one
    phase).
    """
    from polarization_compass.estimators._common import select_view, view_segments

    cam = CameraModel(width_px=203, height_px=150)
    f = Renderer(Scene(camera=cam), pixels=PixelSelection.full()).render(
        attitude=cv.CameraAttitude(10.0, 0.0, 0.0), sun=SunDirection(0.0, 30.0)
    )
    obs = Observation.from_frame(f, camera=cam)
    for stride, region in ((2, None), (4, None), (4, (11, 20, 101, 77)), (6, None)):
        knobs = {'stride': stride, 'region': region}
        plain = select_view(obs, knobs)
        v = select_view(obs, knobs, balance_phases=True)
        assert len(np.unique((plain.x_px % 2) * 2 + plain.y_px % 2)) == 1  # one phase
        assert abs(v.aop.size - plain.aop.size) <= 0.1 * plain.aop.size
        for axis in (
            np.unique(v.x_px),
            np.unique(v.y_px),
        ):  # rows and columns: half odd, half even
            odd = int((axis % 2).sum())
            assert abs(2 * odd - axis.size) <= 1, axis
        assert v.aop.size == np.unique(v.x_px).size * np.unique(v.y_px).size
        # each pixel once, with its own values and ray
        assert len(set(zip(v.x_px, v.y_px))) == v.aop.size
        yi, xi = (v.y_px - 1).astype(int), (v.x_px - 1).astype(int)
        assert np.array_equal(v.aop, f.aop_rad[yi, xi]) and np.array_equal(
            v.valid, f.valid[yi, xi]
        )
        assert np.array_equal(v.rays, f.rays_cam.reshape(3, *f.aop_rad.shape)[:, yi, xi])
        # the uncertainty blocks: every pixel in one run, each run inside one 32 px block
        _, (start, end, block, n_blocks) = view_segments(v, 32)
        seen = np.zeros(v.aop.size, int)
        for a, b, g in zip(start, end, block):
            seen[a:b] += 1
            assert (
                np.ptp(np.floor((v.x_px[a:b] - 0.5) / 32)) == 0
                and np.ptp(np.floor((v.y_px[a:b] - 0.5) / 32)) == 0
            )
            assert 0 <= g < n_blocks
        assert seen.min() == 1 and seen.max() == 1
    # an odd stride and the superpixel grid are left alone
    assert select_view(obs, {'stride': 3, 'region': None}, balance_phases=True).grid is not None


#: IMX250MZR-like sensor as in the benchmark's noisy conditions: 5000 e- per unpolarized pixel
#: (fill of a 10.5 ke- well), shot noise, 2.3 e- read noise, extinction ratio 100, 12 or 8 bit;
#: Rayleigh sky, DoP_max 0.7.
def _imx_scene(bits):
    from polarization_compass.scene import load_scene

    sc = load_scene('config/scenes/imx250mzr_noisy.yaml')
    sensor = dict(
        sc.sensor,
        exposure={'full_well_e': 10500, 'fill': 5000.0 / 10500},
        quantization={'bits': bits},
        demosaic='superpixel',
    )
    return sc.replace(sky={'model': 'rayleigh', 'dop_max': 0.7}, sensor=sensor)


def _sensor_path_z2(bits, n_scenes, seed, tilted):
    """
    (condition, err^2 / sigma^2) over ``n_scenes`` full 2448 x 2048 frames.

    Each frame is one render through the sensor (mosaic, shot and read noise, extinction ratio,
    quantisation, superpixel demosaic), estimated at the default settings; its raw mosaic also goes
    through the mosaic front-end's bilinear demosaic, estimated at stride 1, 2 or 4 in turn (scene
    i: (1, 2, 4)[i % 3]). Level scenes: least_squares; tilted: tilt_aware given the true tilt,
    |pitch| + |roll| <= 20 deg. Sun 10-60 deg (tilted 10-50) at any azimuth, any bearing.
    """
    from polarization_compass.estimators.mosaic_input import observation_from_mosaic

    scene = _imx_scene(bits)
    cam = scene.camera
    r = Renderer(scene, pixels=PixelSelection.full())
    name = 'tilt_aware' if tilted else 'least_squares'
    ests = {1: make_estimator(name), **{s: make_estimator(name, stride=s) for s in (2, 4)}}
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_scenes):
        sun = SunDirection(rng.uniform(0, 360), rng.uniform(10, 50 if tilted else 60))
        pitch = roll = 0.0
        if tilted:
            pitch = rng.uniform(-20, 20)
            roll = rng.uniform(-1, 1) * (20 - abs(pitch))
        att = cv.CameraAttitude(rng.uniform(0, 360), pitch, roll)
        f = r.render(attitude=att, sun=sun, seed=int(rng.integers(2**31)))
        stride = (1, 2, 4)[i % 3]
        for cond, obs, est in (
            (
                'superpixel',
                Observation.from_frame(f, pitch_deg=pitch, roll_deg=roll, camera=cam),
                ests[1],
            ),
            (
                f'bilinear stride {stride}',
                observation_from_mosaic(
                    f.mosaic,
                    cam,
                    sun.azimuth_deg,
                    sun.altitude_deg,
                    method='bilinear',
                    saturation_level=2**bits - 1,
                    pitch_deg=pitch,
                    roll_deg=roll,
                ),
                ests[stride],
            ),
        ):
            res = est.estimate(obs)
            assert res.status is Status.OK, (cond, res.status, res.reason)
            out.append((cond, (heading_error(res, f.psi_deg) / res.sigma_deg) ** 2))
    return out


def _means(groups):
    """Mean err^2 / sigma^2 and count per named group of (condition, z2) records."""
    return {k: (float(np.mean([z for _, z in v])), len(v)) for k, v in groups.items()}


@pytest.mark.slow
def test_uncertainty_calibrated_full_frames_through_the_sensor():
    """
    The uncertainty is calibrated on full frames through the sensor path.

    Issue 3's calibration at the default full-frame configuration through the real sensor and
    demosaic path (:func:`_sensor_path_z2`): IMX250MZR-like noise at 12 bit (100 level scenes for
    least_squares, 100 tilted for tilt_aware) and 8 bit (50 + 50), superpixel demosaic at the
    default settings and the front-end's bilinear demosaic at stride 1, 2, 4. Full frames, not a
    region: the O(sigma^2) biases that do not shrink with the pixel count matter most there (a
    plain even stride of a bilinear frame reads one mosaic phase: 2-4 here, while a 1024 px region
    hid it at stride 4).

    Statistics: calibrated, z = err / sigma is N(0, 1) in every scene, z^2 is chi-square(1) and the
    mean of n independent scenes is Gamma(n / 2, 2 / n) (sd sqrt(2 / n)). The issue's bound [0.7,
    1.4] is asserted on groups of 133-200 scenes: each estimator (150 scenes over both bit depths;
    its two values per scene are correlated, so counted as 150), the superpixel default at 12 bit
    (200) and the even bilinear strides at 12 bit (133). A calibrated sigma falls outside with
    probability 0.06-0.5 % per group, and a sigma too small by sqrt(2) (mean 2) passes with
    probability <= 0.34 %. The 8-bit scenes as one group (100 scenes, two correlated values each):
    <= 1.5 % and <= 1 %. Single conditions (33-100 scenes) get [0.5, 2] (outside with probability
    0.8 % at 33 scenes, 0.02 % at 67): a one-phase stride 2 (3.5 here) still fails there. Measured
    with 300 scenes per bit depth and geometry (docs/estimators.md): 1.0-1.1 pooled, 0.9-1.3 per
    condition.
    """
    runs = {
        ('least_squares', 12): _sensor_path_z2(12, 100, 41, False),
        ('tilt_aware', 12): _sensor_path_z2(12, 100, 42, True),
        ('least_squares', 8): _sensor_path_z2(8, 50, 43, False),
        ('tilt_aware', 8): _sensor_path_z2(8, 50, 44, True),
    }
    groups = {}
    for (name, bits), recs in runs.items():
        groups.setdefault(name, []).extend(recs)
        for cond, z in recs:
            groups.setdefault(f'{cond}, {bits} bit', []).append((cond, z))
            if bits == 12 and cond.startswith('bilinear') and not cond.endswith(' 1'):
                groups.setdefault('bilinear even strides, 12 bit', []).append((cond, z))
        if bits == 8:
            groups.setdefault('all, 8 bit', []).extend(recs)
    means = _means(groups)
    strict = (
        'least_squares',
        'tilt_aware',
        'superpixel, 12 bit',
        'bilinear even strides, 12 bit',
        'all, 8 bit',
    )
    bad = {
        k: m
        for k, m in means.items()
        if not ((0.7 <= m[0] <= 1.4) if k in strict else (0.5 <= m[0] <= 2.0))
    }
    assert not bad, (bad, means)


def test_cr1_factor_is_the_published_small_sample_factor():
    """
    The CR1 factor is the published small-sample factor (Cameron & Miller 2015).

    Cameron & Miller (2015): c = G / (G - 1) * (N - 1) / (N - K); each part 1 where undefined.
    """
    from polarization_compass.estimators._common import cr1_factor

    assert math.isclose(cr1_factor(10, 100, 2), (10 / 9) * (99 / 98), rel_tol=1e-15)
    assert math.isclose(cr1_factor(50, 51, 1), 50 / 49, rel_tol=1e-15)
    assert (
        cr1_factor(1, 100, 2) == 99 / 98
        and cr1_factor(5, 2, 2) == 5 / 4
        and cr1_factor(0, 0, 2) == 1.0
    )


def test_disc_and_least_squares_sigmas_use_the_same_cr1_factor():
    """
    The disc and least-squares sigmas use the same CR1 factor.

    The compiled least-squares block sigma and the disc methods' block sigma agree with a plain
    sandwich times the factor, for the same block sums (n = 40 pixels, 3 blocks).
    """
    from polarization_compass.estimators._disc_sigma import cr1_sigma
    from polarization_compass.estimators._ls_sigma import _block_sigmas

    b = np.array([0.3, -0.1, 0.25])
    want = math.sqrt(float(b @ b) * (3 / 2) * (39 / 38))
    assert math.isclose(cr1_sigma(np.concatenate([b, [0.0, 0.0]]), 40), want, rel_tol=1e-14)
    # least squares: block influence -s^T M_b c with s = e_x, c = e_x, M_b = -b_g e_x e_x^T; equal
    # block weights, so the centring removes the mean
    block_m = np.zeros((3, 3, 3))
    block_m[:, 0, 0] = -b
    got = _block_sigmas(
        block_m, np.ones(3), 40, np.array([1.0, 0.0, 0.0]), np.array([[1.0, 0.0, 0.0]])
    )[0]
    d = b - b.mean()
    assert math.isclose(got, math.sqrt(float(d @ d) * (3 / 2) * (39 / 38)), rel_tol=1e-12)
