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
The camera estimators use CAMERA.yaml's ``mount:`` (issue 28).

A frame is rendered with the camera's attitude = the body's composed with a known mount, the
composition and its eq 21 angles computed with scipy's Rotation (not the package's rotations).
Estimated through ``estimate`` with the body's ``--pitch/--roll``, the method that levels with the
tilt (tilt_aware) is right with the mount in CAMERA.yaml and measurably wrong without it (the
camera's least_squares does not level and is unchanged); the IMU path of the node and replay
(:meth:`AttitudeBuffer.camera_tilt`) gives the camera's attitude.
"""

import json
import math
import os

import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.cli import main
from polarization_compass.conventions import CameraAttitude, wrap_180_deg
from polarization_compass.demosaic import stokes_from_mosaic
from polarization_compass.mount import camera_tilt_deg, Mount
from polarization_compass.pipeline.attitude import AttitudeBuffer
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene
import pytest
from scipy.spatial.transform import Rotation

N = 160
F_PX = (N / 2) / (math.pi / 2)
CAM = CameraModel(
    model='fisheye_equidistant',
    width_px=N,
    height_px=N,
    focal_length_mm=F_PX * 3.45e-3,
    principal_x_px=N / 2 + 0.5,
    principal_y_px=N / 2 + 0.5,
    max_field_angle_deg=80.0,
)
SUN_AZ, SUN_ALT = 135.0, 62.0
BODY = (200.0, 2.0, -1.5)  # bearing of the body's front, pitch, roll [deg]
MOUNT = (-4.0, -2.5)  # the camera's pitch and roll on the body [deg]
T_IMU_NS = 1_573_797_600_000_000_000  # 2019-11-15T06:00:00Z, the nodes' default start


def _R_enu_cam_scipy(bearing, pitch, roll, mount=(0.0, 0.0)):
    """Return ``Rz(-bearing) Rx(pitch) Ry(roll) Rx(mount pitch) Ry(mount roll)`` (eq 21, mount)."""
    body = Rotation.from_euler('ZXY', [-bearing, pitch, roll], degrees=True)
    return body * Rotation.from_euler('XY', list(mount), degrees=True)


def _attitude_scipy(rot) -> CameraAttitude:
    """Eq 21 angles of a camera-to-ENU rotation: intrinsic Z-X-Y = (-bearing, pitch, roll)."""
    z, x, y = rot.as_euler('ZXY', degrees=True)
    return CameraAttitude(float(-z % 360.0), float(x), float(y))


def test_scipy_composition_is_eq_21():
    # the reference itself: level body, the mount alone is eq 21 with the mount's pitch and roll
    from polarization_compass.conventions import R_enu_cam_from_attitude

    R = _R_enu_cam_scipy(30.0, 0.0, 0.0, MOUNT).as_matrix()
    np.testing.assert_allclose(R, R_enu_cam_from_attitude(30.0, *MOUNT), atol=1e-12)


def _yaml(mount) -> str:
    K = CAM.K_matrix()
    text = (
        f'image_width: {N}\nimage_height: {N}\n'
        f'camera_matrix: {{rows: 3, cols: 3, data: {K.reshape(-1).tolist()}}}\n'
        'distortion_model: equidistant\n'
        'distortion_coefficients: {rows: 1, cols: 4, data: [0, 0, 0, 0]}\n'
        f'max_field_angle_deg: {CAM.max_field_angle_deg}\n'
        "polarizer: {layout: [[90, 45], [135, 0]], pol45_toward: '+x-y'}\n"
    )
    if mount is not None:
        text += f'mount: {{pitch_deg: {mount[0]}, roll_deg: {mount[1]}}}\n'
    return text


@pytest.fixture(scope='module')
def frame(tmp_path_factory):
    d = tmp_path_factory.mktemp('mcam')
    cam_att = _attitude_scipy(_R_enu_cam_scipy(*BODY, MOUNT))
    scene = Scene(
        camera=CAM,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor={
            'mosaic': {},
            'exposure': {'full_well_e': 10500, 'fill': 0.45},
            'shot_noise': {},
            'quantization': {'bits': 12},
            'demosaic': 'superpixel',
        },
    )
    f = Renderer(scene).render(attitude=cam_att, sun=SunDirection(SUN_AZ, SUN_ALT), seed=3)
    m = f.mosaic.astype(np.uint16)
    s0, s1, s2 = stokes_from_mosaic(m, [[90, 45], [135, 0]], '+x-y', 'superpixel', 4095)
    np.savez(d / 'stokes.npz', s0=s0, s1=s1, s2=-s2)  # the SDK's S2 = I(45) - I(135)
    (d / 'mounted.yaml').write_text(_yaml(MOUNT))
    (d / 'level.yaml').write_text(_yaml(None))
    return d, cam_att


def _errors(capsys, d, cam_yaml, want_bearing):
    errs = {}
    for method in ('least_squares', 'tilt_aware'):
        capsys.readouterr()
        argv = ['estimate', str(d / 'stokes.npz'), '--camera', str(d / cam_yaml)]
        argv += ['--sun-azimuth', str(SUN_AZ), '--sun-altitude', str(SUN_ALT)]
        argv += ['--pitch', str(BODY[1]), '--roll', str(BODY[2]), '--method', method]
        assert main(argv) == 0
        (row,) = json.loads(capsys.readouterr().out)
        assert row['status'] == 'ok', (method, row['reason'])
        errs[method] = abs(float(wrap_180_deg(row['bearing_deg'] - want_bearing)))
    return errs


def test_estimate_composes_the_camera_yaml_mount_with_the_body_tilt(frame, capsys):
    d, cam_att = frame
    mounted = _errors(capsys, d, 'mounted.yaml', cam_att.bearing_deg)
    level = _errors(capsys, d, 'level.yaml', cam_att.bearing_deg)
    assert max(mounted.values()) < 0.5, (mounted, level)
    # tilt_aware levels with the tilt given: without the mount it is the body's, 4.5 deg off the
    # camera's (measured: 0.004 deg with the mount, 5.7 without)
    assert level['tilt_aware'] > 3 * mounted['tilt_aware'] + 1.0, (mounted, level)
    # least_squares fits the sky without levelling: the mount does not change its heading
    assert level['least_squares'] == pytest.approx(mounted['least_squares'], abs=1e-9)


def test_camera_tilt_deg_is_the_scipy_composition():
    want = _attitude_scipy(_R_enu_cam_scipy(0.0, BODY[1], BODY[2], MOUNT))
    got = camera_tilt_deg(BODY[1], BODY[2], Mount(*MOUNT))
    np.testing.assert_allclose(got, (want.pitch_deg, want.roll_deg), atol=1e-9)
    assert camera_tilt_deg(None, None, Mount(*MOUNT)) == (None, None)
    assert camera_tilt_deg(1.0, 2.0, None) == (1.0, 2.0)


def test_imu_buffer_gives_the_mounted_camera_attitude():
    # the node's and replay's path: an IMU quaternion of the body, the camera's tilt out
    from polarization_compass.conventions import R_BODY_CAM_DEFAULT

    R_enu_body = _R_enu_cam_scipy(*BODY).as_matrix() @ R_BODY_CAM_DEFAULT.T
    q = Rotation.from_matrix(R_enu_body).as_quat()  # x, y, z, w
    want = _attitude_scipy(_R_enu_cam_scipy(*BODY, MOUNT))
    buf = AttitudeBuffer(mount=Mount(*MOUNT))
    buf.add(1_000, q)
    got = buf.camera_tilt(1_000, 10)
    assert float(wrap_180_deg(got.bearing_deg - want.bearing_deg)) == pytest.approx(0, abs=1e-9)
    np.testing.assert_allclose((got.pitch_deg, got.roll_deg), (want.pitch_deg, want.roll_deg))
    plain = AttitudeBuffer()
    plain.add(1_000, q)
    got = plain.camera_tilt(1_000, 10)
    np.testing.assert_allclose((got.pitch_deg, got.roll_deg), BODY[1:], atol=1e-9)


@pytest.mark.parametrize('mount', [MOUNT, (0.0, 0.0)])
def test_tilt_corrector_reads_the_error_map_at_the_mounted_camera_tilt(ctx, mount):
    # the node's mount parameters reach the tilt it corrects with: its status reports the pitch
    # and roll it looked the map up at, against the scipy composition of the body and the mount
    from polarization_compass.conventions import R_BODY_CAM_DEFAULT
    from polarization_compass.nodes import msgs
    from polarization_compass.nodes.tilt_corrector import TiltCorrectorNode
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Imu

    R_enu_body = _R_enu_cam_scipy(*BODY).as_matrix() @ R_BODY_CAM_DEFAULT.T
    imu = Imu()
    imu.header.stamp = msgs.time_msg(T_IMU_NS)
    imu.header.frame_id = 'base_link'
    q = Rotation.from_matrix(R_enu_body).as_quat()  # x, y, z, w
    imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w = map(float, q)
    imu.orientation_covariance = [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1.0]
    over = [
        Parameter('imu_max_wait_s', value=0.0),
        Parameter('mount_pitch_deg', value=mount[0]),
        Parameter('mount_roll_deg', value=mount[1]),
    ]
    node = TiltCorrectorNode(context=ctx, parameter_overrides=over)
    statuses = []
    node._status = statuses.append  # the status dicts, without DDS
    try:
        node._on_imu(imu)
        node._on_heading(
            msgs.heading_imu(T_IMU_NS, 'base_link', math.radians(90.0 - BODY[0]), 1e-4, 1e3)
        )
        node._drain()
    finally:
        node.destroy_node()
    want = _attitude_scipy(_R_enu_cam_scipy(*BODY, mount))
    st = statuses[-1]
    assert st['status'] == 'ok', st
    np.testing.assert_allclose((st['pitch_deg'], st['roll_deg']), (want.pitch_deg, want.roll_deg))


# ------------------------------------------------------------------------------------------------
# calibrate-mount --camera: simulated turns in place through the estimate road
# ------------------------------------------------------------------------------------------------
LAT, LON, TIME = 40.0, 0.0, '2026-06-21T10:00:00Z'
TURN_OFFSETS = (30.0, 34.0)  # IMU zero of each turn: bearing = offset - degrees(imu yaw)
PER_TURN = 24


def render_turns(d, camera=CAM, mount=MOUNT, time=TIME, per_turn=PER_TURN) -> float:
    """
    Render two turns in place of a mounted camera into ``d``: the frames and ``turns.csv``.

    Returns the sun's altitude [deg] at ``time`` (at LAT, LON).
    """
    from polarization_compass.cli.cmd_estimate_array import sun_per_sample

    az, alt = sun_per_sample(time, None, 1, LAT, LON)
    scene = Scene(
        camera=camera,
        pixels=PixelSelection.full(),
        sky={'model': 'rayleigh', 'dop_max': 0.7},
        sensor={
            'mosaic': {},
            'exposure': {'full_well_e': 10500, 'fill': 0.45},
            'shot_noise': {},
            'quantization': {'bits': 12},
            'demosaic': 'superpixel',
        },
    )
    r = Renderer(scene)
    rows = ['path,imu_yaw_rad,turn_index']
    for k, off in enumerate(TURN_OFFSETS):
        yaw = np.radians(np.linspace(0.0, 360.0, per_turn, endpoint=False) + 3.0 * k)
        for j, y in enumerate(yaw):
            att = _attitude_scipy(_R_enu_cam_scipy(off - math.degrees(y), 0.0, 0.0, mount))
            f = r.render(attitude=att, sun=SunDirection(az[0], alt[0]), seed=100 * k + j)
            m = f.mosaic.astype(np.uint16)
            s0, s1, s2 = stokes_from_mosaic(m, [[90, 45], [135, 0]], '+x-y', 'superpixel', 4095)
            name = f'f{k}_{j:02d}.npz'
            np.savez(d / name, s0=s0, s1=s1, s2=-s2)
            rows.append(f'{name},{float(y)!r},{k}')
    (d / 'turns.csv').write_text('\n'.join(rows) + '\n')
    return float(alt[0])


@pytest.fixture(scope='module')
def turns(tmp_path_factory):
    """Render two turns in place of the mounted camera; write the frames and a turn list."""
    d = tmp_path_factory.mktemp('mturn')
    alt = render_turns(d)
    (d / 'camera.yaml').write_text(_yaml(None))
    return d, alt


def test_calibrate_mount_camera_recovers_the_mount_and_removes_the_curve(turns, capsys):
    import yaml

    d, alt = turns
    assert alt > 50.0  # a sun high enough for the tilt to show
    capsys.readouterr()
    argv = ['calibrate-mount', str(d / 'turns.csv'), '--camera', str(d / 'camera.yaml')]
    argv += ['--lat', str(LAT), '--lon', str(LON), '--time', TIME, '--out', str(d / 'out.yaml')]
    assert main(argv) == 0
    err = capsys.readouterr().err
    m = yaml.safe_load((d / 'out.yaml').read_text())['mount']
    for key, want in (('pitch', MOUNT[0]), ('roll', MOUNT[1])):
        sigma = m[f'{key}_sigma_deg']
        assert 0.0 < sigma < 0.5, (m, err)
        assert abs(m[f'{key}_deg'] - want) < 3.0 * sigma + 0.05, (m, err)
    # the within-turn scatter of tilt_aware's bearing + IMU yaw: the sun-relative curve of a level
    # camera file, gone with the kept one (estimate reads the written mount)
    assert m['residual_before_deg'] > 1.0, (m, err)
    assert m['residual_after_deg'] < m['residual_before_deg'] / 3.0, (m, err)
    from polarization_compass.camera_file import load_camera_yaml

    assert load_camera_yaml(d / 'out.yaml').mount.pitch_deg == m['pitch_deg']


def test_calibrate_mount_camera_refuses_a_list_without_imu_yaw(tmp_path, capsys):
    (tmp_path / 'camera.yaml').write_text(_yaml(None))
    (tmp_path / 'turns.csv').write_text('path,turn_index\nf.npz,0\n')
    argv = ['calibrate-mount', str(tmp_path / 'turns.csv'), '--camera']
    argv += [str(tmp_path / 'camera.yaml'), '--lat', '40', '--lon', '0', '--time', TIME]
    assert main(argv + ['--out', str(tmp_path / 'o.yaml')]) != 0
    assert 'needs a header with path and imu_yaw_rad' in capsys.readouterr().err
    os.mkfifo(tmp_path / 'fifo.csv')  # a special file is refused before it is opened
    argv[1] = str(tmp_path / 'fifo.csv')
    assert main(argv + ['--out', str(tmp_path / 'o.yaml')]) == 2
    assert 'FIFO' in capsys.readouterr().err
