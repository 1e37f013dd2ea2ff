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
Every node fed bad messages counts a rejection and never raises.

A counted rejection (``/diagnostics`` ``rejected`` counter, by reason) or a status message with the
reason, and never an exception out of a callback.

Why calling the callbacks directly is the right test: rclpy's executor re-raises an exception from
a callback out of ``spin_once``, and ``nodes.runner.run_node`` then ends the process (exit 2 for a
CompassError, a traceback otherwise). So "no node dies" is exactly "no callback raises". The nodes
are built in-process on a private rclpy context (no DDS traffic is needed); what the DDS graph does
end to end is test_nodes_graph.py's subject.

Covered elsewhere and not repeated: message decoders' reasons (test_bag.py::test_bad_images_raise_
message_error_with_reason, ::test_orientation_decoding_reasons, ::test_navsatfix_decoding,
::test_camera_info_with_distortion_or_nan_is_refused), the IMU buffer's tolerance
(test_nodes_units.py::test_attitude_buffer_interpolates_within_tolerance_only).
"""

import csv
import math

import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import CameraAttitude
from polarization_compass.mosaic import IMX250MZR_POL45
from polarization_compass.nodes import msgs as M
from polarization_compass.pipeline import AttitudeBuffer
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import ReliabilityPolicy
from sensor_msgs.msg import Image, Imu

T0 = 1_573_797_600_000_000_000  # 2019-11-15T06:00:00Z, the paper's experiment (sun ~30 deg up)
SITE = (32.026778, 118.853306, 30.0)
CAM = CameraModel(
    'pinhole', 96, 80, 0.12, 3.45, 3.45
)  # ~100 deg field of view, 48 x 40 superpixels
LAYOUT = ((90, 45), (135, 0))


def ideal_mosaic(bearing, pitch, roll, sun_az, sun_alt, cam=CAM):
    """
    Build 32FC1 polarizer intensities by Malus's law.

    Written out here: I(phi) = (1 + DoP cos 2(phi - AoLP_x)) / 2 with AoLP_x = 90 deg - AoP
    (physics notes section 1), phi of the IMX250MZR 2 x 2 layout.
    """
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene

    f = Renderer(Scene(camera=cam)).render(
        attitude=CameraAttitude(bearing, pitch, roll), sun=SunDirection(sun_az, sun_alt)
    )
    # the node's default polarizer is the IMX250MZR as delivered: 45 deg towards +x-y, camera angle
    # -label
    sign = 1.0 if IMX250MZR_POL45 == '+x+y' else -1.0
    phi = sign * np.radians(
        np.tile(np.array(LAYOUT, float), (cam.height_px // 2, cam.width_px // 2))
    )
    aolp = np.pi / 2 - f.aop_rad.astype(float)
    m = 0.5 * (1 + f.dop.astype(float) * np.cos(2 * (phi - aolp)))
    return np.where(f.valid, m, 0.5).astype(np.float32)


def body_quat(bearing, pitch, roll):
    from polarization_compass.conventions import body_quat_from_camera_attitude

    return body_quat_from_camera_attitude(CameraAttitude(bearing, pitch, roll))


def imu_msg(t_ns, q, cov0=1e-4):
    m = Imu()
    m.header.stamp = M.time_msg(t_ns)
    m.header.frame_id = 'base_link'
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (float(v) for v in q)
    m.orientation_covariance = [cov0, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1.0]
    return m


def raw_image(h, w, enc, step, data, t_ns=T0, big=0):
    m = Image()
    m.header.stamp = M.time_msg(t_ns)
    m.height, m.width, m.encoding, m.step, m.is_bigendian = h, w, enc, step, big
    m.data = bytes(data)
    return m


def _sun_at(t_ns):
    from polarization_compass.pipeline import SunSource

    return SunSource(*SITE).at_ns(t_ns)


@pytest.fixture(scope='module')
def estimator(ctx):
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='tilt_aware'),
            Parameter('site_source', value='navsatfix'),
        ],
    )
    node.statuses = []
    node._publish_status = node.statuses.append
    yield node
    node.destroy_node()


def feed_good_frame(node, t_ns, bearing=40.0, pitch=-10.0, roll=5.0):
    node._on_camera_info(M.camera_info_msg(CAM, t_ns, 'camera_optical_frame'))
    node._on_fix(M.navsatfix_msg(*SITE, t_ns, 'gps'))
    q = body_quat(bearing, pitch, roll)
    node._on_imu(imu_msg(t_ns - 10_000_000, q))
    node._on_imu(imu_msg(t_ns + 10_000_000, q))
    az, alt = _sun_at(t_ns)
    node._on_image(
        M.image_msg(ideal_mosaic(bearing, pitch, roll, az, alt), t_ns, 'camera_optical_frame')
    )
    return node.statuses[-1]


def rejected(node):
    return dict(node.diag.rejected)


# --------------------------------------------------------------------------------------------
# heading_estimator
# --------------------------------------------------------------------------------------------
def test_estimator_works_on_a_good_frame(estimator):
    st = feed_good_frame(estimator, T0)
    assert st['ok'] and st['status'] == 'ok', st
    assert abs(math.remainder(st['bearing_deg'] - 40.0, 360.0)) < 0.5


BAD_IMAGES = [
    (lambda: raw_image(4, 4, 'rgb8', 12, bytes(48)), 'bad_encoding'),
    (lambda: raw_image(3, 4, 'mono8', 4, bytes(12)), 'bad_size'),  # odd rows: no 2x2 mosaic
    (lambda: raw_image(1, 1, 'mono16', 2, bytes(2)), 'bad_size'),  # a single pixel
    (lambda: raw_image(0, 0, 'mono16', 0, b''), 'bad_size'),  # empty
    (lambda: raw_image(80, 96, 'mono16', 192, bytes(100)), 'bad_size'),  # truncated data
    (
        lambda: raw_image(2**20, 2**20, 'mono16', 2**21, bytes(8)),
        'bad_size',
    ),  # absurd header, no allocation
    (lambda: raw_image(2, 2, '32FC1', 8, np.float32([np.nan] * 4).tobytes()), 'non_finite'),
    (lambda: raw_image(2, 2, '32FC1', 8, np.float32([1, -1, 1, 1]).tobytes()), 'bad_value'),
    (lambda: raw_image(2, 2, '64FC1', 16, bytes(32)), 'bad_encoding'),  # wrong dtype
]


@pytest.mark.parametrize('make, reason', BAD_IMAGES)
def test_estimator_counts_bad_images(estimator, make, reason):
    before = rejected(estimator).get(reason, 0)
    estimator._on_image(make())
    assert rejected(estimator).get(reason, 0) == before + 1


@pytest.mark.parametrize(
    'fill, dtype, enc',
    [
        (0, np.uint16, 'mono16'),
        (65535, np.uint16, 'mono16'),
        (255, np.uint8, 'mono8'),
        (0.0, np.float32, '32FC1'),
    ],
)
def test_estimator_all_zero_or_saturated_image_is_a_status_not_a_crash(
    estimator, fill, dtype, enc
):
    """A decodable image with no usable pixel: one status message with ok false and a reason."""
    t = T0 + 3_000_000_000
    feed_good_frame(estimator, t)  # fix, camera_info and IMU around t
    n = len(estimator.statuses)
    estimator._on_image(M.image_msg(np.full((CAM.height_px, CAM.width_px), fill, dtype), t, 'cam'))
    assert len(estimator.statuses) == n + 1
    st = estimator.statuses[-1]
    assert st['ok'] is False and st['status'] != 'ok' and st['reason']


def test_estimator_image_size_differing_from_camera_info(estimator):
    t = T0 + 4_000_000_000
    feed_good_frame(estimator, t)
    estimator._on_image(M.image_msg(np.ones((40, 48), np.uint16), t, 'cam'))
    st = estimator.statuses[-1]
    assert st['status'] == 'bad_input' and 'camera_info' in st['reason']


@pytest.mark.parametrize(
    'q, reason',
    [
        ([0, 0, 0, 0], 'imu_bad_quaternion'),
        ([0, 0, 0, 2], 'imu_bad_quaternion'),
        ([np.nan, 0, 0, 1], 'imu_non_finite'),
        ([0, 0, np.inf, 1], 'imu_non_finite'),
    ],
)
def test_estimator_counts_bad_imu_quaternions(estimator, q, reason):
    before = rejected(estimator).get(reason, 0)
    estimator._on_imu(imu_msg(T0, q))
    assert rejected(estimator).get(reason, 0) == before + 1


def test_estimator_counts_imu_without_orientation(estimator):
    before = rejected(estimator).get('imu_no_orientation', 0)
    estimator._on_imu(imu_msg(T0, [0, 0, 0, 1], cov0=-1.0))
    assert rejected(estimator).get('imu_no_orientation', 0) == before + 1


def test_estimator_imu_older_than_the_image_is_reported_not_used(estimator):
    """
    An IMU older than the image is reported, not used.

    tilt_aware needs the tilt at the image stamp: IMU samples 1 s older than the image (tolerance
    0.05 s) must give a bad_input status naming the IMU, not a heading from stale tilt.
    """
    t = T0 + 60_000_000_000
    estimator._on_camera_info(M.camera_info_msg(CAM, t, 'cam'))
    estimator._on_fix(M.navsatfix_msg(*SITE, t, 'gps'))
    estimator._on_imu(imu_msg(t - 1_000_000_000, body_quat(40.0, -10.0, 5.0)))
    az, alt = _sun_at(t)
    estimator._on_image(M.image_msg(ideal_mosaic(40.0, -10.0, 5.0, az, alt), t, 'cam'))
    st = estimator.statuses[-1]
    assert st['status'] == 'bad_input' and 'IMU' in st['reason'] and st['ok'] is False


@pytest.mark.parametrize(
    'edit, reason',
    [
        (lambda m: setattr(m.status, 'status', -1), 'fix_no_fix'),
        (lambda m: setattr(m, 'latitude', float('nan')), 'fix_non_finite'),
        (lambda m: setattr(m, 'longitude', 181.0), 'fix_bad_value'),
    ],
)
def test_estimator_counts_bad_fixes(estimator, edit, reason):
    m = M.navsatfix_msg(*SITE, T0, 'gps')
    edit(m)
    before = rejected(estimator).get(reason, 0)
    estimator._on_fix(m)
    assert rejected(estimator).get(reason, 0) == before + 1


def test_estimator_survives_a_fix_with_an_absurd_altitude(estimator):
    m = M.navsatfix_msg(SITE[0], SITE[1], 1.0e6, T0, 'gps')
    estimator._on_fix(m)  # must not raise: reject or clamp


@pytest.mark.parametrize(
    'edit, reason',
    [
        (lambda m: m.k.__setitem__(0, float('nan')), 'camera_info_non_finite'),
        (lambda m: m.k.__setitem__(0, 0.0), 'camera_info_bad_camera_info'),
        (
            lambda m: setattr(m, 'distortion_model', 'kannala_brandt'),
            'camera_info_unsupported_camera',
        ),
    ],
)
def test_estimator_counts_bad_camera_info(estimator, edit, reason):
    m = M.camera_info_msg(CAM, T0, 'cam')
    edit(m)
    before = rejected(estimator).get(reason, 0)
    estimator._on_camera_info(m)
    assert rejected(estimator).get(reason, 0) == before + 1


def test_estimator_is_still_working_after_all_the_bad_input(estimator):
    st = feed_good_frame(estimator, T0 + 200_000_000_000, bearing=250.0)
    assert st['ok'], st
    assert abs(math.remainder(st['bearing_deg'] - 250.0, 360.0)) < 0.5


def test_estimator_recovers_from_an_imu_stamp_far_in_the_future(estimator):
    t = T0 + 300_000_000_000
    saved = estimator.imu
    estimator.imu = AttitudeBuffer(keep_ns=saved.keep_ns)  # a fresh buffer, restored afterwards
    try:
        estimator._on_imu(imu_msg(t + 10**18, body_quat(40.0, -10.0, 5.0)))  # 31 years ahead
        st = feed_good_frame(estimator, t)
    finally:
        estimator.imu = saved
    assert st['ok'], st


def test_attitude_buffer_far_future_sample_does_not_evict_good_ones():
    """
    A far-future sample does not evict good ones from the attitude buffer.

    The same bug at the buffer level: after a sample 31 years ahead, a correct sample is gone on
    arrival.
    """
    b = AttitudeBuffer(keep_ns=10_000_000_000)
    q = body_quat(0.0, 0.0, 0.0)
    b.add(T0, q)
    b.add(T0 + 10**18, q)
    b.add(T0 + 1_000_000, q)
    assert b.at(T0 + 1_000_000, 50_000_000) is not None


def test_estimator_adds_the_imu_tilt_uncertainty_to_tilt_aware_sigma(estimator):
    """The IMU covariance grows tilt_aware's sigma by J Sigma_att J^T; all zeros: unknown."""
    t = T0 + 300_000_000_000
    known = feed_good_frame(estimator, t)  # imu_msg: roll and pitch variance 1e-4 rad^2
    assert known['ok'] and known['attitude_covariance'] == 'imu'
    assert known['attitude_sigma_deg'] == pytest.approx(math.degrees(0.01))
    s_att = known['sigma_attitude_deg']
    assert s_att > 0.05  # |J| ~ 0.1-1 deg/deg at 0.57 deg of tilt sigma: a real share

    def zero_cov(m):
        m.orientation_covariance = [0.0] * 9
        return m

    orig = estimator._on_imu
    estimator._on_imu = lambda m: orig(zero_cov(m))
    try:
        unknown = feed_good_frame(estimator, t + 1_000_000_000)
        estimator.set_parameters([Parameter('attitude_sigma_deg', value=2 * math.degrees(0.01))])
        stated = feed_good_frame(estimator, t + 2_000_000_000)
    finally:
        estimator._on_imu = orig
        estimator.set_parameters([Parameter('attitude_sigma_deg', value=0.0)])
    assert unknown['attitude_covariance'] == 'unknown' and unknown['sigma_attitude_deg'] == 0.0
    # same frame, same fit: the variances differ by exactly the attitude's share (and by the
    # change of the principal point's share with the sun, which moves in the 1 s between frames)
    pp = known['sigma_principal_point_deg'] ** 2 - unknown['sigma_principal_point_deg'] ** 2
    assert known['sigma_deg'] ** 2 - unknown['sigma_deg'] ** 2 - pp == pytest.approx(s_att**2)
    # linear in the tilt sigma: twice the stated sigma, twice the share (the frames are 1 s apart:
    # the sun, hence J, moves by ~1e-4 relative)
    assert stated['sigma_attitude_deg'] == pytest.approx(2 * s_att, rel=1e-3)


