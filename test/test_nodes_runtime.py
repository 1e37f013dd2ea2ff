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
Nodes built in-process: site from NavSatFix and run-time parameter changes.

Nodes built in-process (a private rclpy context, callbacks called directly as in
test_hard_cases_nodes.py): the corrector's site from NavSatFix, and parameters changed at run time
either take effect or are refused as read-only.

Independent facts: the sun from a direct ephemeris call (solar.sun_position) for the fix's site,
the error map's own formula, the parameter's meaning (history kept, horizon, period = 1 / rate).
"""

import math
import time

import numpy as np
from polarization_compass.conventions import CameraAttitude
from polarization_compass.nodes import msgs as M
import pytest
from rclpy.parameter import Parameter

T0 = 1_573_797_600_000_000_000  # 2019-11-15T06:00:00Z
NANJING = (32.026778, 118.853306, 30.0)  # the parameter defaults
TOKYO = (35.68, 139.69, 40.0)  # sun ~16 deg high at T0 (Nanjing: ~31 deg)
K_ALT = 0.1  # the test map: e(psi, h) = K_ALT * h + sin(psi) deg, any tilt
SMALL_SCENE = """\
name: tiny
camera: {model: pinhole, width_px: 48, height_px: 40, focal_length_mm: 4.0,
         pixel_pitch_x_um: 176.0, pixel_pitch_y_um: 176.0}
