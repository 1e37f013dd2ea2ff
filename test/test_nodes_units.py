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
The nodes' building blocks without DDS.

Message forms, the IMU history, the front end, parameters. Each is checked against an independent
computation (closed form, another module's decoder, a slow reference loop), never against its own
output.
"""

import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
from polarization_compass.bag import decode_camera_info, decode_mosaic, stamp_ns
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import (
    camera_attitude_from_body_quat,
    CameraAttitude,
    R_enu_body_from_camera_attitude,
)
from polarization_compass.motion import frame_times_ns, MotionProfile
from polarization_compass.nodes import msgs
from polarization_compass.pipeline import AttitudeBuffer, HeadingFrontEnd, SunSource
from polarization_compass.specs.params import (
    CORRECTOR,
    ESTIMATOR,
    EVALUATOR,
    knob_params,
    knob_values,
    layout_from_text,
    SIMULATOR,
    validate_value,
)
import pytest

SMALL_CAM = CameraModel(
    'pinhole', 612, 512, 4.0, 13.8, 13.8
)  # the paper's field of view, 1/16 the pixels


def rep103_quat(yaw, pitch=0.0, roll=0.0):
    """Quaternion (x, y, z, w) of REP-103 ZYX Euler angles (rad), written out independently."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )


# ------------------------------------------------------------------------------------------------
# robot_localization's Imu form
# ------------------------------------------------------------------------------------------------
@given(bearing=st.floats(0, 360, exclude_max=True), sigma=st.floats(1e-4, 20))
def test_heading_imu_follows_robot_localization_conventions(bearing, sigma):
    yaw = math.radians(90.0 - bearing)
    m = msgs.heading_imu(
        1_573_797_600_123_456_789, 'base_link', yaw, math.radians(sigma) ** 2, 1000.0
    )
    q = np.array([m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w])
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
    assert q[0] == 0.0 and q[1] == 0.0  # yaw only
    got_yaw = 2 * math.atan2(q[2], q[3])  # pure yaw: q = (0, 0, sin y/2, cos y/2)
    assert math.remainder(got_yaw - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    c = np.asarray(m.orientation_covariance).reshape(3, 3)
    assert c[0, 0] == c[1, 1] == 1000.0 and c[2, 2] == pytest.approx(math.radians(sigma) ** 2)
    assert np.count_nonzero(c - np.diag(np.diag(c))) == 0
    assert m.angular_velocity_covariance[0] == -1.0 and m.linear_acceleration_covariance[0] == -1.0
    assert stamp_ns(m.header) == 1_573_797_600_123_456_789 and m.header.frame_id == 'base_link'
    from polarization_compass.nodes.error_evaluator import bearing_from_imu

    assert math.remainder(bearing_from_imu(m) - bearing, 360.0) == pytest.approx(0.0, abs=1e-9)


def test_heading_imu_refuses_non_finite():
    with pytest.raises(ValueError):
        msgs.heading_imu(0, 'base_link', float('nan'), 1e-4, 1000.0)
    with pytest.raises(ValueError):
        msgs.heading_imu(0, 'base_link', 0.0, 0.0, 1000.0)


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32])
def test_image_round_trip_through_the_replay_decoder(dtype):
    rng = np.random.default_rng(0)
    a = (rng.uniform(0, 200, (6, 8))).astype(dtype)
    m = msgs.image_msg(a, 5, 'cam')
    assert m.encoding == {np.uint8: 'mono8', np.uint16: 'mono16', np.float32: '32FC1'}[dtype]
    assert m.step == 8 * a.itemsize and not m.is_bigendian
    assert np.array_equal(decode_mosaic(m), a)
    # a big-endian producer is decoded right too
    m.data = a.astype(a.dtype.newbyteorder('>')).tobytes()
    m.is_bigendian = 1
    assert np.array_equal(msgs.decode_image(m), a)


@pytest.mark.parametrize('model', ['pinhole', 'fisheye_equidistant'])
def test_camera_info_round_trip(model):
    cam = CameraModel(model, 612, 512, 4.0, 13.8, 13.8, principal_x_px=300.5, principal_y_px=260.0)
    m = msgs.camera_info_msg(cam, 0, 'camera_optical_frame')
    back = decode_camera_info(m, 13.8)
    assert back.model == model
    rays_a, _ = cam.rays_from_pixels(np.array([1.0, 300.5, 612.0]), np.array([1.0, 260.0, 512.0]))
    rays_b, _ = back.rays_from_pixels(np.array([1.0, 300.5, 612.0]), np.array([1.0, 260.0, 512.0]))
    assert np.allclose(rays_a, rays_b, atol=1e-12)