# --------------------------------------------------------------------------------------------
# tilt_corrector
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def corrector(ctx, tmp_path_factory):
    from polarization_compass.errormap import ErrorMap
    from polarization_compass.nodes.tilt_corrector import TiltCorrectorNode

    alt, yaw, tilt = (
        np.arange(0.0, 55.0, 10.0),
        np.arange(-180.0, 180.0, 10.0),
        np.arange(-30.0, 31.0, 10.0),
    )
    shape = (1, alt.size, yaw.size, tilt.size, tilt.size)
    path = tmp_path_factory.mktemp('map') / 'zero_map.npz'
    ErrorMap(
        np.zeros(shape),
        np.zeros(shape, np.int8),
        ('least_squares',),
        alt,
        yaw,
        tilt,
        tilt,
        meta={'domain': {'tilt_limit_deg': 30.0}},
    ).save(path)
    node = TiltCorrectorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('error_map', value=str(path)),
            Parameter('imu_max_wait_s', value=0.0),
        ],
    )
    node.statuses = []
    node._status = node.statuses.append
    yield node
    node.destroy_node()


def heading_msg(t_ns, bearing, var=1e-4):
    return M.heading_imu(t_ns, 'base_link', math.radians(90.0 - bearing), var, 1000.0)


def test_corrector_passes_a_good_heading_through_a_zero_map(corrector):
    corrector._on_imu(imu_msg(T0, body_quat(30.0, -5.0, 5.0)))
    corrector._on_heading(heading_msg(T0, 30.0))
    st = corrector.statuses[-1]
    assert st['status'] == 'ok' and abs(math.remainder(st['bearing_deg'] - 30.0, 360)) < 1e-6


