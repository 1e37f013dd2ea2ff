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
Sensor effects against Malus's law and published noise figures.

Sensor effects: the forward model against Malus's law, ideal round trips through both demosaics and
both 45-deg directions, noise statistics against the published sigma_AoP = 1 / (P sqrt(8 N)), the
random number generator against the normal and Poisson laws, extinction ratio, quantisation,
reproducibility, instrumentation and configuration errors.
"""

import math
from pathlib import Path

import numpy as np
from polarization_compass import instrumentation as instr
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.conventions import CameraAttitude, fold_axial_rad
from polarization_compass.demosaic import polarization_from_mosaic
from polarization_compass.mosaic import IMX250MZR_POL45
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene, SceneError
from polarization_compass.scene_load import load_scene, scene_from_dict
from polarization_compass.sensor import (
    parse_sensor_config,
    SensorError,
    SensorPipeline,
    simulate_mosaic,
    standard_normal_f32,
)
from polarization_compass.sky import RayleighSky
import pytest

REPO = Path(__file__).resolve().parent.parent
ATT = CameraAttitude(30.0, -20.0, 10.0)
SUN = SunDirection(100.0, 35.0)
REGION = PixelSelection.rect(1001, 801, 320, 256)  # 1-based, even offset from the sensor's corner


def ang_err_deg(a, b):
    return np.degrees(np.abs(fold_axial_rad(np.asarray(a, float) - np.asarray(b, float))))


def render(sensor, pixels=REGION, seed=0, att=ATT, sun=SUN, **scene_kw):
    scene = Scene(pixels=pixels, sensor=sensor, **scene_kw)
    return Renderer(scene).render(attitude=att, sun=sun, seed=seed)


def malus_electrons(aop, dop, n0, layout, pol45, x0=1, y0=1, d=1.0, s0=None):
    """
    Return the mean electrons per pixel from Malus's law with vectors.

    The unpolarized part (1 - dP) / 2 plus dP cos^2 of the angle between E = (sin a, cos a) and the
    polarizer axis, times 2 N0 S0.
    """
    h, w = aop.shape
    rows = (np.arange(h) + y0 - 1) % 2
    cols = (np.arange(w) + x0 - 1) % 2
    theta = np.radians(np.array(layout, float))[rows[:, None], cols[None, :]]
    ux, uy = np.cos(theta), np.sin(theta) * (1 if pol45 == '+x+y' else -1)
    a = aop.astype(float)
    cos2 = (np.sin(a) * ux + np.cos(a) * uy) ** 2
    p = d * dop.astype(float)
    s = 1.0 if s0 is None else s0.astype(float)
    return 2 * n0 * s * ((1 - p) / 2 + p * cos2)


# ------------------------------------------------------------------------------------------------
# Forward model and ideal round trips
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize('pol45', ['+x+y', '+x-y'])
@pytest.mark.parametrize('layout', [[[90, 45], [135, 0]], [[0, 135], [45, 90]]])
def test_mosaic_follows_malus_law(pol45, layout):
    region = PixelSelection.rect(1002, 803, 64, 48)  # odd phase: (x0 - 1, y0 - 1) = (1001, 802)
    ideal = render({}, pixels=region)
    f = render(
        {'mosaic': {'layout': layout, 'pol45_toward': pol45}, 'extinction_ratio': {'value': 50}},
        pixels=region,
    )
    assert f.mosaic.dtype == np.float32 and f.mosaic.shape == (48, 64)
    ref = malus_electrons(ideal.aop_rad, ideal.dop, 5250.0, layout, pol45, 1002, 803, d=49 / 51)
    np.testing.assert_allclose(f.mosaic, ref, rtol=2e-6, atol=2e-3)
    np.testing.assert_array_equal(f.aop_ideal_rad, ideal.aop_rad)


@pytest.mark.parametrize('pol45', ['+x+y', '+x-y'])
@pytest.mark.parametrize('layout', [[[90, 45], [135, 0]], [[135, 0], [45, 90]]])
def test_ideal_round_trip_bilinear(pol45, layout):
    f = render(
        {'mosaic': {'layout': layout, 'pol45_toward': pol45}, 'demosaic': 'bilinear'},
        pixels=PixelSelection.full(),
    )
    v = f.valid
    assert f.aop_rad.shape == (2048, 2448) and v.mean() > 0.99
    err = ang_err_deg(f.aop_rad, f.aop_ideal_rad)
    inner = np.zeros_like(v)
    inner[2:-2, 2:-2] = True
    # measured here: interior max 0.0034 deg, median 3e-6 deg; the outer two rows/columns
    # (mirrored, one-sided interpolation) up to 0.062 deg; DoP within 4e-4
    assert err[v & inner].max() < 0.01
    assert np.median(err[v]) < 1e-4
    assert err[v].max() < 0.1
    assert np.abs(f.dop - f.dop_ideal)[v].max() < 1e-3
    assert np.all(f.aop_rad[~v] == 0) and np.all(f.dop[~v] == 0)


@pytest.mark.parametrize('pol45', ['+x+y', '+x-y'])
@pytest.mark.parametrize('region', [REGION, PixelSelection.rect(1002, 802, 321, 255)])
def test_ideal_round_trip_superpixel_against_the_sky_at_block_centres(pol45, region):
    f = render({'mosaic': {'pol45_toward': pol45}, 'demosaic': 'superpixel'}, pixels=region)
    x0, y0, w, h = region.region
    assert f.aop_rad.shape == (h // 2, w // 2)
    np.testing.assert_array_equal(f.x_px[0, :3], x0 + 0.5 + np.array([0, 2, 4]))
    np.testing.assert_array_equal(f.y_px[:3, 0], y0 + 0.5 + np.array([0, 2, 4]))
    rays, _ = CameraModel().rays_from_pixels(f.x_px, f.y_px)
    np.testing.assert_allclose(f.rays_cam, rays, atol=1e-7)
    # independent: the sky model evaluated at the block-centre rays
    a_ref, d_ref, _ = RayleighSky(1.0).polarization(f.sun_cam, f.zenith_cam, f.rays_cam)
    v = f.valid
    assert v.mean() > 0.99
    assert ang_err_deg(f.aop_rad[v], a_ref.reshape(v.shape)[v]).max() < 0.01  # measured 0.004 deg
    assert np.abs(f.dop - d_ref.reshape(v.shape))[v].max() < 1e-3
    assert ang_err_deg(f.aop_ideal_rad[v], a_ref.reshape(v.shape)[v]).max() < 0.01


def test_pol45_mismatch_is_caught_by_the_round_trip():
    """The round trip can fail: a '+x+y' mosaic read as '+x-y' mirrors the AoP."""
    f = render({'mosaic': {'pol45_toward': '+x+y'}})
    a, _, ok = polarization_from_mosaic(
        f.mosaic, [[90, 45], [135, 0]], '+x-y', 'bilinear', saturation_level=10500
    )
    ok &= f.valid & (np.abs(f.aop_ideal_rad) > 0.1) & (np.abs(f.aop_ideal_rad) < 1.4)
    assert ang_err_deg(a[ok], f.aop_ideal_rad[ok]).min() > 5


def test_region_mosaic_is_the_matching_block_of_the_full_sensor():
    full = render({'mosaic': {}}, pixels=PixelSelection.full())
    part = render({'mosaic': {}}, pixels=PixelSelection.rect(101, 52, 40, 30))
    np.testing.assert_allclose(part.mosaic, full.mosaic[51:81, 100:140], rtol=1e-6)


def test_strided_pixels_are_refused():
    scene = Scene(pixels=PixelSelection.rect(1, 1, 100, 100, stride=2), sensor={'mosaic': {}})
    with pytest.raises(SensorError, match='contiguous'):
        Renderer(scene).render(attitude=ATT, sun=SUN)


# ------------------------------------------------------------------------------------------------
# Noise
# ------------------------------------------------------------------------------------------------
def uniform_mosaic(sensor, aop=0.3, dop=0.5, shape=(512, 512), seed=0, s0=None):
    cfg = parse_sensor_config(sensor)
    a = np.full(shape, aop, np.float32)
    d = np.full(shape, dop, np.float32)
    return simulate_mosaic(a, d, s0, cfg, cfg.layout, np.random.default_rng(seed)), cfg


@pytest.mark.parametrize(
    'extra,n_e', [({}, 5000.0), ({'read_noise': {'sigma_e': 30.0}}, 5000.0 + 900.0)]
)
@pytest.mark.parametrize('method', ['superpixel', 'bilinear'])
def test_aop_noise_matches_the_published_formula(extra, n_e, method):
    """
    The AoP noise matches the published formula.

    sigma_AoP = 1 / (P sqrt(8 N)) per superpixel (physics notes 4): N = 5000 e-, P = 0.5 -> 0.573
    deg. Read noise adds its variance to N's (shot variance = N). Bilinear, derived here: a pixel's
    S1 (or S2) takes one channel from the centre sample (variance N) and the other from the mean of
    4 diagonal samples (N / 4) or of two pairs (N / 2 + N / 2): variances (1.25 N, N) or (N, 1.25
    N), so over all pixels var(2 AoP) = 1.125 N / |S12|^2 instead of 2 N / |S12|^2: sigma 0.75 x
    the superpixel's.
    """
    sensor = {'exposure': {'full_well_e': 20000, 'fill': 0.25}, 'shot_noise': {}, **extra}
    m, cfg = uniform_mosaic(sensor)
    a, d, ok = polarization_from_mosaic(
        m, cfg.layout, method=method, saturation_level=cfg.full_well_e
    )
    assert ok.all()
    if method == 'bilinear':
        a, d = a[2:-2, 2:-2], d[2:-2, 2:-2]  # the mirrored border pixels weigh samples differently
    err = fold_axial_rad(a.astype(float) - 0.3)
    # var(S1) = var(I0) + var(I90) = 2 n_e, |S12| = 2 N P, sigma_AoP = sqrt(2 n_e) / (4 N P) = 1 /
    # (P sqrt(8 N))
    predicted = math.degrees(math.sqrt(2 * n_e) / (4 * 5000.0 * 0.5)) * (
        1.0 if method == 'superpixel' else 0.75
    )
    assert (
        abs(math.degrees(err.std()) / predicted - 1) < 0.03
    )  # 65 536 samples: ~0.3 % standard error
    assert abs(math.degrees(err.mean())) < 0.01
    if not extra and method == 'superpixel':
        assert abs(predicted - 0.573) < 0.001
    assert abs(d.mean() - 0.5) < 2e-3


def test_low_counts_are_exactly_poisson():
    m, _ = uniform_mosaic(
        {'exposure': {'full_well_e': 1000, 'fill': 0.004}, 'shot_noise': {}},
        dop=0.0,
        shape=(400, 500),
    )
    lam = 4.0
    assert np.all(m == np.rint(m))  # integer electrons
    k = m.astype(int).ravel()
    assert abs(k.mean() - lam) < 0.02 and abs(k.var() - lam) < 0.06
    counts = np.bincount(k, minlength=12)[:12] / k.size
    pmf = np.array([math.exp(-lam) * lam**j / math.factorial(j) for j in range(12)])
    se = np.sqrt(pmf * (1 - pmf) / k.size)
    assert np.all(np.abs(counts - pmf) < 5 * se + 1e-6)


def test_high_counts_mean_and_variance():
    m, _ = uniform_mosaic(
        {
            'exposure': {'full_well_e': 1e5, 'fill': 0.01},
            'shot_noise': {},
            'read_noise': {'sigma_e': 5.0},
        },
        dop=0.0,
        shape=(400, 500),
    )
    x = m.astype(float).ravel()
    assert abs(x.mean() - 1000) < 0.3
    assert abs(x.var() / 1025 - 1) < 0.015


def test_normal_generator_follows_the_normal_law():
    z = standard_normal_f32(20240601, 2_000_000).astype(float)
    assert abs(z.mean()) < 0.003 and abs(z.std() - 1) < 0.002
    assert abs(np.mean(z**3)) < 0.01 and abs(np.mean(z**4) - 3) < 0.03
    zs = np.sort(z)
    grid = np.linspace(-4.5, 4.5, 91)
    emp = np.searchsorted(zs, grid) / zs.size
    cdf = 0.5 * (1 + np.vectorize(math.erf)(grid / math.sqrt(2)))
    assert np.abs(emp - cdf).max() < 1.5e-3  # Kolmogorov 1 % bound ~1.1e-3
    tail = np.mean(np.abs(z) > 3.6541528853610088)  # beyond the ziggurat's base: tail path
    assert (
        abs(tail / math.erfc(3.6541528853610088 / math.sqrt(2)) - 1) < 0.2
    )  # 516 expected, sd 23


def test_noise_kernel_normals_equal_the_reference_stream():
    """Read noise of sigma 1 on zero signal is the generator's stream itself (two code paths)."""
    cfg = parse_sensor_config({'read_noise': {'sigma_e': 1.0}})
    rng = np.random.default_rng(9)
    key = int(np.random.default_rng(9).integers(0, 2**63, dtype=np.int64))
    zero = np.zeros((64, 80), np.float32)
    m = simulate_mosaic(zero, zero, zero, cfg, cfg.layout, rng)
    z = standard_normal_f32(key, (64, 80))
    np.testing.assert_array_equal(m, np.minimum(z, np.float32(cfg.full_well_e)))