"""


def sun(site, t_ns):
    """(azimuth, altitude) deg from the ephemeris directly (not the nodes' SunSource/SunCache)."""
    from polarization_compass.solar import sun_position

    p = sun_position(np.datetime64(t_ns // 1000, 'us'), *site)
    return float(p.azimuth_deg), float(p.altitude_deg)


def body_quat(bearing, pitch, roll):
    from polarization_compass.conventions import body_quat_from_camera_attitude

    return body_quat_from_camera_attitude(CameraAttitude(bearing, pitch, roll))


def imu_msg(t_ns, q):
    from sensor_msgs.msg import Imu

    m = Imu()
    m.header.stamp = M.time_msg(t_ns)
    m.header.frame_id = 'base_link'
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (float(v) for v in q)
    m.orientation_covariance = [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1.0]
    return m


def heading_msg(t_ns, bearing):
    return M.heading_imu(t_ns, 'base_link', math.radians(90.0 - bearing), 1e-4, 1000.0)


class _Sink:
    """A publisher stand-in that keeps the messages."""

    def __init__(self):
        self.msgs = []

    def publish(self, m):
        self.msgs.append(m)


def _capture(node):
    """Statuses and published headings of a corrector, without DDS."""
    node.statuses = []
    node._status = node.statuses.append
    node.pub_heading = _Sink()
    node.pub_bearing = _Sink()
    return node


@pytest.fixture(scope='module')
def sloped_map(tmp_path_factory):
    """
    Return an error map depending on the sun's altitude and psi.

    Linear in altitude, so interpolated exactly.
    """
    from polarization_compass.errormap import ErrorMap

    alt, yaw, tilt = (
        np.arange(0.0, 55.0, 10.0),
        np.arange(-180.0, 180.0, 10.0),
        np.arange(-30.0, 31.0, 10.0),
    )
    e = K_ALT * alt[:, None] + np.sin(np.radians(yaw))[None, :]
    err = np.broadcast_to(
        e[None, :, :, None, None], (1, alt.size, yaw.size, tilt.size, tilt.size)
    ).copy()
    path = tmp_path_factory.mktemp('map') / 'sloped_map.npz'
    ErrorMap(
        err,
        np.zeros(err.shape, np.int8),
        ('least_squares',),
        alt,
        yaw,
        tilt,
        tilt,
        meta={'domain': {'tilt_limit_deg': 30.0}},
    ).save(path)
    return path


def _corrector(ctx, **params):
    from polarization_compass.nodes.tilt_corrector import TiltCorrectorNode

    over = [Parameter('imu_max_wait_s', value=0.0)] + [
        Parameter(k, value=v) for k, v in params.items()
    ]
    return _capture(TiltCorrectorNode(context=ctx, parameter_overrides=over))


def _feed(node, t_ns, raw_bearing, pitch=-10.0, roll=5.0):
    node._on_imu(imu_msg(t_ns, body_quat(raw_bearing, pitch, roll)))
    node._on_heading(heading_msg(t_ns, raw_bearing))
    return node.statuses[-1]


# --------------------------------------------------------------------------------------------
# tilt_corrector: the site from NavSatFix (site_source navsatfix), as heading_estimator and replay
# --------------------------------------------------------------------------------------------
def test_corrector_takes_the_site_from_navsatfix(ctx, sloped_map):
    from polarization_compass.correction import TiltCorrector

    node = _corrector(ctx, error_map=str(sloped_map), site_source='navsatfix')
    try:
        # before any fix: an explicit status, nothing published, counted
        st = _feed(node, T0, 100.0)
        assert (
            st['status'] == 'no_fix' and st['published'] is False and 'NavSatFix' in st['reason']
        )
        assert node.pub_heading.msgs == [] and node.pub_bearing.msgs == []
        assert node.counts['no_fix'] == 1 and node.diag.extra['no_fix'] == 1

        node._on_fix(M.navsatfix_msg(*TOKYO, T0, 'gps'))
        t = T0 + 1_000_000_000
        st = _feed(node, t, 100.0)
        assert st['status'] == 'ok' and st['published'], st
        az, alt = sun(TOKYO, t)
        assert st['sun_altitude_deg'] == pytest.approx(alt, abs=1e-4)
        assert st['sun_azimuth_deg'] == pytest.approx(az, abs=1e-4)
        ref = TiltCorrector.from_file(sloped_map, 'least_squares')
        want, c = ref.correct_bearing(100.0, az, alt, -10.0, 5.0)
        assert c.ok and abs(math.remainder(st['bearing_deg'] - want, 360.0)) < 1e-3
        assert abs(math.remainder(node.pub_bearing.msgs[-1].data - want, 360.0)) < 1e-3
        # the map's own formula: psi + K h + sin(psi) = psi_meas (cubic yaw interpolation of sin: <
        # 1e-3 deg)
        psi, psi_meas = st['bearing_deg'] - az, 100.0 - az
        assert (
            abs(math.remainder(psi + K_ALT * alt + math.sin(math.radians(psi)) - psi_meas, 360.0))
            < 1e-2
        )
        # and it is not the parameters' (Nanjing) correction: the sun is 15 deg higher there
        nj, _ = ref.correct_bearing(100.0, *sun(NANJING, t), -10.0, 5.0)
        assert abs(math.remainder(nj - want, 360.0)) > 1.0

        # a site parameter changed at run time does not replace the fix's site
        assert node.set_parameters([Parameter('latitude_deg', value=0.0)])[0].successful
        t2 = T0 + 2_000_000_000
        st = _feed(node, t2, 250.0)
        assert st['sun_altitude_deg'] == pytest.approx(sun(TOKYO, t2)[1], abs=1e-4)
        # a fix nobody can use is counted and the last good site stays
        bad = M.navsatfix_msg(*NANJING, t2, 'gps')
        bad.status.status = -1
        node._on_fix(bad)
        assert node.diag.rejected['fix_no_fix'] == 1
        st = _feed(node, t2 + 100_000_000, 250.0)
        assert st['sun_altitude_deg'] == pytest.approx(sun(TOKYO, t2 + 100_000_000)[1], abs=1e-4)
        # site_source is fixed at start (the fix subscription depends on it)
        assert not node.set_parameters([Parameter('site_source', value='parameters')])[
            0
        ].successful
    finally:
        node.destroy_node()


def test_corrector_with_site_parameters_ignores_fixes_and_needs_none(ctx, sloped_map):
    node = _corrector(ctx, error_map=str(sloped_map))
    try:
        st = _feed(node, T0, 100.0)  # no fix ever: the parameters' site
        assert st['status'] == 'ok' and st['sun_altitude_deg'] == pytest.approx(
            sun(NANJING, T0)[1], abs=1e-4
        )
        assert '/gps/fix' not in {s.topic_name for s in node.subscriptions}
    finally:
        node.destroy_node()


# --------------------------------------------------------------------------------------------
# run-time parameters that take effect
# --------------------------------------------------------------------------------------------
def test_corrector_imu_buffer_s_applies_at_run_time(ctx):
    node = _corrector(ctx, correction='none')
    try:
        q = body_quat(30.0, -10.0, 0.0)
        for k in range(21):  # 0 .. 2 s at 10 Hz
            node._on_imu(imu_msg(T0 + k * 100_000_000, q))
        node._on_heading(heading_msg(T0 + 500_000_000, 30.0))
        assert node.statuses[-1]['status'] == 'ok'  # 10 s of history: 1.5 s back is there
        res = node.set_parameters([Parameter('imu_buffer_s', value=0.5)])
        assert res[0].successful, res[0].reason
        node._on_imu(imu_msg(T0 + 2_100_000_000, q))  # the next sample trims to 0.5 s behind it
        assert len(node.imu) == 6  # 1.6 .. 2.1 s
        node._on_heading(heading_msg(T0 + 1_000_000_000, 30.0))
        node._drain()
        assert (
            node.statuses[-1]['status'] == 'stale_imu' and node.statuses[-1]['published'] is False
        )
        node._on_heading(heading_msg(T0 + 1_700_000_000, 30.0))
        assert node.statuses[-1]['status'] == 'ok'
    finally:
        node.destroy_node()


@pytest.fixture
def evaluator(ctx, tmp_path):
    from polarization_compass.nodes.error_evaluator import ErrorEvaluatorNode

    node = ErrorEvaluatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('report_dir', value=str(tmp_path)),
            Parameter('methods', value=['least_squares']),
            Parameter('direct_methods', value=['']),
        ],
    )
    yield node
    node.destroy_node()


def _truth(t_ns, bearing=30.0):
    return heading_msg(t_ns, bearing)


def test_evaluator_horizon_s_applies_at_run_time(evaluator):
    streams = evaluator.matcher.streams
    evaluator._on_truth(_truth(T0))
    evaluator._on_truth(_truth(T0 + 1_000_000_000))
    assert all(s.missed == 0 for s in streams.values())  # 5 s horizon: frame T0 still waits
    res = evaluator.set_parameters([Parameter('horizon_s', value=0.5)])
    assert res[0].successful, res[0].reason
    evaluator._on_truth(_truth(T0 + 1_100_000_000))
    # frames T0 (1.1 s old) and T0 + 1 s (0.1 s old): only the first is past a 0.5 s horizon
    assert {n: s.missed for n, s in streams.items()} == {
        'least_squares/raw': 1,
        'least_squares/corrected': 1,
    }
    evaluator._on_estimate('least_squares/raw', heading_msg(T0 + 1_000_000_000, 30.5))
    assert streams['least_squares/raw'].matched == 1  # still inside: matched


def test_evaluator_summary_rate_hz_applies_at_run_time(ctx, evaluator):
    from rclpy.executors import SingleThreadedExecutor

    calls = []
    evaluator.pub_summary = _Sink()
    evaluator.pub_summary.publish = lambda m: calls.append(time.monotonic())
    res = evaluator.set_parameters([Parameter('summary_rate_hz', value=10.0)])
    assert res[0].successful, res[0].reason
    assert evaluator.summary_timer.timer_period_ns == 100_000_000
    assert evaluator.diag._timer.timer_period_ns == 100_000_000  # /diagnostics at the same rate
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(evaluator)
    try:
        end = time.monotonic() + 1.5
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.remove_node(evaluator)
        ex.shutdown()
    assert len(calls) >= 8, calls  # 1 Hz would give at most 2 in 1.5 s


def _status_msg(status, published):
    import json

    from std_msgs.msg import String

    return String(data=json.dumps({'status': status, 'published': published}))


def test_evaluator_separates_declined_frames_from_frames_lost_on_the_way(evaluator):
    """not_received = missed - not_published (the estimator's reasons count for corrected too)."""
    for k in range(6):
        evaluator._on_truth(_truth(T0 + k * 100_000_000))
    evaluator._on_estimate('least_squares/raw', heading_msg(T0, 30.2))
    evaluator._on_estimate('least_squares/corrected', heading_msg(T0, 30.1))
    # frame 1: declined by the estimator (so the corrector never saw it); frame 2: declined by
    # the corrector; frames 3-5: no status, no estimate (lost in transport)
    evaluator._on_status('least_squares/raw', _status_msg('ambiguous', False))
    evaluator._on_estimate('least_squares/raw', heading_msg(T0 + 200_000_000, 30.2))
    evaluator._on_status('least_squares/raw', _status_msg('ok', True))
    evaluator._on_status('least_squares/corrected', _status_msg('no_solution', False))
    s = evaluator.summary()['streams']
    raw, cor = s['least_squares/raw'], s['least_squares/corrected']
    assert (raw['count'], raw['missed'], raw['not_published']) == (2, 4, {'ambiguous': 1})
    assert raw['not_received'] == 3
    assert (cor['count'], cor['missed'], cor['not_published']) == (1, 5, {'no_solution': 1})
    assert cor['not_received'] == 3
    evaluator.publish_summary()
    assert evaluator.diag.extra['least_squares/corrected.not_received'] == 3
    # never negative: a declined frame whose truth never came is not among the missed
    for _ in range(5):
        evaluator._on_status('least_squares/raw', _status_msg('bad_input', False))
    assert evaluator.summary()['streams']['least_squares/raw']['not_received'] == 0


def test_evaluator_reads_the_players_best_effort_clock(ctx, tmp_path):
    """ros2 bag play --clock publishes /clock best effort: a reliable reader would get nothing."""
    from polarization_compass.nodes.error_evaluator import ErrorEvaluatorNode
    from rclpy.qos import ReliabilityPolicy

    node = ErrorEvaluatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('report_dir', value=str(tmp_path)),
            Parameter('methods', value=['least_squares']),
            Parameter('direct_methods', value=['']),
            Parameter('latency_source', value='clock'),
            Parameter('use_sim_time', value=True),
        ],
    )
    try:
        own = [
            sub
            for sub in node.subscriptions
            if sub.topic_name == '/clock' and sub.callback == node._on_clock
        ]
        assert len(own) == 1
        assert own[0].qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
    finally:
        node.destroy_node()