@pytest.mark.parametrize(
    'edit, reason',
    [
        (
            lambda m: setattr(m.orientation, 'w', 0.0) or setattr(m.orientation, 'z', 0.0),
            'heading_bad_quaternion',
        ),
        (lambda m: setattr(m.orientation, 'x', float('nan')), 'heading_non_finite'),
        (
            lambda m: m.orientation_covariance.__setitem__(8, float('nan')),
            'heading_bad_covariance',
        ),
        (lambda m: m.orientation_covariance.__setitem__(8, 0.0), 'heading_bad_covariance'),
        (lambda m: m.orientation_covariance.__setitem__(8, -1.0), 'heading_bad_covariance'),
    ],
)
def test_corrector_counts_bad_headings(corrector, edit, reason):
    m = heading_msg(T0, 30.0)
    edit(m)
    before = rejected(corrector).get(reason, 0)
    corrector._on_heading(m)
    assert rejected(corrector).get(reason, 0) == before + 1


@pytest.mark.parametrize('pitch, roll', [(-40.0, 0.0), (20.0, 20.0)])
def test_corrector_tilt_outside_the_map_is_an_out_of_domain_status(corrector, pitch, roll):
    t = T0 + 5_000_000_000
    corrector._on_imu(imu_msg(t, body_quat(30.0, pitch, roll)))
    corrector._on_heading(heading_msg(t, 30.0))
    st = corrector.statuses[-1]
    assert st['status'] == 'out_of_domain' and st['published'] is False and st['reason']


