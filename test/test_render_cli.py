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
`polarization-compass render` on success: the .npz contract of issue 2.

It is checked against computations written here from the physics notes (eq 20 rays, eq 21 attitude,
eq 18 E = S x P, eq 28 AoP), not against the renderer's own output.

Contract: ``aop_rad`` (eq 28, folded to [-pi/2, pi/2)), ``dop``, ``valid`` (bool),
``x_px``/``y_px`` (1-based pixel coordinates of eq 20, same shape as ``aop_rad``), ``meta`` (a JSON
string with the sun's azimuth/altitude, the attitude and the effects used).
``--sun-altitude/--sun-azimuth`` fix the sun; ``--yaw`` is the camera's true bearing, so with
``--sun-azimuth 0`` it is the paper's psi.
"""

import json
import math
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from test_cli_bad_input import run as run_in_process  # (exit status, stdout, stderr) in-process

W, H = 2448, 2048  # Table 1 imager
F_MM, PITCH_MM = 4.0, 3.45e-3


def cli_command():
    exe = Path(sys.executable).with_name('polarization-compass')
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'polarization_compass.cli']


def load(path):
    """Load the npz as the contract describes it, with numpy alone (no project code)."""
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    assert {'aop_rad', 'dop', 'valid', 'x_px', 'y_px', 'meta'} <= set(data)
    assert data['meta'].dtype.kind == 'U' and data['meta'].shape == ()
    data['meta'] = json.loads(str(data['meta']))
    shape = data['aop_rad'].shape
    for k in ('dop', 'valid', 'x_px', 'y_px'):
        assert data[k].shape == shape, k
    assert data['valid'].dtype == np.bool_
    a = data['aop_rad']
    assert np.all(np.isfinite(a)) and np.all(a >= -np.pi / 2) and np.all(a < np.pi / 2)
    d = data['dop'][data['valid']]
    assert d.size and d.min() >= 0 and d.max() <= 1
    return data


# ------------------------------------------------------------------------------------------------
# Independent reference (physics notes section 1)
# ------------------------------------------------------------------------------------------------
def _rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _rx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _ry(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def enu(az_deg, alt_deg):
    """
    Return the ENU unit vector of altitude h and azimuth A.

    Altitude h, azimuth A clockwise from North: (cos h sin A, cos h cos A, sin h) in East-North-Up.
    """
    a, h = math.radians(az_deg), math.radians(alt_deg)
    return np.array([math.cos(h) * math.sin(a), math.cos(h) * math.cos(a), math.sin(h)])


def rayleigh_reference(x_px, y_px, sun_az, sun_alt, bearing, pitch, roll):
    """
    Return AoP (eq 28), DoP (dop_max 1), |S x P| and the view altitude per pixel.

    Eq 21: camera-to-world C = Rz(-psi) Rx(alpha) Ry(beta) in the sun-azimuth frame; in the world
    frame the camera +y bearing is A_sun + psi, i.e. C_world = Rz(-bearing) Rx(pitch) Ry(roll). Eq
    20: the ray of 1-based pixel (x, y) is (Dx (x - (W + 1) / 2), Dy (y - (H + 1) / 2), f). Eq 18:
    E = S x P.
    """
    C = _rz(-math.radians(bearing)) @ _rx(math.radians(pitch)) @ _ry(math.radians(roll))
    v = np.stack(
        [
            PITCH_MM * (np.ravel(x_px) - (W + 1) / 2),
            PITCH_MM * (np.ravel(y_px) - (H + 1) / 2),
            np.full(np.size(x_px), F_MM),
        ]
    )
    p = C @ (v / np.linalg.norm(v, axis=0))  # viewing directions, world frame
    s = enu(sun_az, sun_alt)
    e = np.cross(s, p.T)  # (N, 3) world frame
    e_cam = e @ C  # C^T e for each row
    aop = np.arctan2(e_cam[:, 0], e_cam[:, 1])
    aop = (aop + np.pi / 2) % np.pi - np.pi / 2  # fold to [-pi/2, pi/2)
    cos_g = s @ p
    dop = (1 - cos_g**2) / (1 + cos_g**2)
    shape = np.shape(x_px)
    return (
        aop.reshape(shape),
        dop.reshape(shape),
        np.linalg.norm(e, axis=1).reshape(shape),
        np.degrees(np.arcsin(np.clip(p[2], -1, 1))).reshape(shape),
        np.degrees(np.arccos(np.clip(cos_g, -1, 1))).reshape(shape),
    )


def axial_diff_deg(a, b):
    d = (np.asarray(a, float) - np.asarray(b, float) + np.pi / 2) % np.pi - np.pi / 2
    return np.degrees(np.abs(d))


def check_against_reference(data, sun_az, sun_alt, bearing, pitch, roll):
    aop_ref, dop_ref, sxp, alt, ang_sun = rayleigh_reference(
        data['x_px'], data['y_px'], sun_az, sun_alt, bearing, pitch, roll
    )
    v = data['valid']
    # validity (default scene: 3 deg around the sun, at or above the horizon), away from the edges
    margin = (np.abs(ang_sun - 3.0) > 0.01) & (np.abs(alt) > 0.01)
    np.testing.assert_array_equal(v[margin], ((ang_sun >= 3.0) & (alt >= 0.0))[margin])
    use = v & (sxp > 0.05)
    assert use.sum() > 0.5 * v.size
    # float32 rays and kernel against float64 here: measured < 2e-3 deg
    assert axial_diff_deg(data['aop_rad'][use], aop_ref[use]).max() < 5e-3
    np.testing.assert_allclose(data['dop'][use], dop_ref[use], atol=1e-5)
    assert np.all(data['aop_rad'][~v] == 0) and np.all(data['dop'][~v] == 0)


# ------------------------------------------------------------------------------------------------
# The full-resolution run, as a user runs it (console entry point, subprocess)
# ------------------------------------------------------------------------------------------------
FIXED = [
    '--sun-altitude',
    '40',
    '--sun-azimuth',
    '0',
    '--yaw',
    '30',
    '--pitch',
    '-15',
    '--roll',
    '5',
]


@pytest.fixture(scope='module')
def full_run(tmp_path_factory):
    out = tmp_path_factory.mktemp('render') / 'full.npz'
    r = subprocess.run(
        cli_command() + ['render', *FIXED, '--time', '2021-06-01T12:00:00Z', '--out', str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert 'Traceback' not in r.stderr
    return load(out), json.loads(r.stdout)


def test_full_frame_contract_and_coordinates(full_run):
    data, summary = full_run
    assert data['aop_rad'].shape == (H, W)
    assert data['aop_rad'].dtype == np.float32
    # 1-based eq 20 coordinates: x is the column, y the row
    np.testing.assert_array_equal(
        data['x_px'], np.broadcast_to(np.arange(1, W + 1, dtype=float), (H, W))
    )
    np.testing.assert_array_equal(
        data['y_px'], np.broadcast_to(np.arange(1, H + 1, dtype=float)[:, None], (H, W))
    )
    assert summary['shape'] == [H, W] and summary['out'][0].endswith('full.npz')


def test_full_frame_matches_the_independent_rayleigh_computation(full_run):
    data, _ = full_run
    check_against_reference(data, 0.0, 40.0, 30.0, -15.0, 5.0)
    # a few pixels spelled out (corners, centre, one near the solar meridian)
    for x, y in ((1, 1), (W, H), (1224, 1024), (700, 1900)):
        ref = rayleigh_reference(np.array([x]), np.array([y]), 0.0, 40.0, 30.0, -15.0, 5.0)[0][0]
        assert axial_diff_deg(data['aop_rad'][y - 1, x - 1], ref) < 5e-3, (x, y)


def test_meta_of_a_fixed_sun(full_run):
    data, summary = full_run
    m = data['meta']
    assert (m['sun_azimuth_deg'], m['sun_altitude_deg']) == (0.0, 40.0)
    assert (m['bearing_deg'], m['pitch_deg'], m['roll_deg']) == (30.0, -15.0, 5.0)
    assert m['psi_deg'] == pytest.approx(30.0)  # --sun-azimuth 0: yaw is the paper's psi
    assert m['effects'] == [] and m['sensor'] is None
    # the sun was fixed: no time is claimed, although --time was given
    assert m['sun_fixed'] is True and m['sun_source'] == 'given' and m['time_utc'] is None
    assert summary['time_utc'] is None and summary['sun_source'] == 'given'


# ------------------------------------------------------------------------------------------------
# Strided runs (in process: same code path after argument parsing)
# ------------------------------------------------------------------------------------------------
def render_to(tmp_path, capsys, argv, name='f.npz'):
    rc, out, err = run_in_process(['render', *argv, '--out', str(tmp_path / name)], capsys)
    assert rc == 0, err
    return load(tmp_path / name), json.loads(out)


@pytest.mark.parametrize('n', [7, 16])
def test_stride_shape_and_coordinates(n, tmp_path, capsys, full_run):
    data, summary = render_to(tmp_path, capsys, [*FIXED, '--stride', str(n)])
    rows, cols = -(-H // n), -(-W // n)  # every n-th of H rows and W columns
    assert data['aop_rad'].shape == (rows, cols) and summary['shape'] == [rows, cols]
    x, y = data['x_px'], data['y_px']
    assert np.all(x == x[0]) and np.all(y == y[:, :1])  # a grid
    for axis, size in ((x[0], W), (y[:, 0], H)):
        assert np.all(axis == np.round(axis)) and np.all(np.diff(axis) == n)
        assert axis[0] >= 1 and axis[-1] <= size
        assert abs((axis[0] - 1) - (size - axis[-1])) <= 1  # centred on the image
    # the strided pixels are exactly those pixels of the full frame
    full = full_run[0]
    iy, ix = np.ix_(y[:, 0].astype(int) - 1, x[0].astype(int) - 1)
    # (SIMD remainder loops may round differently: 1 float32 ulp at a few pixels for odd strides)
    np.testing.assert_allclose(data['aop_rad'], full['aop_rad'][iy, ix], rtol=0, atol=2e-7)
    np.testing.assert_array_equal(data['valid'], full['valid'][iy, ix])


@pytest.mark.parametrize('sun_az,yaw', [(0.0, -120.0), (0.0, 75.0), (70.0, 75.0), (250.0, 10.0)])
def test_yaw_is_the_true_bearing(sun_az, yaw, tmp_path, capsys):
    """With --sun-azimuth A the camera +y axis points at bearing --yaw, i.e. psi = yaw - A."""
    data, summary = render_to(
        tmp_path,
        capsys,
        [
            '--sun-altitude',
            '25',
            '--sun-azimuth',
            str(sun_az),
            '--yaw',
            str(yaw),
            '--pitch',
            '10',
            '--roll',
            '-20',
            '--stride',
            '32',
        ],
    )
    check_against_reference(data, sun_az, 25.0, yaw, 10.0, -20.0)
    psi = (yaw - sun_az + 180.0) % 360.0 - 180.0
    assert summary['psi_deg'] == pytest.approx(psi) and data['meta']['psi_deg'] == pytest.approx(
        psi
    )


def test_sun_from_time_and_place_is_recorded_with_its_time(tmp_path, capsys):
    """
    The sun from time and place is recorded with its time.

    Without a fixed sun, meta holds the time the sun was computed for, and the sun is NREL SPA's
    (pvlib, called here directly) for the default site.
    """
    import pandas as pd
    import pvlib

    data, summary = render_to(
        tmp_path, capsys, ['--time', '2019-11-15T03:30:00Z', '--stride', '64']
    )
    m = data['meta']
    assert (
        m['time_utc'] == '2019-11-15T03:30:00Z'
        and m['sun_source'] == 'ephemeris'
        and m['sun_fixed'] is False
    )
    sp = pvlib.solarposition.spa_python(
        pd.DatetimeIndex(['2019-11-15T03:30:00Z']), 32.026778, 118.853306, altitude=30.0
    )
    assert m['sun_azimuth_deg'] == pytest.approx(float(sp['azimuth'].iloc[0]), abs=1e-3)
    assert m['sun_altitude_deg'] == pytest.approx(float(sp['elevation'].iloc[0]), abs=1e-3)
    check_against_reference(data, m['sun_azimuth_deg'], m['sun_altitude_deg'], 0.0, 0.0, 0.0)


def test_png_files_are_viewable_images(tmp_path):
    import matplotlib.image as mpimg

    r = subprocess.run(
        cli_command()
        + [
            'render',
            *FIXED,
            '--stride',
            '16',
            '--out',
            str(tmp_path / 'f.npz'),
            '--png',
            str(tmp_path / 'png'),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0 and 'Traceback' not in r.stderr, r.stderr
    summary = json.loads(r.stdout)
    names = sorted(Path(p).name for p in summary['out'][1:])
    assert names == ['aop.png', 'dop.png']
    for name in names:
        img = mpimg.imread(tmp_path / 'png' / name)
        assert (
            img.ndim == 3
            and img.shape[0] >= 300
            and img.shape[1] >= 300
            and img.shape[2] in (3, 4)
        )
        rgb = np.round(img[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
        colours = np.unique(rgb, axis=0)
        assert len(colours) > 100, (name, len(colours))  # a colour-mapped field, not a blank
        assert rgb.std(axis=0).max() > 20


# ------------------------------------------------------------------------------------------------
# Scenes with sensor effects and --stride
# ------------------------------------------------------------------------------------------------
SMALL_NOISY = """\
name: small_noisy
camera: {width_px: 64, height_px: 48, pixel_pitch_x_um: 130.0, pixel_pitch_y_um: 130.0}
sun: {azimuth_deg: 0, altitude_deg: 35}
sensor: {shot_noise: {}, read_noise: {}, quantization: {bits: 12}}
"""


def test_stride_with_sensor_effects_is_refused_clearly(tmp_path, capsys):
    scene = tmp_path / 'noisy.yaml'
    scene.write_text(SMALL_NOISY)
    rc, out, err = run_in_process(
        ['render', '--scene', str(scene), '--stride', '2', '--out', str(tmp_path / 'f.npz')],
        capsys,
    )
    assert rc == 2 and out == '' and 'Traceback' not in err
    (line,) = err.strip().splitlines()
    for word in ('--stride 2', 'sensor effects', 'contiguous', 'shot_noise'):
        assert word in line, (word, line)
    assert not (tmp_path / 'f.npz').exists()
    # the help says so
    rc, out, _ = run_in_process(['render', '--help'], capsys)
    assert (
        rc == 0
        and 'sensor' in ' '.join(out.split())
        and 'contiguous pixels' in ' '.join(out.split())
    )
    # without --stride (or with 1) the same scene renders, with its effects in meta
    for extra in ([], ['--stride', '1']):
        data, _ = render_to(tmp_path, capsys, ['--scene', str(scene), *extra])
        assert data['aop_rad'].shape == (48, 64)
        assert data['meta']['effects'] == ['shot_noise', 'read_noise', 'quantization']
        assert data['meta']['sun_source'] == 'scene' and data['meta']['time_utc'] is None