def test_same_seed_same_mosaic_whatever_the_thread_count():
    import numba

    sensor = {'shot_noise': {}, 'read_noise': {}, 'quantization': {'bits': 12}}
    a = render(sensor, seed=5)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        b = render(sensor, seed=5)
    finally:
        numba.set_num_threads(before)
    c = render(sensor, seed=6)
    np.testing.assert_array_equal(a.mosaic, b.mosaic)
    np.testing.assert_array_equal(a.aop_rad, b.aop_rad)
    assert np.mean(a.mosaic != c.mosaic) > 0.9


# ------------------------------------------------------------------------------------------------
# Extinction ratio, quantisation, saturation, radiance
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize('er', [2.0, 20.0, 300.0])
@pytest.mark.parametrize('method', ['superpixel', 'bilinear'])
def test_extinction_ratio_scales_dop_by_d(er, method):
    d = (er - 1) / (er + 1)
    # a uniform sky patch: exactly d * DoP, AoP unchanged
    for dop in (0.1, 0.5, 1.0):
        m, cfg = uniform_mosaic(
            {'extinction_ratio': {'value': er}}, aop=-0.7, dop=dop, shape=(8, 10)
        )
        a, dm, ok = polarization_from_mosaic(
            m, cfg.layout, method=method, saturation_level=cfg.full_well_e
        )
        assert ok.all()
        np.testing.assert_allclose(dm, d * dop, rtol=1e-5)
        assert ang_err_deg(a, -0.7).max() < 1e-4
    # a rendered sky: the same sensor with ideal polarizers, times d. Not exact: where the field
    # varies, the four channels of a pixel come from neighbouring positions and S0 keeps a residual
    # ~ d * dP/dx.
    f = render({'extinction_ratio': {'value': er}, 'demosaic': method})
    g = render({'mosaic': {}, 'demosaic': method})
    v = f.valid & g.valid & (g.dop > 0.05)
    np.testing.assert_allclose(f.dop[v] / g.dop[v], d, rtol=1e-3)
    assert ang_err_deg(f.aop_rad[v], g.aop_rad[v]).max() < 1e-3