def test_corrector_imu_older_than_the_heading_is_stale(corrector):
    t = T0 + 20_000_000_000
    corrector._on_imu(imu_msg(t - 2_000_000_000, body_quat(30.0, 0.0, 0.0)))
    corrector._on_heading(heading_msg(t, 30.0))
    corrector._drain()
    assert corrector.statuses[-1]['status'] == 'stale_imu'


@pytest.fixture(scope='module')
def sloped_corrector(ctx, tmp_path_factory):
    """Build a corrector whose map's error is 0.5 x pitch: d psi / d pitch = -0.5, d/droll 0."""
    from polarization_compass.errormap import ErrorMap
    from polarization_compass.nodes.tilt_corrector import TiltCorrectorNode

    alt, yaw, tilt = (
        np.arange(0.0, 55.0, 10.0),
        np.arange(-180.0, 180.0, 10.0),
        np.arange(-30.0, 31.0, 10.0),
    )
    err = np.broadcast_to(0.5 * tilt[:, None], (alt.size, yaw.size, tilt.size, tilt.size))
    path = tmp_path_factory.mktemp('map') / 'sloped_map.npz'
    ErrorMap(
        np.array(err)[None],
        np.zeros((1,) + err.shape, np.int8),
        ('least_squares',),
        alt,
        yaw,
        tilt,
        tilt,
        meta={'domain': {'tilt_limit_deg': 30.0}},
    ).save(path)
    node = TiltCorrectorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('error_map', value=str(path)),
            Parameter('imu_max_wait_s', value=0.0),
        ],
    )
    node.statuses = []
    node._status = node.statuses.append
    yield node
    node.destroy_node()


def test_corrector_propagates_the_imu_covariance_into_the_heading_sigma(sloped_corrector):
    node = sloped_corrector
    t = T0 + 40_000_000_000
    node._on_imu(imu_msg(t, body_quat(30.0, 0.0, 0.0), cov0=4e-4))  # roll var > pitch var
    node._on_heading(heading_msg(t, 30.0, var=1e-4))
    st = node.statuses[-1]
    s_tilt = math.degrees(math.sqrt(4e-4))  # the larger of roll/pitch variances, both axes
    assert st['attitude_covariance'] == 'imu'
    assert st['attitude_sigma_deg'] == pytest.approx(s_tilt)
    assert st['sigma_attitude_deg'] == pytest.approx(0.5 * s_tilt, rel=1e-6)
    expected_var = 1e-4 + math.radians(0.1) ** 2 + math.radians(0.5 * s_tilt) ** 2
    assert st['sigma_deg'] == pytest.approx(math.degrees(math.sqrt(expected_var)), rel=1e-9)


