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
The sim graph on real DDS (loopback only), started as `make sim` does.

Started by `polarization-compass sim` (graphs/ -> console scripts with the shipped parameter
files), with a recording node in this process on the same domain.

Checks: each node's actual topics equal the graphs/ declaration; the heading's form (ENU yaw = 90
deg
- bearing, unit yaw-only quaternion, covariance layout, -1 markers, frame, stamps = image stamps);
  no
frame dropped; camera, IMU and clock streams; /diagnostics; the evaluator's report against errors
computed here from the truth of the motion profile; and the paper's effect: at pitch -20 deg the
uncorrected least-squares heading is off by degrees, the error-map correction and the tilt-aware
solve remove it. (Level-camera accuracy on DDS: test_nodes_robustness.py.)

The correctors get a coarse error map made here (yaw step 30 deg) so that the test does not wait
minutes for a fine one.
"""

import json
import math
import signal
import subprocess
import sys

import numpy as np
import pytest
from test_nodes_helpers import no_traceback, quat, Recorder, SMALL_SCENE, stamp

pytestmark = [pytest.mark.ros, pytest.mark.slow]

START_NS = 1_573_797_600_000_000_000  # 2019-11-15T06:00:00Z, the simulator's default start
RATE_DEG_S, N_FRAMES = 36.0, 10  # --turns 0.1 at 36 deg/s and 10 Hz: bearings 0, 3.6, ... 32.4


def _tiny_map(path, scene_file):
    from polarization_compass.scene_load import load_scene
    from polarization_compass.sweep import run_sweep, SweepSpec

    # the run: sun 30.6 deg, pitch -20, roll 0 (+ IMU noise): three nodes per tilt axis, 30 deg of
    # yaw
    spec = SweepSpec(
        ('least_squares',),
        np.array([25.0, 30.0, 35.0]),
        np.arange(-180.0, 180.0, 30.0),
        np.array([-25.0, -20.0, -15.0]),
        np.array([-5.0, 0.0, 5.0]),
        scene=load_scene(scene_file),
        knobs={'least_squares': {'stride': 8}},
    )
    run_sweep(spec, out=path, workers=1, progress=False)


def test_sim_graph_on_dds(ros_env, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from polarization_compass import graphs
    from polarization_compass.specs import topics as T
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import CameraInfo, Image, Imu
    from std_msgs.msg import Float64, String

    scene_file = tmp_path / 'small.yaml'
    scene_file.write_text(SMALL_SCENE)
    map_path = tmp_path / 'map.npz'
    _tiny_map(map_path, scene_file)
    out = tmp_path / 'out'
    env = dict(ros_env)
    env.pop('FASTDDS_DEFAULT_PROFILES_FILE', None)  # the command sets the shipped profile itself
    m, ta = 'least_squares', 'tilt_aware'
    tm, tt = T.method_topics(m), T.method_topics(ta)
    rec = Recorder(int(env['ROS_DOMAIN_ID']))
    # topics whose subscriber count the simulator waits for are subscribed only once it runs
    for topic, ty in (
        (T.TRUTH, Imu),
        (tm['heading_raw'], Imu),
        (tm['heading'], Imu),
        (tm['bearing_raw'], Float64),
        (tm['status'], String),
        (tm['correction_status'], String),
        (tt['heading_raw'], Imu),
        (T.CLOCK, Clock),
        (T.DIAGNOSTICS, DiagnosticArray),
        (T.EVAL_SUMMARY, String),
    ):
        rec.sub(ty, topic)
    cmd = [
        sys.executable,
        '-m',
        'polarization_compass.cli',
        'sim',
        '--methods',
        m,
        '--turns',
        '0.1',
        '--turn-rate',
        str(RATE_DEG_S),
        '--scene',
        str(scene_file),
        '--error-map',
        str(map_path),
        '--out',
        str(out),
        '--timeout',
        '240',
    ]
    proc = subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    expected = graphs.build(
        'sim',
        {'methods': m, 'lockstep': 'true', 'error_map': str(map_path), 'report_dir': str(out)},
    )  # what the command builds
    try:
        assert rec.spin_until(
            lambda: len(rec.msgs[tm['heading_raw']]) >= 1 or proc.poll() is not None, 180
        )
        assert proc.poll() is None, proc.communicate()
        for topic, ty in ((T.IMAGE, Image), (T.CAMERA_INFO, CameraInfo), (T.IMU, Imu)):
            rec.sub(ty, topic, depth=5)
        # every node's actual topics equal the graphs/ declaration (ROS built-ins aside)
        # TF is broadcast through tf2_ros where it is installed (the simulator's odom_tf), like
        # /rosout an infrastructure topic outside the graph's declared data flow
        builtin = {'/rosout', '/parameter_events', '/clock', '/tf', '/tf_static'}
        for spec in expected.nodes:
            pubs, subs = rec.node_topics(spec.name)
            want_pubs = {t: (ty,) for t, ty in spec.resolved_publishes() if t not in builtin}
            want_subs = {t: (ty,) for t, ty in spec.resolved_subscribes() if t not in builtin}
            assert {k: v for k, v in pubs.items() if k not in builtin} == want_pubs, spec.name
            assert {k: v for k, v in subs.items() if k not in builtin} == want_subs, spec.name
        assert rec.spin_until(lambda: proc.poll() is not None, 240)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)  # the command stops its nodes, then exits
        stdout, stderr = proc.communicate(timeout=90)
        rec.spin_for(0.2)
        rec.close()
    assert proc.returncode == 0, stdout[-3000:] + stderr[-3000:]
    assert no_traceback(stderr)
    for p in (out / 'logs').glob('*.log'):
        assert no_traceback(p.read_text()), p.name

    # ---------------------------------------------------------------- truth, from the motion
    # profile
    truth = rec.msgs[T.TRUTH]
    stamps = [stamp(x) for _, x in truth]
    assert len(truth) == N_FRAMES and stamps[0] == START_NS
    assert np.array_equal(
        np.diff(stamps), np.full(N_FRAMES - 1, 100_000_000)
    )  # 10 Hz, simulated time
    true_bearing = {s: (RATE_DEG_S * (s - START_NS) / 1e9) % 360.0 for s in stamps}
    for _, x in truth:
        yaw = math.degrees(2 * math.atan2(quat(x)[2], quat(x)[3]))
        assert math.remainder(yaw - (90.0 - true_bearing[stamp(x)]), 360) == pytest.approx(
            0, abs=1e-9
        )

    # ---------------------------------------------------------------- the heading's form, no drops
    raw = rec.msgs[tm['heading_raw']]
    assert [stamp(x) for _, x in raw] == stamps, 'frames dropped or reordered'
    bearings = [x.data for _, x in rec.msgs[tm['bearing_raw']]]
    assert len(bearings) == N_FRAMES
    for (_, x), b in zip(raw, bearings):
        q = quat(x)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12) and q[0] == 0.0 and q[1] == 0.0
        yaw_deg = math.degrees(2 * math.atan2(q[2], q[3]))
        assert math.remainder(yaw_deg - (90.0 - b), 360.0) == pytest.approx(
            0.0, abs=1e-9
        )  # ENU yaw = 90 - bearing
        c = np.asarray(x.orientation_covariance).reshape(3, 3)
        assert c[0, 0] == c[1, 1] == 1000.0 and 0 < c[2, 2] < math.radians(5.0) ** 2
        assert np.count_nonzero(c - np.diag(np.diag(c))) == 0
        assert (
            x.angular_velocity_covariance[0] == -1.0
            and x.linear_acceleration_covariance[0] == -1.0
        )
        assert x.header.frame_id == 'base_link'
    err = {
        k: np.array(
            [math.remainder(_bearing(x) - true_bearing[stamp(x)], 360.0) for _, x in rec.msgs[t]]
        )
        for k, t in (
            ('raw', tm['heading_raw']),
            ('corrected', tm['heading']),
            ('tilt_aware', tt['heading_raw']),
        )
    }
    assert all(v.size == N_FRAMES for v in err.values())
    # pitch -20 deg, sun ~31 deg: the uncorrected error is degrees (paper Fig 17); corrected and
    # tilt-aware are far smaller (tilt_aware's only error source: the simulated IMU's 0.05 deg
    # noise)
    assert np.max(np.abs(err['raw'])) > 1.0
    assert np.sqrt(np.mean(err['corrected'] ** 2)) < np.sqrt(np.mean(err['raw'] ** 2)) / 5
    assert np.sqrt(np.mean(err['tilt_aware'] ** 2)) < 0.1
    cst = rec.statuses(tm['correction_status'])
    assert len(cst) == N_FRAMES and all(s['status'] == 'ok' for s in cst)
    assert all(
        s['pitch_deg'] == pytest.approx(-20.0, abs=0.5) for s in cst
    )  # IMU tilt, noise 0.05
    est_st = rec.statuses(tm['status'])
    assert len(est_st) == N_FRAMES and all(s['status'] == 'ok' and s['published'] for s in est_st)

    # ---------------------------------------------------------------- camera, IMU, clock,
    # diagnostics
    images = rec.msgs[T.IMAGE]
    assert images and {stamp(x) for _, x in images} <= set(stamps)
    im = images[-1][1]
    assert (im.encoding, im.width, im.height, im.step) == ('mono16', 612, 512, 612 * 2)
    assert im.header.frame_id == 'camera_optical_frame'
    info = rec.msgs[T.CAMERA_INFO][-1][1]
    assert info.k[0] == pytest.approx(4.0 / 13.8e-3) and info.k[2] == pytest.approx(305.5)
    imu_stamps = np.array(sorted(stamp(x) for _, x in rec.msgs[T.IMU]))
    assert imu_stamps.size and np.all((imu_stamps - START_NS) % 20_000_000 == 0)  # 50 Hz grid
    clock = [int(x.clock.sec) * 1_000_000_000 + int(x.clock.nanosec) for _, x in rec.msgs[T.CLOCK]]
    assert clock and np.all(np.diff(clock) >= 0) and clock[-1] >= stamps[-1]
    names = {s.name.split(':')[0] for _, arr in rec.msgs[T.DIAGNOSTICS] for s in arr.status}
    assert {n.name for n in expected.nodes} <= names
    est_diag = [
        s
        for _, arr in rec.msgs[T.DIAGNOSTICS]
        for s in arr.status
        if s.name.startswith('heading_estimator_least_squares')
    ][-1]
    keys = {kv.key: kv.value for kv in est_diag.values}
    assert {'rate_hz', 'processing_ms_p95', 'stamp_age_ms_p95', 'rejected', 'last_status'} <= set(
        keys
    )
    assert keys['rejected'] == '0'

    # ---------------------------------------------------------------- the command's table and
    # report
    assert any(
        line.startswith('least_squares') and ' corrected ' in line for line in stdout.splitlines()
    )
    s = json.loads((out / 'evaluation_summary.json').read_text())
    assert s['truth_frames'] == N_FRAMES
    for name, e in (
        ('least_squares/raw', err['raw']),
        ('least_squares/corrected', err['corrected']),
        ('tilt_aware/raw', err['tilt_aware']),
    ):
        d = s['streams'][name]
        assert d['count'] == N_FRAMES and d['missed'] == 0 and d['not_published'] == {}, (
            name,
            d,
            s['nodes'],
        )
        assert d['rms'] == pytest.approx(math.sqrt(np.mean(e**2)), abs=1e-6)
        assert d['max'] == pytest.approx(np.max(np.abs(e)), abs=1e-6)
    for f in ('evaluation_samples.csv', 'evaluation_summary.csv', 'evaluation.png'):
        assert (out / f).is_file()
    assert json.loads(rec.msgs[T.EVAL_SUMMARY][-1][1].data)['truth_frames'] >= 1
    wall = np.array([t for t, _ in raw])
    print(
        f'\nsim graph: raw max {np.max(np.abs(err["raw"])):.2f} deg, corrected rms '
        f'{np.sqrt(np.mean(err["corrected"] ** 2)):.3f}, tilt-aware rms '
        f'{np.sqrt(np.mean(err["tilt_aware"] ** 2)):.3f}; '
        f'{(len(wall) - 1) / max(wall[-1] - wall[0], 1e-9):.1f} headings/s wall (lockstep)'
    )


def _bearing(imu_msg) -> float:
    q = quat(imu_msg)
    return (90.0 - math.degrees(2 * math.atan2(q[2], q[3]))) % 360.0
