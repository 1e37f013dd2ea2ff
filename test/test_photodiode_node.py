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
array_heading_estimator: a photodiode-array compass and its companion header.

A photodiode-array compass on compass_array/intensities (std_msgs/Float32MultiArray) with its
companion std_msgs/Header on compass_array/header, callbacks
called in-process on a private rclpy context (see test_hard_cases_nodes.py for why that is the
right test of 'never crashes'). The DDS test at the end runs the simulator and the estimator as
processes.
"""

import math
from pathlib import Path
import time

import numpy as np
from polarization_compass.errors import CompassError
from polarization_compass.nodes import msgs as M
from polarization_compass.photodiode.geometry import load_array_geometry
from polarization_compass.photodiode.simulate import simulate_readings
import pytest
from rclpy.parameter import Parameter
from std_msgs.msg import Float32MultiArray, Header, MultiArrayDimension

GEOMETRY = str(Path(__file__).resolve().parents[1] / 'config' / 'arrays' / 'pol_op_8unit.yaml')
TIME = '2019-11-15T04:00:00Z'  # Nanjing (the default site), sun about 40 deg up


def _sun():
    from polarization_compass.solar import sun_position

    p = sun_position(TIME, 32.026778, 118.853306, 30.0)
    return p.azimuth_deg, p.altitude_deg


def array_msg(sample, dims=True, offset=0):
    m = Float32MultiArray()
    a = np.asarray(sample, dtype=np.float32)
    if dims:
        m.layout.dim = [
            MultiArrayDimension(label='units', size=a.shape[0], stride=a.size),
            MultiArrayDimension(label='channels', size=a.shape[1], stride=a.shape[1]),
        ]
    m.layout.data_offset = offset
    m.data = [0.0] * offset + [float(v) for v in a.ravel()]
    return m


def feed(n, msg, stamp_ns=None, frame_id='compass_link', header=True):
    """
    Publish the companion header, then the array.

    Publish-like: the companion header (stamp ``stamp_ns``, default the node's now) then the array.
    """
    t = n.get_clock().now().nanoseconds if stamp_ns is None else int(stamp_ns)
    if header:
        n._on_array_header(Header(stamp=M.time_msg(t), frame_id=frame_id))
    n._on_array(msg)
    return t


def _stamp(m) -> int:
    return int(m.header.stamp.sec) * 1_000_000_000 + int(m.header.stamp.nanosec)


@pytest.fixture(scope='module', params=['least_squares', 'tilt_aware'])
def node(ctx, request):
    from polarization_compass.nodes.array_heading_estimator import ArrayHeadingEstimatorNode

    n = ArrayHeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value=request.param),
            Parameter('array_geometry', value=GEOMETRY),
            Parameter('time_source', value='parameter'),
            Parameter('time_utc', value=TIME),
            Parameter('prior_source', value='none'),
            Parameter('imu_tolerance_s', value=5.0),
        ],
    )
    n.statuses, n.headings = [], []
    n._publish_status = n.statuses.append
    n.pub_heading = type('P', (), {'publish': lambda self, m: n.headings.append(m)})()
    yield n
    n.destroy_node()


def _feed_imu(n):
    from polarization_compass.conventions import body_quat_from_camera_attitude, CameraAttitude
    from test_hard_cases_nodes import imu_msg

    now = n.get_clock().now().nanoseconds
    q = body_quat_from_camera_attitude(CameraAttitude(0.0, 0.0, 0.0))
    n._on_imu(
        imu_msg(now - 1_000_000_000, q)
    )  # level, around the arrival stamp of the next sample
    n._on_imu(imu_msg(now + 2_000_000_000, q))


@pytest.mark.parametrize('bearing', [30.0, 200.0])
def test_array_sample_gives_the_heading_imu(node, bearing):
    g = load_array_geometry(GEOMETRY)
    az, alt = _sun()
    x = simulate_readings(g, az, alt, [bearing])[0]
    if node.needs_tilt:
        _feed_imu(node)
    n_before = len(node.headings)
    t = node.get_clock().now().nanoseconds - 123_456_789  # a stamp that is not the arrival time
    feed(node, array_msg(x), t)
    st = node.statuses[-1]
    assert st['status'] == 'ok' and st['published'], st
    assert (
        abs(math.remainder(st['bearing_deg'] - bearing, 360.0)) < 0.5
    )  # the acceptance cone: < 0.5 deg
    assert len(node.headings) == n_before + 1
    assert (
        _stamp(node.headings[-1]) == t and st['stamp_ns'] == t
    )  # the header's stamp, not the arrival
    assert node.headings[-1].header.frame_id == 'compass_link'  # and its frame
    yaw = M.yaw_enu_from_quat([getattr(node.headings[-1].orientation, k) for k in 'xyzw'])
    assert abs(math.remainder(math.degrees(yaw) - (90.0 - bearing), 360.0)) < 0.5
    assert st['pixels'] in (5, 6)  # units 5 and 7 are disabled; one may look (nearly) at the sun


def test_layout_without_dims_and_with_offset(node):
    g = load_array_geometry(GEOMETRY)
    az, alt = _sun()
    x = simulate_readings(g, az, alt, [75.0])[0]
    if node.needs_tilt:
        _feed_imu(node)
    feed(node, array_msg(x, dims=False, offset=3))
    assert node.statuses[-1]['status'] == 'ok'


@pytest.mark.parametrize(
    'make',
    [
        lambda: array_msg(np.ones((8, 3))),  # wrong channel count
        lambda: array_msg(np.ones((7, 4))),  # wrong unit count
        lambda: array_msg(np.full((8, 4), np.nan)),  # not finite
        lambda: _short(),  # no layout, 31 values for 8 x 4
    ],
)
def test_bad_array_messages_are_counted_not_raised(node, make):
    before = dict(node.diag.rejected).get('array_layout', 0)
    n_status = len(node.statuses)
    feed(node, make())
    assert dict(node.diag.rejected).get('array_layout', 0) == before + 1
    assert len(node.statuses) == n_status


def test_array_without_its_header_is_dropped_and_counted(node):
    """
    An array without its header is dropped and counted.

    No header within the timeout: no heading, no status with a made-up stamp, a drop by reason.
    """
    g = load_array_geometry(GEOMETRY)
    az, alt = _sun()
    x = simulate_readings(g, az, alt, [120.0])[0]
    if node.needs_tilt:
        _feed_imu(node)
    n_head, n_status = len(node.headings), len(node.statuses)
    before = dict(node.diag.rejected).get('array_header_timeout', 0)
    feed(node, array_msg(x), header=False)
    assert len(node.statuses) == n_status and node.pairer.pending_arrays == 1
    time.sleep(node.params['array_header_timeout_s'] + 0.05)
    node._expire_array_pairs()
    assert dict(node.diag.rejected)['array_header_timeout'] == before + 1
    assert (
        node.pairer.pending_arrays == 0
        and len(node.headings) == n_head
        and len(node.statuses) == n_status
    )
    # the next sample with its header is paired normally (the lost header did not shift the
    # pairing)
    t = feed(node, array_msg(x))
    assert node.statuses[-1]['stamp_ns'] == t and node.statuses[-1]['status'] == 'ok'


def test_a_rejected_array_consumes_its_header(node):
    """
    A rejected array consumes its header.

    A sample that fails to decode takes its header with it: the next sample keeps its own stamp.
    """
    g = load_array_geometry(GEOMETRY)
    az, alt = _sun()
    x = simulate_readings(g, az, alt, [10.0])[0]
    if node.needs_tilt:
        _feed_imu(node)
    now = node.get_clock().now().nanoseconds
    feed(node, array_msg(np.ones((7, 4))), now - 10**9)  # bad layout, header stamp 1 s ago
    feed(node, array_msg(x), now)
    assert node.statuses[-1]['stamp_ns'] == now


def test_optical_header_frame_is_refused(node):
    g = load_array_geometry(GEOMETRY)
    az, alt = _sun()
    x = simulate_readings(g, az, alt, [10.0])[0]
    n_status = len(node.statuses)
    before = dict(node.diag.rejected).get('array_header_optical_frame', 0)
    feed(node, array_msg(x), frame_id='compass_optical_frame')
    assert (
        dict(node.diag.rejected)['array_header_optical_frame'] == before + 1
        and len(node.statuses) == n_status
    )


def test_arrival_stamping_without_a_header(ctx):
    """
    Arrival stamping without a header.

    array_stamp arrival: no header topic, each sample stamped with the node's clock when it
    arrives.
    """
    from polarization_compass.nodes.array_heading_estimator import ArrayHeadingEstimatorNode

    n = ArrayHeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('array_geometry', value=GEOMETRY),
            Parameter('array_stamp', value='arrival'),
            Parameter('time_source', value='parameter'),
            Parameter('time_utc', value=TIME),
            Parameter('prior_source', value='none'),
        ],
    )
    try:
        assert n.pairer is None
        assert '/compass_array/header' not in {sub.topic_name for sub in n.subscriptions}
        n.statuses = []
        n._publish_status = n.statuses.append
        g = load_array_geometry(GEOMETRY)
        az, alt = _sun()
        t0 = n.get_clock().now().nanoseconds
        n._on_array(array_msg(simulate_readings(g, az, alt, [30.0])[0]))
        t1 = n.get_clock().now().nanoseconds
        st = n.statuses[-1]
        assert st['status'] == 'ok' and t0 <= st['stamp_ns'] <= t1
    finally:
        n.destroy_node()


def _short():
    m = Float32MultiArray()
    m.data = [1.0] * 31
    return m


def test_dark_sample_is_a_status(node):
    if node.needs_tilt:
        _feed_imu(node)
    feed(node, array_msg(np.zeros((8, 4))))
    st = node.statuses[-1]
    assert st['ok'] is False and st['status'] == 'too_few_units' and not st['published']


def test_array_node_needs_a_geometry_and_a_unit_method(ctx):
    from polarization_compass.nodes.array_heading_estimator import ArrayHeadingEstimatorNode

    with pytest.raises(CompassError, match='array_geometry'):
        ArrayHeadingEstimatorNode(context=ctx)
    with pytest.raises(CompassError, match='needs an image'):
        ArrayHeadingEstimatorNode(
            context=ctx,
            parameter_overrides=[
                Parameter('method', value='zenith'),
                Parameter('array_geometry', value=GEOMETRY),
            ],
        )


def test_sim_graph_with_an_array():
    from polarization_compass import graphs
    from polarization_compass.specs import topics

    g = graphs.build('sim', {'methods': 'least_squares', 'array_geometry': GEOMETRY})
    assert not g.check()
    sim = g.node('sky_simulator')
    assert sim.parameters['array_geometry'] == GEOMETRY
    assert ('/' + topics.ARRAY, topics.T_FLOAT32_MULTIARRAY) in sim.resolved_publishes()
    arr = [n for n in g.nodes if n.namespace == 'array']
    assert sorted(n.parameters['method'] for n in arr) == ['least_squares', 'tilt_aware']
    for n in arr:
        assert n.executable == 'array_heading_estimator'
        subs = dict(n.resolved_subscribes())
        assert (
            '/' + topics.ARRAY in subs and '/imu/data' in subs and '/camera/image_raw' not in subs
        )
        assert dict(n.resolved_publishes())[
            '/array/compass/%s/heading_raw' % n.parameters['method']
        ]
    assert any(
        e.startswith('compass_array/intensities=heading_estimator_array_least_squares')
        for e in sim.parameters['wait_for_downstream']
    )
    plain = graphs.build('sim', {'methods': 'least_squares'})
    assert not any(n.namespace == 'array' for n in plain.nodes)
    assert ('/' + topics.ARRAY, topics.T_FLOAT32_MULTIARRAY) not in plain.node(
        'sky_simulator'
    ).resolved_publishes()


def test_simulator_publishes_the_array(ctx):
    """
    sky_simulator with array_geometry publishes one array message per frame.

    sky_simulator with array_geometry: one Float32MultiArray per frame that the estimator decodes
    back.
    """
    from polarization_compass.nodes.sky_simulator import SkySimulatorNode
    from polarization_compass.photodiode.readings import array_sample_from_flat

    sim = SkySimulatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('array_geometry', value=GEOMETRY),
            Parameter('clock_mode', value='system'),
        ],
    )
    try:
        img, _, _, _ = sim._render_frame(sim.start_ns, 1, np.eye(3))
        msg = img[1]
        assert isinstance(msg, Float32MultiArray) and [d.size for d in msg.layout.dim] == [8, 4]
        x = array_sample_from_flat(msg.data, [8, 4], 0, load_array_geometry(GEOMETRY))
        assert np.all(x > 0)
    finally:
        sim.destroy_node()


def test_array_knobs_are_node_parameters(ctx):
    from polarization_compass.nodes.array_heading_estimator import ArrayHeadingEstimatorNode

    n = ArrayHeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('array_geometry', value=GEOMETRY),
            Parameter('time_source', value='parameter'),
            Parameter('time_utc', value=TIME),
            Parameter('prior_source', value='none'),
            Parameter('knob.min_units', value=4),
        ],
    )
    try:
        n.statuses = []
        n._publish_status = n.statuses.append
        assert n.array.knobs['min_units'] == 4 and n.has_parameter('knob.max_misfit_deg')
        assert not n.has_parameter('knob.stride')  # an image knob: not for an array
        g = load_array_geometry(GEOMETRY)
        az, alt = _sun()
        x = simulate_readings(g, az, alt, [30.0])[0]
        feed(n, array_msg(x))
        assert n.statuses[-1]['status'] == 'ok'
        res = n.set_parameters(
            [Parameter('knob.min_units', value=7)]
        )  # more than the 6 enabled units
        assert res[0].successful and n.array.knobs['min_units'] == 7
        feed(n, array_msg(x))
        assert n.statuses[-1]['status'] == 'too_few_units'
        res = n.set_parameters_atomically(
            [
                Parameter('knob.min_sun_altitude_deg', value=9.0),
                Parameter('knob.max_sun_altitude_deg', value=5.0),
            ]
        )
        assert (
            not res.successful and 'min_sun_altitude_deg' in res.reason
        )  # refused, the old estimator stays
        assert n.array.knobs['min_units'] == 7
    finally:
        n.destroy_node()


@pytest.mark.ros
@pytest.mark.slow
def test_dds_heading_carries_the_simulated_header_stamp(ros_env, tmp_path):
    """
    A heading on DDS carries the simulated header's stamp.

    sky_simulator and an array_heading_estimator as processes on DDS (loopback): every published
    heading has the stamp and frame_id of the std_msgs/Header the simulator published for its
    sample, on the simulator's frame grid (start + k / rate), and the estimator drops nothing.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from polarization_compass.specs import topics as T
    from sensor_msgs.msg import Imu
    from std_msgs.msg import String
    from test_nodes_helpers import node_env, Proc, Recorder, SMALL_SCENE, stamp

    scene = tmp_path / 'small.yaml'
    scene.write_text(SMALL_SCENE)
    env = node_env(ros_env)
    logs = tmp_path / 'logs'
    t = T.method_topics('least_squares')
    est = Proc(
        'heading_estimator_array',
        'array_heading_estimator',
        [
            '-p',
            'method:=least_squares',
            '-p',
            f'array_geometry:={GEOMETRY}',
            '-p',
            'prior_source:=none',
            '-p',
            'use_sim_time:=true',
            '-p',
            'array_qos:=reliable',
        ],
        env,
        logs,
    )
    rec = Recorder(int(env['ROS_DOMAIN_ID']))
    rate_hz, start_ns = (
        5.0,
        1_573_797_600_000_000_000,
    )  # 2019-11-15T06:00:00Z, the simulator's default
    sim = None
    try:
        rec.sub(Header, T.ARRAY_HEADER)
        rec.sub(Imu, t['heading_raw'])
        rec.sub(String, t['status'])
        rec.sub(DiagnosticArray, T.DIAGNOSTICS)
        sim = Proc(
            'sky_simulator',
            'sky_simulator',
            [
                '-p',
                f'scene:={scene}',
                '-p',
                f'array_geometry:={GEOMETRY}',
                '-p',
                f'rate_hz:={rate_hz}',
                '-p',
                'duration_s:=1.6',
                '-p',
                'turn_rate_deg_s:=30.0',
                '-p',
                'pitch_deg:=0.0',
                '-p',
                # the recorder reads the header, not the intensities: naming it for both made
                # the simulator wait its full 60 s for a reader that never comes
                'wait_for_downstream:=['
                "'compass_array/intensities=heading_estimator_array',"
                "'compass_array/header=heading_estimator_array,test_recorder']",
            ],
            env,
            logs,
        )
        n_frames = 8
        assert rec.spin_until(lambda: len(rec.msgs[t['status']]) >= n_frames, 240, [est]), (
            est.stderr[-2000:],
            sim.stderr[-2000:],
        )
        rec.spin_for(1.5)  # diagnostics of the last period
    finally:
        codes = [p.stop() for p in (sim, est) if p is not None]
        rec.close()
    assert codes == [0, 0], (est.stderr[-2000:], sim.stderr[-2000:] if sim else '')
    headers = {
        stamp(type('M', (), {'header': h})): h.frame_id for _, h in rec.msgs[T.ARRAY_HEADER]
    }
    grid = [start_ns + round(k * 1e9 / rate_hz) for k in range(n_frames)]
    assert sorted(headers)[:n_frames] == grid  # the simulator's frame stamps
    statuses = rec.statuses(t['status'])
    assert [s['stamp_ns'] for s in statuses][:n_frames] == grid  # one per sample, none lost
    imus = [m for _, m in rec.msgs[t['heading_raw']]]
    assert len(imus) == len(statuses) and all(s['published'] for s in statuses)
    for m in imus:
        assert stamp(m) in headers and m.header.frame_id == headers[stamp(m)] == 'base_link'
    diag = [
        s
        for _, a in rec.msgs[T.DIAGNOSTICS]
        for s in a.status
        if s.name.startswith('heading_estimator_array')
    ]
    keys = {kv.key: kv.value for kv in diag[-1].values}
    assert keys['rejected'] == '0', keys


@pytest.mark.parametrize('array_qos', ['reliable', 'sensor_data'])
def test_dds_burst_of_samples_is_not_lost(ros_env, tmp_path, array_qos):
    """
    A burst of samples that arrives while the estimator is busy is not lost.

    An array_heading_estimator process is sent 30 samples (header, then array) back to back, as a
    driver's backlog reaches a busy node: every one gets its status, with its header's stamp (the
    subscriptions' history held 5 samples and silently dropped the older ones of a burst, counted
    nowhere).
    """
    from polarization_compass.specs import topics as T
    from std_msgs.msg import String
    from test_nodes_helpers import node_env, Proc, Recorder

    env = node_env(ros_env)
    t = T.method_topics('least_squares')
    est = Proc(
        'heading_estimator_array',
        'array_heading_estimator',
        [
            *('-p', 'method:=least_squares', '-p', f'array_geometry:={GEOMETRY}'),
            *('-p', 'prior_source:=none', '-p', f'array_qos:={array_qos}'),
            *('-p', 'time_source:=parameter', '-p', f'time_utc:={TIME}'),
        ],
        env,
        tmp_path / 'logs',
    )
    rec = Recorder(int(env['ROS_DOMAIN_ID']))
    n, start_ns = 30, 1_573_797_600_000_000_000
    try:
        rec.sub(String, t['status'])
        pub_h, pub_a = rec.pub(Header, T.ARRAY_HEADER), rec.pub(Float32MultiArray, T.ARRAY)
        assert rec.spin_until(
            lambda: pub_h.get_subscription_count() and pub_a.get_subscription_count(), 60, [est]
        ), est.stderr[-2000:]
        rec.spin_for(1.0)  # the estimator's side of the match too
        g = load_array_geometry(GEOMETRY)
        az, alt = _sun()
        msg = array_msg(simulate_readings(g, az, alt, [120.0])[0])
        grid = [start_ns + k * 100_000_000 for k in range(n)]
        for s in grid:  # back to back: the burst reaches the node while it estimates the first
            pub_h.publish(Header(stamp=M.time_msg(s), frame_id='base_link'))
            pub_a.publish(msg)
        rec.spin_until(lambda: len(rec.msgs[t['status']]) >= n, 60, [est])
        rec.spin_for(0.5)  # none more
    finally:
        code = est.stop()
        rec.close()
    assert code == 0, est.stderr[-2000:]
    assert 'warm-up (kernel compilation or cache load) took' in est.stderr, est.stderr[-2000:]
    statuses = rec.statuses(t['status'])
    assert [s['stamp_ns'] for s in statuses] == grid, (len(statuses), est.stderr[-2000:])
    assert all(s['status'] == 'ok' for s in statuses)