# --------------------------------------------------------------------------------------------
# sky_simulator: run-time changes that would break a running camera are refused; time_scale applies
# --------------------------------------------------------------------------------------------
def fake_wall_clock(monkeypatch, start: float):
    """
    Replace the simulator modules' ``time`` with a fake monotonic clock.

    Its monotonic() is ``wall[0]`` (returned: the caller advances it); perf_counter and time_ns
    stay real. The node's module and its scheduler's (``sky_simulator_clock``) both read it.
    """
    from polarization_compass.nodes import sky_simulator as S
    from polarization_compass.nodes import sky_simulator_clock as C

    wall = [start]

    class FakeTime:
        """The ``time`` module with a monotonic clock the test sets."""

        @staticmethod
        def monotonic():
            return wall[0]

        perf_counter = staticmethod(time.perf_counter)
        time_ns = staticmethod(time.time_ns)

    monkeypatch.setattr(S, 'time', FakeTime)
    monkeypatch.setattr(C, 'time', FakeTime)
    return wall


@pytest.fixture
def simulator(ctx, tmp_path):
    from polarization_compass.nodes.sky_simulator import SkySimulatorNode

    scene = tmp_path / 'tiny.yaml'
    scene.write_text(SMALL_SCENE)
    node = SkySimulatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('scene', value=str(scene)),
            Parameter('encoding', value='32FC1'),
            Parameter('wait_settle_s', value=0.0),
            Parameter('turns', value=0.0),
        ],
    )
    yield node
    node.destroy_node()