@pytest.mark.parametrize('bits', [8, 10, 12, 16])
def test_quantisation_to_bits(bits):
    f = render({'quantization': {'bits': bits}})
    top = 2**bits - 1
    assert f.mosaic.dtype == (np.uint8 if bits == 8 else np.uint16)
    assert f.mosaic.max() <= top
    e = render({'mosaic': {}}).mosaic.astype(float)  # the same frame, unquantised
    ref = np.clip(np.floor(e * top / 10500 + 0.5), 0, top)
    diff = f.mosaic.astype(float) - ref
    # float32 products can land on the other side of a .5 boundary: at most 1 DN, rarely
    assert np.abs(diff).max() <= 1 and np.mean(diff != 0) < 1e-3


def test_fewer_bits_more_aop_error():
    errs = {}
    for bits in (8, 12):
        f = render({'quantization': {'bits': bits}, 'demosaic': 'superpixel'})
        v = f.valid & (f.dop_ideal > 0.3)
        errs[bits] = np.sqrt(np.mean(ang_err_deg(f.aop_rad[v], f.aop_ideal_rad[v]) ** 2))
    # quantisation step 1 DN: sigma_S ~ step / sqrt(12) per sample; 16x finer at 12 bits
    assert errs[8] > 8 * errs[12]
    assert errs[8] < 0.5