def test_corrector_unknown_covariance_propagates_only_the_stated_sigma(sloped_corrector):
    from rclpy.parameter import Parameter as P

    node = sloped_corrector
    t = T0 + 50_000_000_000
    m = imu_msg(t, body_quat(30.0, 0.0, 0.0))
    m.orientation_covariance = [0.0] * 9  # sensor_msgs/Imu: covariance unknown
    node._on_imu(m)
    node._on_heading(heading_msg(t, 30.0, var=1e-4))
    st = node.statuses[-1]
    assert st['attitude_covariance'] == 'unknown' and st['sigma_attitude_deg'] == 0.0
    assert st['sigma_deg'] == pytest.approx(
        math.degrees(math.sqrt(1e-4 + math.radians(0.1) ** 2)), rel=1e-9
    )
    node.set_parameters([P('attitude_sigma_deg', value=2.0)])
    node._on_imu(m)
    node._on_heading(heading_msg(t, 30.0, var=1e-4))
    st = node.statuses[-1]
    assert st['status'] == 'ok' and st['sigma_attitude_deg'] == pytest.approx(1.0, rel=1e-6)


# --------------------------------------------------------------------------------------------
# error_evaluator
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def evaluator(ctx, tmp_path_factory):
    from polarization_compass.nodes.error_evaluator import ErrorEvaluatorNode

    out = tmp_path_factory.mktemp('report')
    node = ErrorEvaluatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('report_dir', value=str(out)),
            Parameter('methods', value=['least_squares']),
            Parameter('direct_methods', value=['']),
        ],
    )
    node.report_dir = out
    yield node
    node.destroy_node()


@pytest.mark.parametrize(
    'q, reason', [([0, 0, 0, 0], 'bad_quaternion'), ([np.nan, 0, 0, 1], 'non_finite')]
)
def test_evaluator_counts_bad_truth_and_estimates(evaluator, q, reason):
    before = rejected(evaluator)
    evaluator._on_truth(imu_msg(T0, q))
    evaluator._on_estimate('least_squares/raw', imu_msg(T0, q))
    after = rejected(evaluator)
    assert after.get('truth_' + reason, 0) == before.get('truth_' + reason, 0) + 1
    assert after.get('estimate_' + reason, 0) == before.get('estimate_' + reason, 0) + 1


def test_evaluator_never_writes_nan_sigma(evaluator):
    for k, var in enumerate((float('nan'), float('inf'))):
        t = T0 + 50_000_000_000 + k * 100_000_000
        evaluator._on_truth(heading_msg(t, 30.0))
        m = heading_msg(t, 30.2)
        m.orientation_covariance[8] = var  # heading_imu itself refuses to build this
        evaluator._on_estimate('least_squares/raw', m)
    evaluator.close()
    with open(evaluator.report_dir / 'evaluation_samples.csv') as fh:
        for row in csv.DictReader(fh):
            assert math.isfinite(float(row['sigma_deg'])), row


# --------------------------------------------------------------------------------------------
# parameter files (parsed by rcl's C YAML parser, not Python)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('node_main', ['heading_estimator', 'tilt_corrector', 'error_evaluator'])
def test_a_python_tag_in_a_parameter_file_is_never_executed(ctx, tmp_path, capsys, node_main):
    """
    A Python tag in a parameter file is never executed.

    rcl ignores YAML tags: the tagged value arrives as a plain string array, the typed parameter
    refuses it, and the node exits 2 with one line. (test_nodes_robustness.py checks an
    out-of-range value over DDS.)
    """
    import importlib

    marker = tmp_path / 'EXECUTED'
    p = tmp_path / 'evil.yaml'
    p.write_text(
        '/**:\n  ros__parameters:\n    method: !!python/object/apply:os.system ["touch '
        f'{marker}"]\n'
        f'    methods: !!python/object/apply:os.system ["touch {marker}"]\n'
    )
    main = importlib.import_module(f'polarization_compass.nodes.{node_main}').main
    rc = main([node_main, '--ros-args', '--params-file', str(p)])
    err = capsys.readouterr().err
    assert rc == 2 and 'Traceback' not in err and 'error' in err
    assert not marker.exists()


# --------------------------------------------------------------------------------------------
# sky_simulator: its own inputs (attitude topic, lockstep acks)
# --------------------------------------------------------------------------------------------
TINY_SCENE = """camera: {model: pinhole, width_px: 48, height_px: 40, focal_length_mm: 0.12,
         pixel_pitch_x_um: 3.45, pixel_pitch_y_um: 3.45}
"""