@pytest.mark.parametrize(
    'name, value', [('rate_hz', 5.0), ('imu_rate_hz', 100.0), ('turns', 2.0), ('duration_s', 30.0)]
)
def test_simulator_rate_and_length_are_read_only(simulator, name, value):
    before = simulator.params[name]
    res = simulator.set_parameters([Parameter(name, value=value)])
    assert res[0].successful is False and 'read-only' in res[0].reason and name in res[0].reason
    assert simulator.describe_parameter(name).read_only
    assert simulator.params[name] == before and simulator.get_parameter(name).value == before


def test_simulator_time_scale_change_continues_simulated_time(simulator, monkeypatch):
    """
    A time_scale change continues the simulated time without a jump.

    A new time_scale applies from the moment of the change: simulated time neither jumps nor
    stalls.
    """
    wall = fake_wall_clock(monkeypatch, 1000.0)
    clock = []
    simulator._publish_clock = lambda t_ns, force=False: clock.append(
        t_ns
    )  # every value, unthrottled
    simulator.t_wait0 = wall[0]

    def tick(dt):
        wall[0] += dt
        simulator._tick_sim()
        return clock[-1]

    tick(0.0)  # primes (camera_info, fix, first IMU)
    tick(0.0)  # starts: base = (start, now)
    step = 1 / 64  # ~ the /clock timer's period, binary exact
    for _ in range(128):  # 2 s of wall at time_scale 1
        c = tick(step)
    assert c == simulator.start_ns + 2_000_000_000 and simulator.frames == 21
    res = simulator.set_parameters([Parameter('time_scale', value=3.0)])
    assert res[0].successful, res[0].reason
    assert tick(0.0) == c  # no jump at the change
    for k in range(1, 17):  # then 3 simulated s per wall s
        assert tick(step) == c + k * 46_875_000
    assert (
        simulator.frames == 28 and simulator.late_frames == 0
    )  # frames at 2.1 .. 2.7 s, none late


