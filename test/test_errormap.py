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
Error-map sweeps against independent computations.

The references: the closed-form level-assumption heading, the physics notes' published curve, the
paper's three similarities and eq 32's 90-degree shift, plus the engine's bookkeeping (domain,
status codes, resume, workers, corrupt files).
"""

import json
import subprocess
import sys

import numpy as np
from polarization_compass import conventions as cv
from polarization_compass import sweep_cells
from polarization_compass.cli import main as cli_main
from polarization_compass.errormap import (
    ErrorMapError,
    STATUS_CODES,
    STATUS_NOT_COMPUTED,
    tilt_domain_mask,
)
from polarization_compass.errormap_io import load_error_map
from polarization_compass.estimators import estimator_names, registry
from polarization_compass.sweep import run_sweep
from polarization_compass.sweep_spec import parse_range, SweepSpec
import pytest

PAPER_METHODS = registry.paper_methods()  # the class facts, as the sweep reads them
YAW = np.arange(-180.0, 180.1, 15.0)


def level_assumption_error_deg(psi, h, pitch, roll):
    """
    Return the error of a level-assuming compass, computed independently.

    Independent reference: the heading a level-assuming compass reads from the *true* camera-frame
    sun (the solar meridian of the tilted image), minus the truth. Built from eq 21 directly with
    numpy (R^T s), not through the renderer or any estimator.
    """
    psi, h, pitch, roll = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (psi, h, pitch, roll))
    )
    a, b, y, hr = (np.radians(v) for v in (pitch, roll, psi, h))
    # C_c^a = Rz(-psi) Rx(a) Ry(b); the sun in frame a is (0, cos h, sin h); s_cam = C^T s_a
    s_a = np.stack([np.zeros_like(hr), np.cos(hr), np.sin(hr)], -1)
    cz, sz = np.cos(-y), np.sin(-y)
    Rz = np.stack(
        [
            np.stack([cz, -sz, 0 * cz], -1),
            np.stack([sz, cz, 0 * cz], -1),
            np.stack([0 * cz, 0 * cz, 1 + 0 * cz], -1),
        ],
        -2,
    )
    ca, sa = np.cos(a), np.sin(a)
    Rx = np.stack(
        [
            np.stack([1 + 0 * ca, 0 * ca, 0 * ca], -1),
            np.stack([0 * ca, ca, -sa], -1),
            np.stack([0 * ca, sa, ca], -1),
        ],
        -2,
    )
    cb, sb = np.cos(b), np.sin(b)
    Ry = np.stack(
        [
            np.stack([cb, 0 * cb, sb], -1),
            np.stack([0 * cb, 1 + 0 * cb, 0 * cb], -1),
            np.stack([-sb, 0 * cb, cb], -1),
        ],
        -2,
    )
    C = Rz @ Rx @ Ry
    s_cam = np.einsum('...ji,...j->...i', C, s_a)
    est = np.degrees(np.arctan2(-s_cam[..., 0], s_cam[..., 1]))
    return cv.fold_axial_deg(est - psi)


def available(methods):
    have = set(estimator_names())
    missing = [m for m in methods if m not in have]
    assert not missing, f'methods not registered: {missing}'
    return list(methods)


@pytest.fixture(scope='module')
def pitch_map():
    spec = SweepSpec(
        available(PAPER_METHODS), [0.0, 20.0, 50.0], YAW, [-30.0, -20.0, 0.0, 20.0, 30.0], [0.0]
    )
    return run_sweep(spec, workers=1, progress=False)


@pytest.fixture(scope='module')
def roll_map():
    spec = SweepSpec(
        available(PAPER_METHODS), [0.0, 20.0, 50.0], YAW, [0.0], [-30.0, -20.0, 0.0, 20.0, 30.0]
    )
    return run_sweep(spec, workers=1, progress=False)


# --------------------------------------------------------------------------------------------
# Axes and domain
# --------------------------------------------------------------------------------------------
def test_parse_range_is_inclusive_and_checked():
    np.testing.assert_allclose(parse_range('-180:180:5'), np.arange(-180, 181, 5))
    np.testing.assert_allclose(parse_range('0:1:0.1'), np.round(np.arange(11) * 0.1, 9))
    np.testing.assert_allclose(parse_range('7'), [7.0])
    np.testing.assert_allclose(
        parse_range('0:10:3'), [0, 3, 6, 9]
    )  # B not on the grid: stop before
    for bad in ('0:10', 'a:b:c', '0:10:0', '10:0:1', '0:nan:1', '0:1e9:1e-3', ''):
        with pytest.raises(ErrorMapError):
            parse_range(bad, max_count=10000)
    with pytest.raises(ErrorMapError):
        parse_range('-100:0:10', 'sun-altitude', -90, 90)


@pytest.mark.parametrize('support', [1, 2])
def test_tilt_domain_support_contains_every_interpolation_stencil(support):
    """
    The tilt domain's support contains every interpolation stencil.

    Brute force: for random points with |p|+|r| <= 30, every node the interpolation reads (cell
    corners for multilinear, the 4x4 window for cubic, clipped at the axis ends) is in the support
    mask.
    """
    axis = np.arange(-30.0, 30.1, 5.0)
    mask = tilt_domain_mask(axis, axis, 30.0, support)
    rng = np.random.default_rng(3)
    pts = rng.uniform(-30, 30, (4000, 2))
    pts = pts[np.abs(pts).sum(1) <= 30]
    n = axis.size
    for p, r in pts:
        i = min(int((p + 30) // 5), n - 2)
        k = min(int((r + 30) // 5), n - 2)
        if support == 1:
            rows, cols = [i, i + 1], [k, k + 1]
        else:
            rows = range(max(0, min(i - 1, n - 4)), max(0, min(i - 1, n - 4)) + 4)
            cols = range(max(0, min(k - 1, n - 4)), max(0, min(k - 1, n - 4)) + 4)
        assert all(mask[a, b] for a in rows for b in cols), (p, r)
    exact = tilt_domain_mask(axis, axis, 30.0, 0)
    np.testing.assert_array_equal(exact, np.abs(axis)[:, None] + np.abs(axis)[None, :] <= 30)
    assert not mask.all()  # something is skipped


def test_cells_outside_the_domain_are_not_computed_unless_asked():
    axes = {
        'sun_altitude_deg': [30.0],
        'yaw_deg': [0.0, 90.0],
        'pitch_deg': [-30.0, 0.0, 30.0],
        'roll_deg': [-30.0, 0.0, 30.0],
    }
    m = run_sweep(SweepSpec(['least_squares'], support=0, **axes), workers=1, progress=False)
    inside = np.abs(m.pitch_deg)[:, None] + np.abs(m.roll_deg)[None, :] <= 30
    st = m.status[0, 0]
    assert np.all(st[:, ~inside] == STATUS_NOT_COMPUTED) and np.all(m.valid[0, 0][:, inside])
    assert np.all(m.error_deg[0, 0][:, ~inside] == 0.0)
    full = run_sweep(
        SweepSpec(['least_squares'], full_domain=True, **axes), workers=1, progress=False
    )
    assert full.valid.all()
    np.testing.assert_array_equal(full.error_deg[0, 0][:, inside], m.error_deg[0, 0][:, inside])


# --------------------------------------------------------------------------------------------
# Against independent references
# --------------------------------------------------------------------------------------------
def test_least_squares_map_matches_the_notes_published_curve():
    """
    Physics notes section 3 (pitch -20, yaw -180..180 step 30).

    Our eq 21 gives the same magnitudes with
    the opposite sign (README: 'A sign to know about'); the comparison is on -error.
    """
    m = run_sweep(
        SweepSpec(['least_squares'], [20.0, 50.0], np.arange(-180.0, 181, 30), [-20.0], [0.0]),
        workers=1,
        progress=False,
    )
    ref50 = [0, 7.7, 15.4, 22.2, 25.9, 20.9, 0, -20.9, -25.9, -22.2, -15.4, -7.7, 0]
    ref20 = [0, 2.0, 4.5, 7.1, 8.3, 6.0, 0, -6.0, -8.3, -7.1, -4.5, -2.0, 0]
    np.testing.assert_allclose(-m.error_deg[0, 1, :, 0, 0], ref50, atol=0.06)
    np.testing.assert_allclose(-m.error_deg[0, 0, :, 0, 0], ref20, atol=0.06)


def test_least_squares_map_equals_the_closed_form_level_heading():
    rng = np.random.default_rng(11)
    h = np.round(rng.uniform(0, 60, 3), 3)
    p = np.round(np.sort(rng.uniform(-25, 25, 3)), 3)
    r = np.round(np.sort(rng.uniform(-5, 5, 2)), 3)
    yaw = np.round(np.sort(rng.uniform(-180, 180, 7)), 3)
    m = run_sweep(SweepSpec(['least_squares'], np.sort(h), yaw, p, r), workers=1, progress=False)
    H, Y, P, R = np.meshgrid(m.sun_altitude_deg, yaw, p, r, indexing='ij')
    ref = level_assumption_error_deg(Y, H, P, R)
    assert m.valid.all()
    assert np.abs(cv.fold_axial_deg(m.error_deg[0] - ref)).max() < 0.01


def test_tilt_aware_map_is_zero_everywhere():
    m = run_sweep(
        SweepSpec(
            ['tilt_aware'], [10.0, 50.0], np.arange(-180.0, 180, 45), [-20.0, 10.0], [-10.0, 15.0]
        ),
        workers=1,
        progress=False,
    )
    assert m.valid.all() and np.abs(m.error_deg).max() < 1e-3


# --------------------------------------------------------------------------------------------
# The paper's similarities (section 3), for each of its four methods
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('method', PAPER_METHODS)
def test_similarity_1_zero_at_zero_tilt_and_growth_with_tilt(pitch_map, method):
    m = pitch_map
    i = m.method_index(method)
    assert m.valid[i].all()
    e = m.error_deg[i, :, :, :, 0]  # (h, yaw, pitch)
    ip0 = m.axis_index(m.pitch_deg, 0.0, 'pitch')
    assert np.abs(e[:, :, ip0]).max() < 0.05
    for ia in range(m.sun_altitude_deg.size):
        peak = np.abs(e[ia]).max(axis=0)  # per pitch
        for sign in (-1, 1):
            order = [m.axis_index(m.pitch_deg, sign * t, 'pitch') for t in (0.0, 20.0, 30.0)]
            assert np.all(np.diff(peak[order]) > 0), (method, m.sun_altitude_deg[ia], peak[order])


@pytest.mark.parametrize('method', PAPER_METHODS)
def test_similarity_2_small_at_sun_altitude_zero_and_growth_with_altitude(pitch_map, method):
    """
    Similarity 2: small error at sun altitude 0, growing with altitude.

    At h = 0 the paper says 'close to 0': what remains is the tilt's projection of a horizontal sun
    direction, atan2(sin psi, cos psi cos pitch) - psi (closed form, <= 4.1 deg at 30 deg pitch),
    far below the 44 deg at h = 50.
    """
    m = pitch_map
    i = m.method_index(method)
    e = m.error_deg[i, :, :, :, 0]
    psi = m.yaw_deg[:, None]
    horizon = np.degrees(
        np.arctan2(
            np.sin(np.radians(psi)), np.cos(np.radians(psi)) * np.cos(np.radians(m.pitch_deg))
        )
    )
    horizon = cv.fold_axial_deg(horizon - psi)
    assert np.abs(e[0] - horizon).max() < 1.0
    assert np.abs(e[0]).max() < 0.15 * np.abs(e[-1]).max()
    peak = np.abs(e).max(axis=1)  # (h, pitch)
    tilted = np.abs(m.pitch_deg) > 0
    assert np.all(np.diff(peak[:, tilted], axis=0) > 0)


@pytest.mark.parametrize('method', PAPER_METHODS)
def test_similarity_3_symmetry_pitch_only_about_yaw_0_and_180(pitch_map, method):
    m = pitch_map
    i = m.method_index(method)
    e = m.error_deg[i, :, :, :, 0]
    rev = [m.axis_index(m.yaw_deg, -y, 'yaw') for y in m.yaw_deg]  # yaw -> -yaw (axis symmetric)
    assert np.abs(e + e[:, rev]).max() < 0.3  # odd in yaw: mirror image about 0 and 180
    for y in (-180.0, 0.0, 180.0):
        assert np.abs(e[:, m.axis_index(m.yaw_deg, y, 'yaw')]).max() < 0.3


@pytest.mark.parametrize('method', PAPER_METHODS)
def test_similarity_3_symmetry_roll_only_about_yaw_plus_minus_90(roll_map, method):
    m = roll_map
    i = m.method_index(method)
    e = m.error_deg[i, :, :, 0, :]
    idx = {float(y): k for k, y in enumerate(m.yaw_deg)}
    pairs = [
        (idx[90.0 + d], idx[float(cv.wrap_180_deg(90.0 - d))])
        for d in np.arange(0, 181, 15.0)
        if 90.0 + d <= 180
    ]
    for a, b in pairs:
        assert np.abs(e[:, a] + e[:, b]).max() < 0.3
    for y in (-90.0, 90.0):
        assert np.abs(e[:, idx[y]]).max() < 0.3


@pytest.mark.parametrize('method', PAPER_METHODS)
def test_roll_only_is_pitch_only_shifted_by_90_deg_of_yaw(pitch_map, roll_map, method):
    """Eq 32: (psi + 90, roll = a) sees the sky of (psi, pitch = a)."""
    ip, ir = pitch_map.method_index(method), roll_map.method_index(method)
    for t in (-30.0, -20.0, 20.0, 30.0):
        ep = pitch_map.error_deg[
            ip, :, :, pitch_map.axis_index(pitch_map.pitch_deg, t, 'pitch'), 0
        ]
        er = roll_map.error_deg[ir, :, :, 0, roll_map.axis_index(roll_map.roll_deg, t, 'roll')]
        shifted = [
            roll_map.axis_index(roll_map.yaw_deg, float(cv.wrap_180_deg(y + 90.0)), 'yaw')
            for y in pitch_map.yaw_deg
        ]
        assert np.abs(er[:, shifted] - ep).max() < 0.3, (method, t)


def test_the_four_methods_agree_within_one_degree(pitch_map, roll_map):
    """The paper reports < 0.66 deg (pitch only) and < 0.77 deg (pitch and roll)."""
    worst = 0.0
    for m in (pitch_map, roll_map):
        idx = [m.method_index(x) for x in PAPER_METHODS]
        e = m.error_deg[idx]
        worst = max(worst, float((e.max(axis=0) - e.min(axis=0)).max()))
    assert worst < 1.0, worst


def _scene(name):
    from pathlib import Path

    from polarization_compass.camera import CameraModel
    from polarization_compass.scene_load import default_scene, load_scene

    if name == 'ideal':
        return default_scene()
    if name == 'radiance':  # intensity: the brightness gradient resolves the 180 deg ambiguity
        return load_scene(
            Path(__file__).resolve().parents[1] / 'config' / 'scenes' / 'cie_clear_radiance.yaml'
        )
    # a fisheye whose corners lie beyond the lens' field (pixels without a ray)
    return default_scene().replace(
        camera=CameraModel(
            model='fisheye_equidistant',
            width_px=800,
            height_px=600,
            focal_length_mm=1.2,
            max_field_angle_deg=80.0,
        )
    )


@pytest.mark.parametrize('scene_name', ['ideal', 'radiance', 'fisheye'])
def test_sweep_equals_each_method_on_its_own_render_with_its_uncertainty(scene_name):
    """
    The sweep equals each method on its own render, uncertainty aside.

    The sweep renders only the sky arrays (Renderer.render_sky), once per cell and distinct pixel
    selection, and asks the estimators for no uncertainty. The plain path -- Renderer.render of
    each method's own pixel selection, estimate() with its uncertainty, the error folded by
    conventions.fold_axial_deg -- gives the same errors (1e-9 deg) and statuses. The cells include
    the sun inside the view (unusable pixels around it: the mirror-pair path).
    """
    from polarization_compass import instrumentation as instr
    from polarization_compass.estimators import make_estimator

    scene = _scene(scene_name)
    methods = available(registry.names())
    spec = SweepSpec(
        methods,
        [4.0, 35.0, 50.0],
        [-150.0, -60.0, 10.0, 95.0],
        [-25.0, 0.0, 20.0],
        [-5.0, 10.0],
        scene=scene,
    )
    cells = spec.sun_altitude_deg.size * spec.yaw_deg.size * int(spec.tilt_mask().sum())
    selections = {make_estimator(x, **spec.knobs[x]).pixels_needed(scene.camera) for x in methods}
    # zenith's window, the disc at sm_asm's and at symmetry's stride, the whole image (LS and
    # tilt_aware)
    assert len(selections) == 4
    instr.reset()
    m = run_sweep(spec, workers=1, progress=False)
    assert instr.counts().get('sky.' + scene.sky['model'], 0) == cells * len(selections)
    statuses = set()
    # every sweep backend runs numba on one thread (symmetry's parallel reductions move by ~4e-9
    # deg with the thread count), so the plain path does too
    from polarization_compass.runtime import single_threaded_kernels

    with single_threaded_kernels():
        _compare_with_plain_path(m, spec, scene, methods, statuses)
    assert STATUS_CODES['ok'] in statuses
    if scene_name == 'radiance':
        assert (
            m.status[methods.index('zenith')].min() == STATUS_CODES['ok']
        )  # resolved by the brightness


def _compare_with_plain_path(m, spec, scene, methods, statuses):
    from polarization_compass.estimators import make_estimator
    from polarization_compass.estimators.base import Observation
    from polarization_compass.render import Renderer, SunDirection

    for i, method in enumerate(methods):
        est = make_estimator(method, **spec.knobs[method])
        renderer = Renderer(scene, pixels=est.pixels_needed(scene.camera))
        for ia, h in enumerate(spec.sun_altitude_deg):
            for iy, y in enumerate(spec.yaw_deg):
                for ip, p in enumerate(spec.pitch_deg):
                    for ir, r in enumerate(spec.roll_deg):
                        f = renderer.render(
                            attitude=cv.CameraAttitude(y, p, r), sun=SunDirection(0.0, h)
                        )
                        res = est.estimate(
                            Observation.from_frame(f, pitch_deg=p, roll_deg=r, camera=scene.camera)
                        )
                        code = STATUS_CODES[res.status.value]
                        assert m.status[i, ia, iy, ip, ir] == code, (
                            method,
                            h,
                            y,
                            p,
                            r,
                            res.reason,
                        )
                        statuses.add(code)
                        if res.ok:
                            assert res.sigma_deg is not None and res.sigma_deg > 0
                            want = cv.fold_axial_deg(res.psi_deg - y)
                            assert abs(m.error_deg[i, ia, iy, ip, ir] - want) <= 1e-9, (
                                method,
                                h,
                                y,
                                p,
                                r,
                            )


def _noisy_scene():
    from pathlib import Path

    from polarization_compass.camera import CameraModel
    from polarization_compass.scene_load import load_scene

    scene = load_scene(
        Path(__file__).resolve().parents[1] / 'config' / 'scenes' / 'imx250mzr_noisy.yaml'
    )
    return scene.replace(camera=CameraModel(width_px=256, height_px=200, focal_length_mm=0.5))


@pytest.mark.parametrize('method', registry.names())
def test_estimate_without_uncertainty_changes_nothing_but_the_uncertainty(method):
    """
    Estimating without uncertainty changes nothing but the uncertainty.

    sigma=False (what sweeps ask for): sigma_deg None and no residual statistics (except on the
    mirror-pair path, whose acceptance test computes them anyway); status, quality, pixels and the
    axis of psi are those of estimate() with its uncertainty, on noisy frames, occluded ones (the
    mirror-pair path) and with a prior bearing (psi itself the same once the sun's side is
    resolved).
    """
    from polarization_compass.estimators import make_estimator
    from polarization_compass.estimators.base import Observation
    from polarization_compass.render import Renderer, SunDirection

    scene = _noisy_scene()
    # zenith decides its side from the whole sky; without its side grid (every other frame) the
    # axial path runs
    ests = [make_estimator(method)] + (
        [make_estimator(method, side_grid=0)] if method == 'zenith' else []
    )
    renderer = Renderer(scene)
    rng = np.random.default_rng(7)
    kinds = set()
    for k in range(24):
        est = ests[k % len(ests)]
        f = renderer.render(
            attitude=cv.CameraAttitude(
                rng.uniform(-180, 180), rng.uniform(-25, 25), rng.uniform(-10, 10)
            ),
            sun=SunDirection(0.0, rng.uniform(5, 60)),
            seed=k,
        )
        valid = f.valid.copy()
        if k % 3 == 1:
            valid[:, : valid.shape[1] // 2 - 7] = False  # a wall on one side: mirror pairs
        prior = float(rng.uniform(0, 360)) if k % 3 == 2 else None
        tilt = (
            (f.attitude.pitch_deg, f.attitude.roll_deg) if method == 'tilt_aware' else (None, None)
        )
        obs = Observation(
            f.aop_rad,
            f.dop,
            valid,
            f.rays_cam,
            f.x_px,
            f.y_px,
            scene.camera,
            0.0,
            f.sun.altitude_deg,
            f.intensity,
            *tilt,
            prior,
        )
        a, b = est.estimate(obs), est.estimate(obs, sigma=False)
        assert (a.status, a.pixels, a.axial) == (b.status, b.pixels, b.axial), (
            k,
            a.reason,
            b.reason,
        )
        assert b.sigma_deg is None
        assert ('rms_residual_deg' in b.extras) == (
            'mirror_axes' in b.extras
        )  # kept where a test needs it
        if a.ok:
            kinds.add('resolved' if not a.axial else 'axial')
            assert a.sigma_deg > 0 and b.quality == pytest.approx(a.quality, abs=1e-12)
            assert abs(cv.fold_axial_deg(a.psi_deg - b.psi_deg)) < 1e-9
            if not a.axial:
                assert abs(cv.wrap_180_deg(a.psi_deg - b.psi_deg)) < 1e-9
        else:
            kinds.add(a.status.value)
    # tilt_aware knows the tilt, so the levelled sun's elevation always resolves the side here
    assert ({'resolved'} if method == 'tilt_aware' else {'resolved', 'axial'}) <= kinds


def test_render_sky_refuses_a_scene_with_sensor_effects():
    from polarization_compass.render import Renderer
    from polarization_compass.sensor import SensorError

    with pytest.raises(SensorError, match='sensor effects'):
        Renderer(_noisy_scene()).render_sky(cv.enu_direction(0.0, 30.0), np.array([0.0, 0.0, 1.0]))


# --------------------------------------------------------------------------------------------
# Bookkeeping
# --------------------------------------------------------------------------------------------
def test_failed_estimates_are_status_codes_not_nan():
    # the sun 89.5 deg high: least squares reports sun_near_zenith (knob max_sun_altitude_deg = 89)
    m = run_sweep(
        SweepSpec(['least_squares'], [45.0, 89.5], [0.0, 90.0], [0.0], [0.0]),
        workers=1,
        progress=False,
    )
    assert np.all(np.isfinite(m.error_deg))
    assert np.all(m.status[0, 1] == STATUS_CODES['sun_near_zenith'])
    assert not m.valid[0, 1].any() and m.valid[0, 0].all()
    assert np.all(m.error_deg[0, 1] == 0.0)


def _chunk_files(store, ia, ip):
    """
    Return the Zarr chunk files of sweep chunk (ia, ip) and its checksum.

    The Zarr (format 3) chunk files of sweep chunk (ia, ip): error_deg and status, then its
    checksum.
    """
    return [
        store / 'error_deg' / 'c' / '0' / str(ia) / '0' / str(ip) / '0',
        store / 'status' / 'c' / '0' / str(ia) / '0' / str(ip) / '0',
        store / 'chunk_checksum' / 'c' / str(ia) / str(ip),
    ]


def test_resume_after_interruption_gives_the_same_map(tmp_path, monkeypatch, capsys):
    """
    A resumed sweep gives the same map as an uninterrupted one.

    A resumed sweep computes exactly the chunks that are not finished (each once; a chunk whose
    stored bytes do not match its checksum is named and recomputed, never used) and gives the same
    map as an uninterrupted one.
    """
    spec = SweepSpec(
        ['least_squares', 'tilt_aware'],
        [10.0, 40.0],
        np.arange(-180.0, 180, 60),
        [-10.0, 10.0],
        [0.0, 5.0],
    )
    whole = run_sweep(spec, workers=1, progress=False)
    computed = []  # every chunk evaluation, in this process (workers=1)
    real_chunk = sweep_cells.CellEvaluator.chunk

    def counting_chunk(self, ia, ip):
        computed.append((ia, ip))
        return real_chunk(self, ia, ip)

    monkeypatch.setattr(sweep_cells.CellEvaluator, 'chunk', counting_chunk)
    out = tmp_path / 'm.npz'
    assert (
        run_sweep(spec, out=out, workers=1, progress=False, max_chunks=2) is None
    )  # "interrupted"
    store = tmp_path / 'm.npz.partial.zarr'
    finished = list(computed)
    assert len(finished) == 2 and len(set(finished)) == 2
    written = {
        (ia, ip)
        for ia in range(2)
        for ip in range(2)
        if all(f.is_file() for f in _chunk_files(store, ia, ip))
    }
    assert written == set(finished)
    assert not out.exists()
    torn = finished[1]
    f = _chunk_files(store, *torn)[0]
    f.write_bytes(
        f.read_bytes()[:-7] + b'damaged'
    )  # same size, other bytes: only the checksum sees it
    computed.clear()
    capsys.readouterr()
    resumed = run_sweep(spec, out=out, workers=1, progress=False)
    h, p = spec.sun_altitude_deg[torn[0]], spec.pitch_deg[torn[1]]
    assert (
        f'chunk (sun altitude {h:g} deg, pitch {p:g} deg) [{torn[0]}, {torn[1]}] is damaged'
        in capsys.readouterr().err
    )
    everything = set(spec.chunks())
    assert len(everything) == 4
    assert sorted(computed) == sorted(
        (everything - set(finished)) | {torn}
    )  # not the intact finished chunk
    np.testing.assert_array_equal(resumed.error_deg, whole.error_deg)
    np.testing.assert_array_equal(resumed.status, whole.status)
    assert not store.exists()
    loaded = load_error_map(out)
    np.testing.assert_array_equal(loaded.error_deg, whole.error_deg)
    # a store of another sweep is refused, not mixed in
    other = SweepSpec(['least_squares'], [10.0], [0.0], [0.0], [0.0])
    run_sweep(spec, out=tmp_path / 'x.npz', workers=1, progress=False, max_chunks=1)
    with pytest.raises(ErrorMapError, match='different sweep'):
        run_sweep(other, out=tmp_path / 'x.npz', workers=1, progress=False)


def test_resume_on_dask_leaves_finished_chunks_alone(tmp_path):
    """
    Resuming on Dask leaves finished chunks alone.

    With Dask worker processes (no hook reaches them) the store itself shows it: a resumed run
    writes the missing chunks and never rewrites a finished one (a rewrite is a new file: new inode
    or mtime).
    """
    spec = SweepSpec(
        ['least_squares'], [10.0, 40.0], np.arange(-180.0, 180, 90), [-10.0, 0.0, 10.0], [0.0]
    )
    whole = run_sweep(spec, workers=1, progress=False)
    out = store = tmp_path / 'p.zarr'  # kept as the map: the store stays after the end

    def chunk_files():
        return {
            str(f): (f.stat().st_ino, f.stat().st_mtime_ns, f.read_bytes())
            for ia in range(2)
            for ip in range(3)
            for f in _chunk_files(store, ia, ip)
            if f.is_file()
        }

    assert run_sweep(spec, out=out, workers=2, progress=False, max_chunks=2) is None
    first = chunk_files()
    assert len(first) == 2 * 3
    assert (
        run_sweep(spec, out=out, workers=1, progress=False, max_chunks=0) is None
    )  # nothing new: untouched
    assert chunk_files() == first
    resumed = run_sweep(spec, out=out, workers=2, progress=False, stats=(stats := {}))
    assert stats['tasks'] == 4 and resumed.meta['workers'] == 2
    final = chunk_files()
    assert len(final) == 6 * 3 and all(final[k] == first[k] for k in first)
    np.testing.assert_array_equal(resumed.error_deg, whole.error_deg)
    np.testing.assert_array_equal(resumed.status, whole.status)
    loaded = load_error_map(store)  # the Zarr store read back as a map, checksums verified
    np.testing.assert_array_equal(loaded.error_deg, whole.error_deg)
    np.testing.assert_array_equal(loaded.status, whole.status)


def test_dask_local_cluster_gives_the_same_map_as_one_process():
    spec = SweepSpec(
        ['least_squares'], [20.0, 50.0], np.arange(-180.0, 180, 45), [-20.0, 0.0, 20.0], [0.0]
    )
    one = run_sweep(spec, workers=1, progress=False)
    two = run_sweep(spec, workers=2, progress=False)
    np.testing.assert_array_equal(one.error_deg, two.error_deg)
    np.testing.assert_array_equal(one.status, two.status)
    assert two.meta['workers'] == 2


def _small_map():
    return run_sweep(
        SweepSpec(['least_squares'], [30.0], [-90.0, 0.0, 90.0], [0.0, 10.0], [0.0]),
        workers=1,
        progress=False,
    )


def test_map_file_round_trip_and_corrupt_files(tmp_path):
    m = _small_map()
    p = m.save(tmp_path / 'ok.npz')
    back = load_error_map(p)
    np.testing.assert_array_equal(back.error_deg, m.error_deg)
    assert (
        back.methods == ('least_squares',)
        and back.meta['scene']['name'] == m.meta['scene']['name']
    )
    assert json.loads(json.dumps(back.meta))['status_codes']['0'] == 'ok'

    def write(name, **overrides):
        arrays = {
            'error_deg': m.error_deg,
            'status': m.status,
            'methods': np.array(m.methods),
            'sun_altitude_deg': m.sun_altitude_deg,
            'yaw_deg': m.yaw_deg,
            'pitch_deg': m.pitch_deg,
            'roll_deg': m.roll_deg,
            'meta': np.array(json.dumps(m.meta)),
        }
        arrays.update(overrides)
        arrays = {k: v for k, v in arrays.items() if v is not None}
        f = tmp_path / name
        np.savez(f, **arrays)
        return f

    cases = {
        'nan.npz': {'error_deg': np.where(m.valid, np.nan, 0.0)},
        'shape.npz': {'error_deg': m.error_deg[:, :, :2]},
        'axis.npz': {'yaw_deg': m.yaw_deg[::-1].copy()},
        'missing.npz': {'status': None},
        'meta.npz': {'meta': np.array('{not json')},
        'status.npz': {'status': np.full(m.status.shape, 99, dtype=np.int8)},
        'unfolded.npz': {'error_deg': m.error_deg + 200.0},
        'pickle.npz': {'methods': np.array([object()], dtype=object)},
    }
    for name, over in cases.items():
        with pytest.raises(ErrorMapError):
            load_error_map(write(name, **over))
    junk = tmp_path / 'junk.npz'
    junk.write_bytes(b'PK\x03\x04 definitely not a zip')
    with pytest.raises(ErrorMapError):
        load_error_map(junk)
    trunc = tmp_path / 'trunc.npz'
    trunc.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])
    with pytest.raises(ErrorMapError):
        load_error_map(trunc)
    with pytest.raises(ErrorMapError, match='does not exist'):
        load_error_map(tmp_path / 'none.npz')


def test_errormap_cli_writes_the_contract_and_errors_are_one_line(tmp_path, capsys):
    """
    The errormap command writes its contract; bad arguments and files are one line, exit 2.

    The good run goes through the console entry point in a subprocess (stdout is the JSON summary);
    the refusals run in this process (``main``: the same one line and exit status, without
    importing the package anew for each).
    """
    out = tmp_path / 'cli.npz'
    args = [
        'errormap',
        '--methods',
        'least_squares',
        '--sun-altitude',
        '20:40:20',
        '--yaw',
        '-180:180:90',
        '--pitch',
        '-10:10:10',
        '--roll',
        '0',
        '--workers',
        '1',
        '--no-progress',
        '--out',
        str(out),
    ]
    cmd = [sys.executable, '-m', 'polarization_compass.cli'] + args
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary['shape'] == [1, 2, 5, 3, 1]
    m = load_error_map(out)
    assert m.error_deg.shape == (1, 2, 5, 3, 1)
    np.testing.assert_allclose(m.yaw_deg, [-180, -90, 0, 90, 180])
    assert m.meta['sampling']['least_squares']['pixels'].startswith('stride')
    assert m.meta['package_version'] and m.meta['scene']['sky']['model'] == 'rayleigh'

    def refused(argv):
        try:
            rc = cli_main(argv)
        except SystemExit as exc:  # argparse
            rc = exc.code
        err = capsys.readouterr().err
        assert rc == 2, (argv, err)
        assert len(err.strip().splitlines()) == 1 and 'Traceback' not in err, (argv, err)

    capsys.readouterr()
    for bad in (
        ['--yaw', '0:10'],
        ['--methods', 'nope'],
        ['--pitch', '10:-10:5'],
        ['--stride', '0'],
    ):
        argv = list(args)
        if bad[0] in argv:
            argv[argv.index(bad[0]) + 1] = bad[1]
        else:
            argv += bad
        refused(argv)
    junk = tmp_path / 'junk.npz'
    junk.write_text('nonsense')
    refused(['allowable-tilt', '--max-error', '1', '--map', str(junk)])


def test_noisy_scene_sweeps_are_reproducible_and_resumable(tmp_path):
    """
    Noisy scene sweeps are reproducible and resumable.

    Sensor noise: contiguous pixels are read (the renderer refuses strided mosaics), each cell
    draws its own noise from a seed of the cell, so a resumed sweep equals an uninterrupted one.
    """
    from pathlib import Path

    from polarization_compass.camera import CameraModel
    from polarization_compass.scene_load import load_scene

    scene = load_scene(
        Path(__file__).resolve().parents[1] / 'config' / 'scenes' / 'imx250mzr_noisy.yaml'
    )
    scene = scene.replace(camera=CameraModel(width_px=256, height_px=200, focal_length_mm=0.5))
    spec = SweepSpec(
        ['least_squares'], [30.0], [-90.0, 0.0, 90.0], [-10.0, 10.0], [0.0], scene=scene
    )
    assert spec.knobs['least_squares']['stride'] == 1
    whole = run_sweep(spec, workers=1, progress=False)
    assert whole.valid.all()
    out = tmp_path / 'n.npz'
    assert run_sweep(spec, out=out, workers=1, progress=False, max_chunks=1) is None
    resumed = run_sweep(spec, out=out, workers=1, progress=False)
    np.testing.assert_array_equal(resumed.error_deg, whole.error_deg)
    # noise is real: the errors differ from the noise-free closed form, by a small amount
    H, Y, P, R = np.meshgrid(
        whole.sun_altitude_deg, whole.yaw_deg, whole.pitch_deg, whole.roll_deg, indexing='ij'
    )
    d = np.abs(cv.fold_axial_deg(whole.error_deg[0] - level_assumption_error_deg(Y, H, P, R)))
    assert 0 < d.max() < 5.0