@pytest.fixture(scope='module')
def topic_simulator(ctx, tmp_path_factory):
    from polarization_compass.nodes.sky_simulator import SkySimulatorNode

    scene = tmp_path_factory.mktemp('sim') / 'tiny.yaml'
    scene.write_text(TINY_SCENE)
    node = SkySimulatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('scene', value=str(scene)),
            Parameter('encoding', value='32FC1'),
            Parameter('attitude_source', value='topic'),
            Parameter('lockstep', value=True),
            Parameter('lockstep_topics', value=['compass/least_squares/status']),
            Parameter('turns', value=0.0),
        ],
    )
    yield node
    node.destroy_node()


@pytest.mark.parametrize('q', [[0, 0, 0, 0], [np.nan, 0, 0, 1], [0, 0, 0, 3]])
def test_simulator_counts_bad_attitudes_and_keeps_the_last_good_one(topic_simulator, q):
    good = body_quat(75.0, -10.0, 4.0)
    topic_simulator._on_attitude(imu_msg(T0, good))
    kept = topic_simulator.R_enu_body_input.copy()
    before = rejected(topic_simulator)
    topic_simulator._on_attitude(imu_msg(T0 + 1, q))  # must not raise
    after = rejected(topic_simulator)
    grew = {k: after[k] - before.get(k, 0) for k in after if after[k] != before.get(k, 0)}
    assert list(grew.values()) == [1] and next(iter(grew)).startswith('attitude'), grew
    assert np.array_equal(
        topic_simulator.R_enu_body_input, kept
    )  # the bad sample replaced nothing
    from polarization_compass.conventions import quat_to_matrix

    assert np.allclose(kept, quat_to_matrix(good), atol=1e-12)


@pytest.mark.parametrize('text', ['not json', '[1, 2]', '{"stamp_ns": "soon"}', 'null'])
def test_simulator_counts_unreadable_lockstep_acks(topic_simulator, text):
    from std_msgs.msg import String

    topic = 'compass/least_squares/status'
    topic_simulator.acks[topic] = 5
    before = rejected(topic_simulator).get('lockstep_bad_status', 0)
    topic_simulator._on_ack(topic, String(data=text))  # must not raise
    assert rejected(topic_simulator).get('lockstep_bad_status', 0) == before + 1
    assert topic_simulator.acks[topic] == 5  # no ack was invented
    topic_simulator._on_ack(topic, String(data='{"stamp_ns": 9}'))
    assert topic_simulator.acks[topic] == 9  # and good acks still count


# --------------------------------------------------------------------------------------------
# issue 18: implausible camera_info, a heading against the IMU prior, parameter sets that raise
# --------------------------------------------------------------------------------------------
def _info_with_k(t_ns, fx, fy, cx, cy):
    m = M.camera_info_msg(CAM, t_ns, 'camera_optical_frame')
    m.k[:] = np.array([fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0])
    return m


FX_CAM = CAM.focal_length_mm / (CAM.pixel_pitch_x_um * 1e-3)


@pytest.mark.parametrize(
    'k',
    [
        (
            FX_CAM,
            FX_CAM,
            CAM.width_px - 1.0,
            CAM.height_px - 1.0,
        ),  # principal point at the last pixel
        (2 * FX_CAM, 2 * FX_CAM, CAM.width_px - 1.0, CAM.height_px - 1.0),  # K scaled 2x
        (FX_CAM, FX_CAM, 10000.0, -5000.0),  # far outside
    ],
)
def test_estimator_implausible_camera_info_gives_no_ok_heading_and_withdraws_the_good_one(
    estimator, k
):
    """
    Issue 18: such a camera_info gave a confident wrong heading (status ok).

    Now it is counted, and the frames after it get a bad_input status naming it -- also when a good
    camera_info came before it (a rejected one never leaves another in use) -- until a good one
    comes again.
    """
    t = T0 + 400_000_000_000
    assert feed_good_frame(estimator, t)['ok']  # a good camera_info in use
    before = rejected(estimator).get('camera_info_bad_camera_info', 0)
    estimator._on_camera_info(_info_with_k(t + 10**8, *k))
    assert rejected(estimator).get('camera_info_bad_camera_info', 0) == before + 1
    q = body_quat(40.0, -10.0, 5.0)
    estimator._on_imu(imu_msg(t + 10**8 + 10**7, q))
    az, alt = _sun_at(t + 10**8)
    estimator._on_image(
        M.image_msg(ideal_mosaic(40.0, -10.0, 5.0, az, alt), t + 10**8, 'camera_optical_frame')
    )
    st = estimator.statuses[-1]
    assert st['stamp_ns'] == t + 10**8 and st['ok'] is False and st['status'] == 'bad_input'
    assert 'camera_info was rejected' in st['reason'] and st['published'] is False
    assert feed_good_frame(estimator, t + 2 * 10**8)['ok']  # a good camera_info again