def test_attitude_imu_carries_the_rotation_and_gravity():
    R = R_enu_body_from_camera_attitude(CameraAttitude(30.0, -20.0, 5.0))
    m = msgs.attitude_imu(0, 'base_link', R, (1e-6, 1e-6, 1e-2), [0, 0, 0.1], R.T @ [0, 0, 9.8])
    q = np.array([m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w])
    # rotate body x by q (v' = q v q*) with the textbook formula and compare with R's first column
    u, w = q[:3], q[3]
    v = np.array([1.0, 0.0, 0.0])
    rotated = 2 * np.dot(u, v) * u + (w * w - np.dot(u, u)) * v + 2 * w * np.cross(u, v)
    assert np.allclose(rotated, R[:, 0], atol=1e-12)
    assert m.linear_acceleration.z == pytest.approx((R.T @ [0, 0, 9.8])[2])
    assert m.orientation_covariance[8] == 1e-2


# ------------------------------------------------------------------------------------------------
# IMU history and camera attitude
# ------------------------------------------------------------------------------------------------
@given(yaw=st.floats(-math.pi, math.pi), nose_up=st.floats(-0.6, 0.6))
def test_camera_attitude_from_body(yaw, nose_up):
    # REP-103: positive pitch about +y (left) puts the nose DOWN; the paper's pitch of the camera
    # (looking up, +y forward) is the elevation of body x, so alpha = nose-up angle
    q = rep103_quat(yaw, -nose_up)
    att = camera_attitude_from_body_quat(q)
    assert att.pitch_deg == pytest.approx(math.degrees(nose_up), abs=1e-9)
    assert att.roll_deg == pytest.approx(0.0, abs=1e-9)
    assert math.remainder(att.bearing_deg - (90.0 - math.degrees(yaw)), 360.0) == pytest.approx(
        0.0, abs=1e-8
    )


def test_attitude_buffer_interpolates_within_tolerance_only():
    b = AttitudeBuffer(keep_ns=10_000)
    b.add(1000, rep103_quat(0.0))
    b.add(2000, rep103_quat(0.2))
    q, gap, interp = b.at(1250, tol_ns=1000)
    assert interp and gap == 250
    assert 2 * math.atan2(q[2], q[3]) == pytest.approx(0.05, abs=1e-4)  # nlerp ~ slerp for 0.2 rad
    q, gap, interp = b.at(2000, tol_ns=10)
    assert not interp and gap == 0
    assert b.at(2600, tol_ns=500) is None  # stale: never extrapolated
    q, gap, _ = b.at(2400, tol_ns=500)
    assert gap == 400
    b.add(1500, rep103_quat(0.1))  # out of order: inserted
    assert b.out_of_order == 1 and len(b) == 3
    b.add(11_600, rep103_quat(0.0))  # prunes older than keep_ns
    assert len(b) == 2 and b.newest_ns == 11_600 and b.at(1500, 10) is None


def test_attitude_buffer_survives_time_line_jumps():
    keep = 1_000
    b = AttitudeBuffer(keep_ns=keep)
    for k in range(5):
        b.add(1000 + 100 * k, rep103_quat(0.0))
    b.add(10**18, rep103_quat(1.0))  # one stamp far in the future: held aside, evicts nothing
    assert b.newest_ns == 1400 and b.jumps_held == 1
    b.add(1500, rep103_quat(0.0))
    assert b.at(1500, 10) is not None
    b.add(200, rep103_quat(0.0))  # a late message far behind: dropped
    assert b.late_dropped == 1 and b.newest_ns == 1500
    b.add(1600, rep103_quat(0.0))
    for k in range(3):  # the clock went back for good (a bag played again)
        b.add(-100_000 + k, rep103_quat(0.3))
    assert b.late_dropped == 3 and b.resets == 1 and b.newest_ns == -100_000 + 2 and len(b) == 1
    b.add(-99_990, rep103_quat(0.3))
    assert b.at(-99_995, 10) is not None
    lone = AttitudeBuffer(keep_ns=keep)  # a lone first sample far ahead was the outlier
    lone.add(10**18, rep103_quat(0.0))
    lone.add(5, rep103_quat(0.0))
    assert lone.newest_ns == 5
    confirmed = AttitudeBuffer(keep_ns=keep)  # a jump ahead confirmed by a second sample is taken
    confirmed.add(0, rep103_quat(0.0))
    confirmed.add(10**12, rep103_quat(0.0))
    confirmed.add(10**12 + 20, rep103_quat(0.0))
    assert confirmed.newest_ns == 10**12 + 20 and len(confirmed) == 2