def test_saturated_pixels_are_invalid_not_nan():
    f = render({'exposure': {'fill': 0.7}, 'quantization': {'bits': 12}, 'shot_noise': {}})
    sat = f.mosaic == 4095
    assert sat.any() and (~sat).any()
    assert np.all(np.isfinite(f.aop_rad)) and np.all(np.isfinite(f.dop))
    import cv2

    touched = cv2.dilate(sat.view(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert not np.any(f.valid & touched)


def test_radiance_scales_the_electrons_and_bad_radiance_is_dark():
    cfg = parse_sensor_config({'mosaic': {}})
    rng = np.random.default_rng(0)
    a = np.full((6, 8), 0.2, np.float32)
    d = np.full((6, 8), 0.4, np.float32)
    s0 = np.linspace(0.5, 1.2, 48).reshape(6, 8).astype(np.float32)  # stays below full well
    m = simulate_mosaic(a, d, s0, cfg, cfg.layout, rng)
    np.testing.assert_allclose(
        m, malus_electrons(a, d, 5250.0, cfg.layout.angles_deg, IMX250MZR_POL45, s0=s0), rtol=2e-6
    )
    s0[0, 0], s0[0, 1], s0[0, 2] = np.nan, np.inf, -1
    m = simulate_mosaic(a, d, s0, cfg, cfg.layout, rng)
    assert np.all(m[0, :3] == 0) and np.all(np.isfinite(m))


def test_superpixel_frame_carries_block_mean_intensity():
    scene = Scene(
        pixels=PixelSelection.rect(1, 1, 8, 6), sensor={'demosaic': 'superpixel', 'mosaic': {}}
    )
    r = Renderer(scene)
    f = r.render(attitude=ATT, sun=SUN)
    ideal = Renderer(Scene(pixels=PixelSelection.rect(1, 1, 8, 6))).render(attitude=ATT, sun=SUN)
    # a frame with intensity, built by hand (no radiance model needed): the pipeline averages it
    ideal.intensity = np.arange(48, dtype=np.float32).reshape(6, 8) + 1
    expect = ideal.intensity.reshape(3, 2, 4, 2).mean(axis=(1, 3))
    r.sensor.apply(ideal, np.random.default_rng(0))
    np.testing.assert_allclose(ideal.intensity, expect, rtol=1e-6)
    assert ideal.aop_rad.shape == f.aop_rad.shape == (3, 4)


# ------------------------------------------------------------------------------------------------
# Instrumentation, configuration, shipped scene
# ------------------------------------------------------------------------------------------------
# Which kernels compute each effect, written down here (not read from the code): a declared effect
# must run one of them, an undeclared one none of them. test_kernel_table_matches_the_code keeps
# the two in step.
EFFECT_KERNELS = {
    'mosaic': {
        '_mean_electrons_kernel',
        '_mean_electrons_er_kernel',
        '_mean_electrons_cal_kernel',
    },
    'extinction_ratio': {'_mean_electrons_er_kernel'},
    'calibration': {'_mean_electrons_cal_kernel', '_crosstalk_kernel'},
    'shot_noise': {'_shot_noise_kernel', '_shot_read_noise_kernel'},
    'read_noise': {'_read_noise_kernel', '_shot_read_noise_kernel'},
    'exposure': {'_saturate_kernel', '_saturate_quantize_kernel'},
    'quantization': {'_quantize_kernel', '_saturate_quantize_kernel'},
}
ALL_KERNELS = set().union(*EFFECT_KERNELS.values())


def test_kernel_table_matches_the_code():
    from polarization_compass import sensor_kernels

    assert set(sensor_kernels._IMPLEMENTS) == ALL_KERNELS
    for effect, kernels in EFFECT_KERNELS.items():
        assert {
            k for k, effects in sensor_kernels._IMPLEMENTS.items() if effect in effects
        } == kernels, effect
    # the effect-free variants do not even take the effect's parameter
    import inspect

    params = {
        k: set(inspect.signature(getattr(sensor_kernels, k).py_func).parameters)
        for k in ALL_KERNELS
    }
    assert (
        'd' not in params['_mean_electrons_kernel'] and 'd' in params['_mean_electrons_er_kernel']
    )
    assert (
        'read_sigma' not in params['_shot_noise_kernel']
        and 'gauss_above' not in params['_read_noise_kernel']
    )
    assert (
        'full_well' not in params['_quantize_kernel']
        and 'full_well' in params['_saturate_quantize_kernel']
    )


@pytest.fixture
def kernels(monkeypatch):
    """
    Record every sensor kernel that runs; forbidden kernels raise.

    Records every sensor kernel that runs; kernels named in ``kernels.forbid(...)`` raise instead.
    """
    from polarization_compass import sensor

    class Spy:
        calls: list = []
        forbidden: set = set()

        def forbid(self, names):
            self.forbidden = set(names)

    spy = Spy()
    spy.calls = []
    for name in ALL_KERNELS:
        real = getattr(sensor, name)

        def wrapper(*args, _name=name, _real=real):
            if _name in spy.forbidden:
                raise AssertionError(f'kernel {_name} of an undeclared effect ran')
            spy.calls.append(_name)
            return _real(*args)

        monkeypatch.setattr(sensor, name, wrapper)
    return spy


def _patch():
    """
    Return the ideal AoP/DoP of a rendered sky block and an S0 above full well.

    Ideal AoP/DoP of a rendered sky block (no sensor) and an S0 that reaches 1.6 (above full well).
    """
    f = render({})
    s0 = np.linspace(0.3, 1.6, f.aop_rad.size).reshape(f.aop_rad.shape).astype(np.float32)
    return f.aop_rad, f.dop, s0


# declared config -> the kernels that must run, in order; the effect-free config of the same effect
EFFECT_CASES = {
    'extinction_ratio': (
        {'extinction_ratio': {'value': 50}},
        ['_mean_electrons_er_kernel'],
        {'mosaic': {}},
    ),
    'exposure': ({'exposure': {}}, ['_mean_electrons_kernel', '_saturate_kernel'], {'mosaic': {}}),
    'quantization': (
        {'quantization': {'bits': 12}},
        ['_mean_electrons_kernel', '_quantize_kernel'],
        {'mosaic': {}},
    ),
    'shot_noise': (
        {'shot_noise': {}},
        ['_mean_electrons_kernel', '_shot_noise_kernel'],
        {'read_noise': {'sigma_e': 30.0}},
    ),
    'read_noise': (
        {'read_noise': {'sigma_e': 30.0}},
        ['_mean_electrons_kernel', '_read_noise_kernel'],
        {'shot_noise': {}},
    ),
}


def _expected(sensor, aop, dop, s0, key):
    """
    Compute the mosaic for EFFECT_CASES independently in float64.

    Independent float64 computation of the mosaic for the configurations of EFFECT_CASES: Malus's
    law (vectors, malus_electrons), then N(0, 1) draws of the reference stream scaled by the
    declared noise's sigma, then the full-well clip, then 12-bit DN. Returns (expected, mask of
    pixels it is exact for).
    """
    layout = [[90, 45], [135, 0]]
    er = (sensor.get('extinction_ratio') or {}).get('value')
    d = 1.0 if er is None else (er - 1) / (er + 1)
    lam = malus_electrons(aop, dop, 5250.0, layout, IMX250MZR_POL45, d=d, s0=s0)
    var = np.zeros_like(lam)
    if 'shot_noise' in sensor:
        var = var + lam
    if 'read_noise' in sensor:
        var = var + sensor['read_noise']['sigma_e'] ** 2
    z = standard_normal_f32(key, lam.shape).astype(float)
    e = lam + np.sqrt(var) * z
    exact = lam >= 20.0 if 'shot_noise' in sensor else np.ones(lam.shape, bool)  # Gaussian regime
    if 'exposure' in sensor:
        e = np.minimum(e, 10500.0)
    if 'quantization' in sensor:
        e = np.clip(np.floor(e * 4095 / 10500 + 0.5), 0, 4095)
    return e, exact


@pytest.mark.parametrize('effect', sorted(EFFECT_CASES))
def test_each_effect_runs_its_kernel_only_when_declared(effect, kernels):
    """
    Each effect runs its kernel only when declared.

    Declared: its stage is counted, its kernel runs, the mosaic is the independent computation with
    the effect. Not declared: none of its kernels runs (they raise), nothing is counted, and the
    mosaic is the independent computation without it (ideal Malus intensities, or the other noise
    alone).
    """
    aop, dop, s0 = _patch()
    declared, expect_kernels, undeclared = EFFECT_CASES[effect]
    for sensor_cfg, has_effect in ((declared, True), (undeclared, False)):
        cfg = parse_sensor_config(sensor_cfg)
        kernels.calls.clear()
        kernels.forbid(() if has_effect else EFFECT_KERNELS[effect])
        instr.reset()
        m = simulate_mosaic(aop, dop, s0, cfg, cfg.layout, np.random.default_rng(9))
        c = instr.counts()
        assert (c.get('sensor.' + effect) == 1) is has_effect, (effect, sensor_cfg, c)
        assert (
            not EFFECT_KERNELS[effect] & set(kernels.calls)
            if not has_effect
            else kernels.calls == expect_kernels
        )
        assert {k[len('sensor.kernel.') :] for k in c if k.startswith('sensor.kernel.')} == set(
            kernels.calls
        )
        key = int(np.random.default_rng(9).integers(0, 2**63, dtype=np.int64))
        ref, exact = _expected(sensor_cfg, aop, dop, s0, key)
        if 'quantization' in sensor_cfg:
            assert m.dtype == np.uint16
            diff = m.astype(float) - ref
            assert (
                np.abs(diff).max() <= 1 and np.mean(diff != 0) < 1e-3
            )  # .5 ties in float32: rarely 1 DN
        else:
            assert m.dtype == np.float32
            # float32 electrons against float64: 1e-6 relative; the effect at stake is >= 3 e-
            # (noise terms with sigma 30 vs sqrt(lambda) differ by ~6 z e-; the full-well clip by
            # up to 6300 e-)
            np.testing.assert_allclose(m[exact], ref[exact], rtol=2e-6, atol=2e-2)
    # the effect makes a difference here (otherwise the comparison above proves nothing)
    a_ref, _ = _expected(declared, aop, dop, s0, key)
    b_ref, _ = _expected(undeclared, aop, dop, s0, key)
    assert np.abs(a_ref - b_ref).max() > 3


def test_without_exposure_the_well_is_unlimited():
    """S0 = 2.5, unpolarized: 2.5 x 5250 = 13 125 e- mean, above the 10 500 e- well."""
    s0 = np.full((256, 256), 2.5, np.float32)
    m, cfg = uniform_mosaic({'shot_noise': {}}, s0=s0, dop=0.0, shape=s0.shape)
    assert abs(m.mean() - 13125) < 1 and m.min() > 10500  # nothing clips (sd 115 e-)
    assert cfg.saturation_level is None and not cfg.saturates
    m, cfg = uniform_mosaic({'shot_noise': {}, 'exposure': {}}, s0=s0, dop=0.0, shape=s0.shape)
    assert np.all(m == 10500) and cfg.saturation_level == 10500
    assert parse_sensor_config({'quantization': {'bits': 8}}).saturation_level == 255


def test_renderer_counts_exactly_the_declared_stages(kernels):
    instr.reset()
    f = render({'mosaic': {}})
    c = instr.counts()
    assert c == {
        'geometry': 1,
        'sky.rayleigh': 1,
        'sensor': 1,
        'sensor.mosaic': 1,
        'sensor.kernel._mean_electrons_kernel': 1,
        'sensor.demosaic.bilinear': 1,
    }, c
    assert kernels.calls == ['_mean_electrons_kernel']
    # without noise the mosaic does not depend on the seed
    np.testing.assert_array_equal(f.mosaic, render({'mosaic': {}}, seed=99).mosaic)
    instr.reset()
    kernels.calls.clear()
    render(
        {
            'exposure': {},
            'shot_noise': {},
            'read_noise': {},
            'quantization': {},
            'extinction_ratio': {},
            'demosaic': 'superpixel',
        }
    )
    c = instr.counts()
    for name in (
        'mosaic',
        'exposure',
        'shot_noise',
        'read_noise',
        'quantization',
        'extinction_ratio',
        'demosaic.superpixel',
    ):
        assert c.get('sensor.' + name) == 1, name
    assert kernels.calls == [
        '_mean_electrons_er_kernel',
        '_shot_read_noise_kernel',
        '_saturate_quantize_kernel',
    ]


@pytest.mark.parametrize(
    'bad,match',
    [
        ({'blur': {}}, 'unknown sensor effect'),
        ({'read_noise': {'sigma': 2}}, 'unknown key'),
        ({'read_noise': {'sigma_e': -1}}, 'sigma_e'),
        ({'read_noise': 2.3}, 'mapping'),
        ({'exposure': {'fill': 0}}, 'fill'),
        ({'exposure': {'full_well_e': float('nan')}}, 'full_well_e'),
        ({'quantization': {'bits': 11}}, 'bits'),
        ({'quantization': {'bits': True}}, 'bits'),
        ({'quantization': {'bits': 12.0}}, 'bits'),
        ({'extinction_ratio': {'value': 1}}, 'extinction_ratio'),
        ({'extinction_ratio': {'value': 'high'}}, 'number'),
        ({'shot_noise': {'gaussian_above_e': 1000}}, 'gaussian_above_e'),
        ({'mosaic': {'layout': [[0, 0], [90, 135]]}}, 'once each'),
        ({'mosaic': {'pol45_toward': 'up'}}, 'pol45_toward'),
        ({'demosaic': 'nearest'}, 'demosaic'),
    ],
)
def test_bad_configs_name_the_problem(bad, match):
    with pytest.raises(SensorError, match=match):
        SensorPipeline.from_config(bad, CameraModel())
    with pytest.raises(SceneError, match='sensor'):
        scene_from_dict({'sensor': bad})


def test_null_effect_parameters_mean_defaults():
    cfg = parse_sensor_config({'shot_noise': None, 'read_noise': {}, 'demosaic': None})
    assert (
        cfg.shot_gaussian_above_e == 20.0
        and cfg.read_sigma_e == 2.3
        and cfg.demosaic == 'bilinear'
    )
    assert cfg.extinction_ratio is None and cfg.bits is None and cfg.d == 1.0


def test_shipped_noisy_scene_loads_and_renders():
    scene = load_scene(REPO / 'config/scenes/imx250mzr_noisy.yaml')
    assert set(scene.effects) >= {
        'mosaic',
        'shot_noise',
        'read_noise',
        'quantization',
        'extinction_ratio',
    }
    f = Renderer(scene.replace(pixels=REGION)).render(attitude=ATT, sun=SUN)
    assert f.mosaic.dtype == np.uint16 and f.mosaic.max() < 4095
    assert f.aop_rad.shape == (128, 160) and f.valid.mean() > 0.99
    v = f.valid & (f.dop_ideal > 0.3)
    # per superpixel: sigma_AoP = sqrt(2 (N + 2.3^2)) / (4 N d P), N = 4725 e-, d = 99/101 (12-bit
    # steps of 2.6 e- add 0.55 e-^2: negligible). The normalised errors must have unit variance.
    n = 4725.0
    sigma = math.sqrt(2 * (n + 2.3**2)) / (4 * n * (99 / 101) * f.dop_ideal[v].astype(float))
    z = fold_axial_rad(f.aop_rad[v].astype(float) - f.aop_ideal_rad[v]) / sigma
    assert v.sum() > 10000 and abs(np.mean(z**2) - 1) < 0.06
    for x in (f.aop_rad, f.dop, f.aop_ideal_rad, f.dop_ideal):
        assert np.all(np.isfinite(x))