def test_estimator_heading_57_deg_from_the_imu_prior_is_not_ok(estimator):
    """
    Issue 18: an IMU prior 57 deg from the sky's heading raised nothing.

    The camera tilt is the same in both IMU samples (only the yaw differs), so tilt_aware's sky fit
    is as good as ever: only the prior check can say no. 30 deg away (within 3 x sqrt(sigma^2 +
    15^2)) stays ok.
    """
    t = T0 + 500_000_000_000
    feed_good_frame(estimator, t)  # camera_info and fix
    for k, (offset, ok) in enumerate([(57.0, False), (30.0, True)]):
        tk = t + (k + 1) * 10**9
        q = body_quat(40.0 + offset, -10.0, 5.0)
        estimator._on_imu(imu_msg(tk - 10_000_000, q))
        estimator._on_imu(imu_msg(tk + 10_000_000, q))
        az, alt = _sun_at(tk)
        estimator._on_image(
            M.image_msg(ideal_mosaic(40.0, -10.0, 5.0, az, alt), tk, 'camera_optical_frame')
        )
        st = estimator.statuses[-1]
        assert st['stamp_ns'] == tk and st['ok'] is ok, st
        if not ok:
            assert (
                st['status'] == 'prior_disagrees'
                and st['published'] is False
                and 'IMU prior' in st['reason']
            )
        else:
            assert abs(math.remainder(st['bearing_deg'] - 40.0, 360.0)) < 0.5


def _map_with_deep_meta(path):
    """Write an error-map file whose meta is JSON nested 100000 deep (valid arrays otherwise)."""
    alt, yaw, tilt = (
        np.arange(0.0, 55.0, 10.0),
        np.arange(-180.0, 180.0, 10.0),
        np.arange(-30.0, 31.0, 10.0),
    )
    shape = (1, alt.size, yaw.size, tilt.size, tilt.size)
    np.savez(
        path,
        error_deg=np.zeros(shape),
        status=np.zeros(shape, np.int8),
        methods=np.array(['least_squares']),
        sun_altitude_deg=alt,
        yaw_deg=yaw,
        pitch_deg=tilt,
        roll_deg=tilt,
        meta=np.array('{"a":' * 100000 + '1' + '}' * 100000),
    )
    return path


def test_corrector_survives_an_error_map_parameter_with_deeply_nested_meta(corrector, tmp_path):
    """
    Issue 18: the RecursionError of such a map ended tilt_corrector.

    Refused with a reason, map kept.
    """
    old = corrector.corrector
    res = corrector.set_parameters(
        [Parameter('error_map', value=str(_map_with_deep_meta(tmp_path / 'deep.npz')))]
    )
    assert (
        res[0].successful is False and 'error_map' in res[0].reason or 'error map' in res[0].reason
    )
    assert corrector.corrector is old
    test_corrector_passes_a_good_heading_through_a_zero_map(corrector)  # still working


def test_any_exception_of_a_parameter_change_is_a_refusal_not_a_dead_node(
    corrector, tmp_path, monkeypatch
):
    """
    Any exception of a parameter change is a refusal, not a dead node.

    Whatever the loader raises (here a MemoryError), the parameter set is refused and the node
    lives.
    """
    from polarization_compass.nodes import tilt_corrector as tc

    def boom(path, method):
        raise MemoryError('simulated')

    monkeypatch.setattr(tc, 'load_corrector', boom)
    old = corrector.corrector
    res = corrector.set_parameters([Parameter('error_map', value=str(tmp_path / 'any.npz'))])
    assert res[0].successful is False and 'MemoryError' in res[0].reason
    assert corrector.corrector is old and corrector.params['error_map'] != str(
        tmp_path / 'any.npz'
    )


def test_estimator_counts_images_dropped_from_a_full_queue(estimator):
    """
    The estimator counts images dropped from a full queue.

    A flood never costs a frame without a count: with MAX_PENDING_IMAGES waiting, the oldest is
    dropped and counted (image_queue_full); every queued frame gets a status.
    """
    from polarization_compass.nodes.heading_estimator import MAX_PENDING_IMAGES

    t = T0 + 600_000_000_000
    feed_good_frame(estimator, t)
    n_status, before = len(estimator.statuses), rejected(estimator).get('image_queue_full', 0)
    az, alt = _sun_at(t)
    img = ideal_mosaic(40.0, -10.0, 5.0, az, alt)
    n = MAX_PENDING_IMAGES + 3
    for k in range(n):  # received while nothing is processed
        estimator._receive_image(M.image_msg(img, t + (k + 1) * 5 * 10**5, 'camera_optical_frame'))
        estimator._receive_image(raw_image(3, 4, 'mono8', 4, bytes(12)))  # and a bad one each time
    assert rejected(estimator).get('image_queue_full', 0) == before + 3
    estimator._drain()
    done = [s['stamp_ns'] for s in estimator.statuses[n_status:]]
    assert done == [t + (k + 1) * 5 * 10**5 for k in range(3, n)]  # the newest, in order