def test_attitude_buffer_takes_the_short_way_between_q_and_minus_q():
    b = AttitudeBuffer()
    b.add(0, rep103_quat(0.1))
    b.add(10, -rep103_quat(0.3))  # the same rotation family, opposite hemisphere
    q, _, _ = b.at(5, tol_ns=10)
    assert 2 * math.atan2(q[2], q[3]) * np.sign(q[3]) == pytest.approx(0.2, abs=1e-3)


def test_tilt_and_prior_follow_the_estimator_nodes_rules():
    """
    The tilt and the prior follow the heading_estimator node's rules.

    One rule for the heading_estimator node and the replay: the tilt only for tilt_aware and only
    within the IMU tolerance; the imu prior from the IMU within prior_max_age_s (interpolated:
    halfway between yaw 10 and 20 deg is yaw 15, bearing 90 - 15 = 75 with camera +y on body +x);
    the last prior only from a resolved heading younger than prior_max_age_s.
    """
    from polarization_compass.estimators.base import HeadingResult
    from polarization_compass.pipeline import TiltAndPrior

    imu = AttitudeBuffer()
    imu.add(0, rep103_quat(math.radians(10.0)))
    imu.add(1_000_000_000, rep103_quat(math.radians(20.0)))
    t = 500_000_000
    tol = 50_000_000
    ta = TiltAndPrior('tilt_aware', 'imu', 2.0)
    tilt, near = ta.lookups(imu, t, tol)
    assert tilt is None and near.bearing_deg == pytest.approx(75.0, abs=1e-6)
    inp = ta.inputs(t, tilt, near)
    assert (
        inp.tilt_missing
        and inp.pitch_deg is None
        and inp.prior_bearing_deg == pytest.approx(75.0, abs=1e-6)
    )
    tilt, near = ta.lookups(imu, 10_000_000, tol)  # 10 ms from the first sample: tilt known
    inp = ta.inputs(10_000_000, tilt, near)
    assert not inp.tilt_missing and inp.pitch_deg == pytest.approx(0.0, abs=1e-9)
    ls = TiltAndPrior('least_squares', 'imu', 0.4)  # both samples 0.5 s away: no prior
    assert ls.lookups(imu, t, tol) == (None, None)
    assert ls.inputs(t, None, None) == type(inp)(None, None, None, False)
    assert TiltAndPrior('least_squares', 'none').lookups(imu, t, tol) == (None, None)
    last = TiltAndPrior('least_squares', 'last', 2.0)
    assert last.inputs(t, None, None).prior_bearing_deg is None
    last.remember(
        0, HeadingResult.from_psi('least_squares', 30.0, 100.0, 1.0, 10, 1.0, axial=True)
    )
    assert last.inputs(t, None, None).prior_bearing_deg is None  # axial: not a resolved heading
    last.remember(
        0, HeadingResult.from_psi('least_squares', 30.0, 100.0, 1.0, 10, 1.0, axial=False)
    )
    assert last.inputs(t, None, None).prior_bearing_deg == pytest.approx(130.0)
    assert last.inputs(2_000_000_001, None, None).prior_bearing_deg is None  # older than 2 s


# ------------------------------------------------------------------------------------------------
# Motion profile
# ------------------------------------------------------------------------------------------------
def test_one_turn_at_ten_degrees_per_second_is_360_frames_one_degree_apart():
    prof = MotionProfile(turn_rate_deg_s=10.0, turns=1.0)
    total = prof.total_s()
    stamps = []
    k = 0
    while (t := frame_times_ns(0, 10.0, total, k)) is not None:
        stamps.append(t)
        k += 1
    assert len(stamps) == 360
    bearings = [prof.attitude(t / 1e9).bearing_deg for t in stamps]
    assert np.allclose(np.diff(bearings), 1.0) and bearings[0] == 0.0
    assert prof.attitude(1.0).pitch_deg == -20.0
    assert MotionProfile(turn_rate_deg_s=0.0, turns=1.0).total_s() is None