def test_simulator_sends_clock_at_clock_rate_not_per_message(simulator, monkeypatch):
    """
    The simulator sends /clock at clock_rate_hz, not per message.

    /clock reaches every node of the graph, so the simulator sends it at clock_rate_hz (wall)
    however many frames and IMU samples it publishes per tick, plus once before anything else; the
    data keep their own rates (10 Hz frames, 50 Hz IMU in simulated time).
    """
    wall = fake_wall_clock(monkeypatch, 1000.0)
    sent = []  # (wall s, clock ns) of every /clock message
    simulator.pub_clock.publish = lambda msg: sent.append(
        (wall[0], msg.clock.sec * 10**9 + msg.clock.nanosec)
    )
    simulator.t_wait0 = wall[0]
    rate = simulator.params['clock_rate_hz']
    assert rate == 20.0  # the shipped default
    simulator._tick_sim()  # primes: the first stamp goes out at once
    assert sent == [(1000.0, simulator.start_ns)]
    step = 1 / 128  # scheduler ticks, faster than the clock rate
    for _ in range(256):  # 2 s of wall at time_scale 1
        wall[0] += step
        simulator._tick_sim()
    gaps = np.diff([w for w, _ in sent])
    assert gaps.min() >= 1.0 / rate - 1e-9  # never faster than clock_rate_hz
    assert gaps.max() <= 1.0 / rate + step + 1e-9  # ... and at the first tick once due
    assert int(2.0 / (1.0 / rate + step)) <= len(sent) - 1 <= 2.0 * rate
    assert all(b >= a for (_, a), (_, b) in zip(sent, sent[1:]))  # simulated time never goes back
    assert (
        simulator.frames == 20 and simulator.imu_samples >= 100
    )  # data at their own rates meanwhile


def _run_sim_ticks(node, monkeypatch, seconds, step=1 / 64):
    """Drive the simulator's scheduler on a fake wall clock; returns the images it published."""
    wall = fake_wall_clock(monkeypatch, 2000.0)
    images = []
    node.pub_image.publish = images.append
    node.t_wait0 = wall[0]
    node._tick_sim()
    for _ in range(int(round(seconds / step))):
        wall[0] += step
        node._tick_sim()
    return images


def test_frames_rendered_ahead_equal_frames_rendered_on_time(ctx, tmp_path, monkeypatch):
    """
    Frames rendered ahead equal frames rendered on time.

    The built-in motion's next frame is rendered half a period early; what goes out (stamp, pixels,
    noise) is what rendering at the frame's time gives.
    """
    from polarization_compass.nodes.sky_simulator import SkySimulatorNode

    scene = tmp_path / 'noisy.yaml'
    scene.write_text(SMALL_SCENE)
    nodes = []
    for ahead in (True, False):
        node = SkySimulatorNode(
            context=ctx,
            parameter_overrides=[
                Parameter('scene', value=str(scene)),
                Parameter('encoding', value='mono16'),
                Parameter('wait_settle_s', value=0.0),
                Parameter('turns', value=0.0),
                Parameter('pitch_deg', value=-12.0),
            ],
        )
        if not ahead:
            monkeypatch.setattr(node, '_prepare_next_frame', lambda now: None)
        nodes.append((node, _run_sim_ticks(node, monkeypatch, 1.0)))
    (a, imgs_a), (b, imgs_b) = nodes
    assert a.frames_ahead >= 8 and b.frames_ahead == 0  # the first frame is never ahead
    assert len(imgs_a) == len(imgs_b) == 10
    for x, y in zip(imgs_a, imgs_b):
        assert (x.header.stamp.sec, x.header.stamp.nanosec) == (
            y.header.stamp.sec,
            y.header.stamp.nanosec,
        )
        assert x.encoding == y.encoding == 'mono16' and bytes(x.data) == bytes(y.data)
    assert len({bytes(x.data) for x in imgs_a}) == 10  # frames do differ (motion, noise)
    for node, _ in nodes:
        node.destroy_node()