def test_estimator_with_the_replay_qos_queues_a_played_bag_instead_of_dropping(ctx):
    """image_qos replay (the replay graph): REPLAY_IMAGE_DEPTH images wait, none is dropped."""
    from polarization_compass.nodes.heading_estimator import (
        HeadingEstimatorNode,
        MAX_PENDING_IMAGES,
    )
    from polarization_compass.specs.topics import REPLAY_IMAGE_DEPTH

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='least_squares'),
            Parameter('site_source', value='navsatfix'),
            Parameter('image_qos', value='replay'),
        ],
    )
    try:
        assert node.max_pending == REPLAY_IMAGE_DEPTH >= 4 * MAX_PENDING_IMAGES
        sub = next(s for s in node.subscriptions if s.topic_name.endswith('camera/image_raw'))
        assert sub.qos_profile.depth == REPLAY_IMAGE_DEPTH
        assert sub.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        # the played IMU reliably too (a best-effort sample lost under the image flood is lost)
        imu = next(s for s in node.subscriptions if s.topic_name.endswith('imu/data'))
        assert imu.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        node._on_camera_info(M.camera_info_msg(CAM, T0, 'camera_optical_frame'))
        img = ideal_mosaic(40.0, -10.0, 5.0, *_sun_at(T0))
        n = 4 * MAX_PENDING_IMAGES
        for k in range(n):  # received while nothing is processed
            node._receive_image(M.image_msg(img, T0 + k * 10**8, 'camera_optical_frame'))
        assert len(node.pending) == n
        assert 'image_queue_full' not in rejected(node)
    finally:
        node.destroy_node()


def test_estimator_reports_a_polarizer_convention_the_sky_contradicts(ctx):
    """
    The estimator refuses headings under a polarizer convention the sky contradicts.

    The images follow the IMX250MZR as delivered (+x-y); a node configured +x+y must check from
    the first frame on, publish no ``ok`` heading (status ``poor_fit`` naming the fix, issue 24
    item 3), say so as a diagnostics ERROR, keep processing frames, and clear the error once
    reconfigured; once the sky supports the configuration it checks every N-th frame only.
    """
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='least_squares'),
            Parameter('site_source', value='navsatfix'),
            Parameter('pol45_toward', value='+x+y'),
            Parameter('polarizer_check_every', value=2),
        ],
    )
    node.statuses = []
    node._publish_status = node.statuses.append
    try:
        for t in (T0 - 10**9, T0):  # every frame is checked while the sky contradicts
            st = feed_good_frame(node, t, bearing=65.0, pitch=0.0, roll=0.0)
            assert st['polarizer_check']['verdict'] == 'contradicted'
            assert st['status'] == 'poor_fit' and not st['ok'], st
            assert "pol45_toward: '+x-y'" in st['reason']
        assert node.diag.error and "pol45_toward: '+x-y'" in node.diag.error
        from diagnostic_msgs.msg import DiagnosticStatus

        assert node.diag.level_and_message()[0] == DiagnosticStatus.ERROR
        node.set_parameters([Parameter('pol45_toward', value='+x-y')])
        st = feed_good_frame(node, T0 + 10**9, bearing=65.0, pitch=0.0, roll=0.0)
        assert st['polarizer_check']['verdict'] == 'supported'
        assert st['status'] == 'ok' and node.diag.error is None
        feed_good_frame(node, T0 + 2 * 10**9, bearing=65.0, pitch=0.0, roll=0.0)
        st = feed_good_frame(node, T0 + 3 * 10**9, bearing=65.0, pitch=0.0, roll=0.0)
        assert 'polarizer_check' not in st and st['status'] == 'ok'  # every 2nd frame now
    finally:
        node.destroy_node()


@pytest.mark.parametrize('readout_flip', ['none', 'x'])
def test_estimator_reads_a_mirrored_readout_back_with_readout_flip(ctx, readout_flip):
    """
    A camera that mirrors its readout in x (GenICam ReverseX) with ``readout_flip: x``.

    The node reads the image back as the sensor sees it and mirrors the camera_info's K with it:
    the true heading, ``ok``, as from the unmirrored camera. Configured without it, the same images
    never give an ``ok`` at the true heading (a layout cannot undo a mirrored geometry).
    """
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='tilt_aware'),
            Parameter('site_source', value='navsatfix'),
            Parameter('readout_flip', value=readout_flip),
        ],
    )
    node.statuses = []
    node._publish_status = node.statuses.append
    bearing, pitch, roll = 40.0, -10.0, 5.0
    try:
        node._on_camera_info(M.camera_info_msg(CAM, T0, 'camera_optical_frame'))
        node._on_fix(M.navsatfix_msg(*SITE, T0, 'gps'))
        q = body_quat(bearing, pitch, roll)
        node._on_imu(imu_msg(T0 - 10_000_000, q))
        node._on_imu(imu_msg(T0 + 10_000_000, q))
        sensor = ideal_mosaic(bearing, pitch, roll, *_sun_at(T0))
        delivered = np.ascontiguousarray(sensor[:, ::-1])  # the readout mirrors x
        node._on_image(M.image_msg(delivered, T0, 'camera_optical_frame'))
        st = node.statuses[-1]
        right = st['ok'] and abs(math.remainder(st['bearing_deg'] - bearing, 360.0)) < 0.5
        assert right == (readout_flip == 'x'), st
    finally:
        node.destroy_node()