def test_R_enu_body_from_camera_attitude_puts_camera_y_on_body_x():
    att = CameraAttitude(123.0, -20.0, 7.0)
    from polarization_compass.conventions import R_enu_cam_from_attitude

    Rc = R_enu_cam_from_attitude(att.bearing_deg, att.pitch_deg, att.roll_deg)
    Rb = R_enu_body_from_camera_attitude(att)
    assert (
        np.allclose(Rb[:, 0], Rc[:, 1])
        and np.allclose(Rb[:, 2], Rc[:, 2])
        and np.allclose(Rb[:, 1], -Rc[:, 0])
    )


# ------------------------------------------------------------------------------------------------
# Sun and front end
# ------------------------------------------------------------------------------------------------
def test_sun_source_matches_a_direct_ephemeris_call():
    from polarization_compass.solar import sun_position

    src = SunSource(32.026778, 118.853306, 30.0)
    t_ns = 1_573_797_600_000_000_000 + 1_234_567_891  # 2019-11-15T06:00:01.23Z
    az, alt = src.at_ns(t_ns)
    ref = sun_position(np.datetime64(t_ns // 1000, 'us'), 32.026778, 118.853306, 30.0)
    assert az == pytest.approx(ref.azimuth_deg, abs=1e-4) and alt == pytest.approx(
        ref.altitude_deg, abs=1e-4
    )


def test_every_node_builds_its_sun_from_its_site_parameters():
    """
    Every node builds its sun from its site parameters.

    The nodes' sun_source reads latitude, longitude, altitude and sun_model by name (not by
    position): a node whose site is moved and whose model is 'paper' gets exactly that site and
    model.
    """
    from polarization_compass.specs.params import defaults, sun_source

    for specs in (SIMULATOR, ESTIMATOR, CORRECTOR):
        v = defaults(specs)
        v.update(latitude_deg=-33.9, longitude_deg=18.4, altitude_m=1086.0, sun_model='paper')
        src = sun_source(v)
        assert src.site == (-33.9, 18.4, 1086.0) and src.model == 'paper'


def _ideal_mosaic(
    bearing, pitch=0.0, roll=0.0, sun=(200.0, 30.0), encoding='32FC1', cam=SMALL_CAM
):
    from polarization_compass.nodes.sky_simulator import mosaic_config
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene_load import default_scene
    from polarization_compass.sensor import simulate_mosaic

    frame = Renderer(default_scene().replace(camera=cam)).render(
        attitude=CameraAttitude(bearing, pitch, roll), sun=SunDirection(*sun)
    )
    cfg = mosaic_config({}, encoding)
    return simulate_mosaic(
        frame.aop_rad, frame.dop, frame.intensity, cfg, cfg.layout, np.random.default_rng(0)
    )


@pytest.mark.parametrize(
    'method,bearing',
    [
        ('least_squares', 0.0),
        ('least_squares', 181.5),
        ('zenith', 77.0),
        ('sm_asm', 300.0),
        ('symmetry', 123.0),
    ],
)
def test_front_end_level_camera_is_accurate(method, bearing):
    fe = HeadingFrontEnd(method, {'stride': 4} if method != 'zenith' else {})
    res = fe.estimate(
        _ideal_mosaic(bearing), SMALL_CAM, 200.0, 30.0, prior_bearing_deg=bearing + 20.0
    )
    assert res.ok and not res.axial
    assert abs(math.remainder(res.bearing_deg - bearing, 360.0)) < 0.01


def test_front_end_presampling_equals_the_estimators_own_sampling():
    """
    Front-end presampling equals the estimator's own sampling.

    Demosaicing only the superpixels a method reads gives the estimate the method computes when it
    subsamples the whole demosaiced frame itself (two independent sampling paths).
    """
    from polarization_compass.demosaic import polarization_from_mosaic
    from polarization_compass.estimators import make_estimator, Observation
    from polarization_compass.sensor import superpixel_pixels

    m = _ideal_mosaic(40.0, -15.0, 5.0, encoding='mono16')
    fe = HeadingFrontEnd('least_squares', {'stride': 6})
    a = fe.estimate(m, SMALL_CAM, 200.0, 30.0, prior_bearing_deg=40.0)
    aop, dop, valid = polarization_from_mosaic(m)
    grid = superpixel_pixels(SMALL_CAM, 1.0, 1.0, 512, 612)
    obs = Observation(
        aop,
        dop,
        valid & grid.has_ray,
        grid.rays_cam,
        grid.x_px,
        grid.y_px,
        SMALL_CAM,
        200.0,
        30.0,
        None,
        None,
        None,
        40.0,
    )
    b = make_estimator('least_squares', stride=6).estimate(obs)
    assert a.pixels == b.pixels
    assert a.bearing_deg == pytest.approx(b.bearing_deg, abs=1e-9)


def test_front_end_rejects_a_mosaic_of_the_wrong_size():
    from polarization_compass.pipeline import PipelineError

    with pytest.raises(PipelineError, match='camera is 612x512'):
        HeadingFrontEnd('least_squares').estimate(
            np.zeros((10, 10), np.uint16), SMALL_CAM, 0.0, 30.0
        )


# ------------------------------------------------------------------------------------------------
# Parameters
# ------------------------------------------------------------------------------------------------
def test_parameter_rules_give_reasons():
    p = {x.name: x for x in ESTIMATOR}
    assert validate_value(p['frame_id'], 'base_link') is None
    assert 'optical' in validate_value(p['frame_id'], 'camera_optical_frame')
    assert 'one of' in validate_value(p['method'], 'magnetometer')
    assert '0, 45, 90 and 135' in validate_value(p['polarizer_layout'], '0,0,90,135')
    assert validate_value(p['time_utc'], '') is None and 'ISO' in validate_value(
        p['time_utc'], 'noon'
    )
    s = {x.name: x for x in SIMULATOR}
    assert '[0.1, 100.0]' in validate_value(s['rate_hz'], 0.0)
    assert 'finite' in validate_value(s['rate_hz'], float('nan'))
    assert 'integer' in validate_value(s['seed'], 1.5)
    assert validate_value(s['rate_hz'], True) is not None  # a bool is not a number
    assert layout_from_text('90,45,135,0') == ((90, 45), (135, 0))
    for spec in (SIMULATOR, ESTIMATOR, CORRECTOR, EVALUATOR):
        for x in spec:
            assert x.description and validate_value(x, x.default) is None, x.name


def test_knob_parameters_convert_back_to_estimator_knobs():
    params = {x.name: x for x in knob_params('least_squares')}
    assert params['knob.stride'].lo == 1 and params['knob.region'].kind == 'str'
    k = knob_values(
        'least_squares',
        {'knob.stride': 8, 'knob.region': '1,1,100,50', 'knob.weighting': 'uniform'},
    )
    assert k == {'stride': 8, 'region': (1, 1, 100, 50), 'weighting': 'uniform'}
    assert knob_values('least_squares', {'knob.region': ''}) == {'region': None}


def test_rejections_are_logged_once_per_reason_per_period(ctx, monkeypatch):
    """A flood of one rejection reason never hides the first warning of another."""
    from polarization_compass.nodes import diagnostics as D
    import rclpy

    node = rclpy.create_node('diag_throttle_probe', context=ctx)
    lines = []
    monkeypatch.setattr(node.get_logger(), 'warning', lambda msg, **kw: lines.append(msg))
    try:
        diag = D.Diagnostics(node, 'probe')
        for _ in range(50):
            diag.reject('tf_missing', 'no transform')
        diag.reject('tf_stale', 'too old')
        assert [ln.split(':')[0] for ln in lines] == [
            'dropped an input (tf_missing)',
            'dropped an input (tf_stale)',
        ]
        assert diag.rejected == {'tf_missing': 50, 'tf_stale': 1}
        monkeypatch.setattr(D.time, 'monotonic', lambda: 1e12)  # a period later
        diag.reject('tf_missing')
        assert lines[-1] == 'dropped an input (tf_missing)'
    finally:
        node.destroy_node()


class _Log:
    """A logger that keeps its lines."""

    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))


def test_a_failing_warm_up_only_warns_in_both_heading_nodes():
    """
    The camera and the array heading nodes' warm-up: its time logged, a failure only a warning.

    One step serves both nodes; a failure never leaves start-up as an exception (the first input
    then waits for the compilation).
    """
    from types import SimpleNamespace

    from polarization_compass.nodes.heading_node import HeadingNodeBase

    log = _Log()
    node = SimpleNamespace(get_logger=lambda: log)
    HeadingNodeBase._warm_up(node, lambda: 1.5, 'image')

    def boom():
        raise RuntimeError('no kernels')

    HeadingNodeBase._warm_up(node, boom, 'sample')
    assert log.lines == [
        ('info', 'warm-up (kernel compilation or cache load) took 1.50 s'),
        ('warning', 'warm-up failed (RuntimeError: no kernels); the first sample will be slow'),
    ]
