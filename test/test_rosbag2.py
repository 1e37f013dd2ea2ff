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
Field runs through the real rosbag2 (issue 27): ``ros2 bag info / play / record``.

Needs the ``ros2 bag`` command (a ROS install; here ../shared/ros-cpp, installed into the venv's
``opt/ros-cpp``, whose ``setup.bash`` this module sources when the environment has not) and the
launch packages (../shared/ros-launch); skipped otherwise with the reason, and then NOT coverage.

* ``record-sim`` bags pass ``ros2 bag info``: storage, topics, types and counts as recorded.
* ``ros2 launch polarization_compass replay.launch.py bag:=BAG`` starts the real player (paused,
  resumed once every node is ready), ends by itself after the bag, every process cleanly, with the
  evaluator's complete report; the player at 2x, flow-controlled at every frame (``high_water:=1``:
  ``player_flow`` pauses it while an estimator is behind), scores every frame the offline
  ``polarization-compass replay`` scores, with its error (to the 1e-6 deg of the evaluator's CSV),
  none lost on the way (``not_received`` 0), and the frames the estimator declined are the offline
  replay's, with the same statuses.
* The same with the camera at 10 Hz, the IMU at 100 Hz and the player at 1x, paused for 3 s half a
  second after the launch resumed it and resumed again (the player's services).
* The two-terminal way: a player started by hand (``--start-paused``) before the launch is resumed
  by it once the graph is ready and scores like the offline replay; Ctrl-C ends the launch with the
  final report.
* A ``ros2 bag record`` of the live sim graph (camera, IMU, reference, fix) is read by the offline
  replay: every recorded image is scored, with the sim evaluator's own errors.

Every process runs on loopback discovery with a domain id of its own and the package's
shared-memory Fast DDS profile (every local participant discovers every other through it).
"""

from __future__ import annotations

import collections
import csv
import json
import os
from pathlib import Path
import re
import shutil
import signal
import subprocess
import sys
import time

from colcon_ws import colcon_install, sourced_env
import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
ROS_CPP_SETUP = Path(
    os.environ.get('ROS_CPP_SETUP', BIN.parent / 'opt' / 'ros-cpp' / 'setup.bash')
)


def _skip_reason() -> str | None:
    try:
        import launch  # noqa: F401
        import launch_ros  # noqa: F401
        import ros2cli  # noqa: F401
    except ImportError:
        return (
            'the ROS 2 launch packages and the ros2 command are not installed (here: '
            '../shared/ros-launch/install.sh .venv)'
        )
    if shutil.which('ros2', path=f'{BIN}:{os.environ.get("PATH", "")}') is None:
        return 'no ros2 command'
    try:
        import ros2bag  # noqa: F401

        return None
    except ImportError:
        pass
    if not ROS_CPP_SETUP.is_file():
        return (
            'rosbag2 (ros2 bag) is not installed: no ros2bag module and no '
            f'{ROS_CPP_SETUP} (here: ../shared/ros-cpp/install.sh .venv)'
        )
    return None


_REASON = _skip_reason()
if _REASON:
    pytest.skip(f'rosbag2 tests SKIPPED: {_REASON}', allow_module_level=True)

pytestmark = [pytest.mark.launch, pytest.mark.ros, pytest.mark.slow, pytest.mark.colcon]

# the small camera of test_replay_live (a 2448 x 2048 sensor binned 25.5 x): a frame costs
# milliseconds, so the player's 1x and 2x are kept up with on a loaded machine
WIDTH_PX, HEIGHT_PX = 192, 160
METHODS = ('least_squares', 'tilt_aware')
DURATION_S = 3.0
RATE_HZ = 10.0
PLAYER_RATE = 2.0  # the player's --rate: twice real time, flow-controlled (player_flow)


@pytest.fixture(scope='module')
def ws(tmp_path_factory, ros_domains):
    """Build a colcon install space of this package; an environment with rosbag2 and it sourced."""
    ws = tmp_path_factory.mktemp('ws')
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    env['PATH'] = f'{BIN}:{env.get("PATH", "")}'
    try:
        import ros2bag  # noqa: F401
    except ImportError:
        env = sourced_env(ROS_CPP_SETUP, env)
    colcon_install(ws, env)
    env = sourced_env(ws / 'install' / 'setup.bash', env)
    env['PATH'] = f'{BIN}:{env["PATH"]}'
    # the launch file and the executables come from the install space, the modules from this tree:
    # numba caches the kernels by source path, and a fresh install space recompiles them in every
    # node (145 s per estimator measured on this loaded 2-core machine)
    env['PYTHONPATH'] = f'{ROOT}:{env.get("PYTHONPATH", "")}'
    env['ROS_DOMAIN_ID'] = str(ros_domains())  # this module's own (conftest)
    env['ROS_LOG_DIR'] = str(ws / 'ros_log')
    env['NUMBA_NUM_THREADS'] = '1'
    share = ws / 'install' / 'polarization_compass' / 'share' / 'polarization_compass'
    # every process of these tests on the shared-memory profile (the launch sets it for its own)
    env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(share / 'config' / 'fastdds_large_images.xml')
    r = subprocess.run(
        ['ros2', 'bag', 'info', '--help'], env=env, capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 0, r.stderr
    return {'env': env, 'share': share, 'dir': ws}


def _record_small(d: Path, imu_rate_hz: float = 50.0):
    from polarization_compass.camera import CameraModel
    from polarization_compass.recording import record_sim, RecordSpec
    from polarization_compass.scene_load import load_scene

    camera = CameraModel(
        width_px=WIDTH_PX,
        height_px=HEIGHT_PX,
        focal_length_mm=4.0,
        pixel_pitch_x_um=2448 * 3.45 / WIDTH_PX,
        pixel_pitch_y_um=2048 * 3.45 / HEIGHT_PX,
    )
    scene = load_scene(None).replace(camera=camera)
    spec = RecordSpec(duration_s=DURATION_S, rate_hz=RATE_HZ, turns=0.25, imu_rate_hz=imu_rate_hz)
    return d / 'run', record_sim(scene, spec, d / 'run')


@pytest.fixture(scope='module')
def small_bag(tmp_path_factory):
    """Record a bag of 3 s at 10 Hz from the small camera; return it and what record_sim wrote."""
    return _record_small(tmp_path_factory.mktemp('bag'))


def _bag_counts(path: Path) -> dict:
    """Return the messages per topic and their types, read with rosbags (not with rosbag2)."""
    from rosbags.rosbag2 import Reader

    out = collections.Counter()
    types = {}
    with Reader(path) as r:
        for conn, _, _ in r.messages():
            out[conn.topic] += 1
            types[conn.topic] = conn.msgtype
    return {t: (types[t], n) for t, n in out.items()}


def test_record_sim_bag_passes_ros2_bag_info(ws, small_bag):
    path, info = small_bag
    r = subprocess.run(
        ['ros2', 'bag', 'info', str(path)],
        env=ws['env'],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert re.search(r'Storage id:\s+mcap', r.stdout), r.stdout
    shown = {
        m['topic']: (m['type'], int(m['count']))
        for m in re.finditer(
            r'Topic: (?P<topic>\S+) \| Type: (?P<type>\S+) \| Count: (?P<count>\d+)', r.stdout
        )
    }
    assert shown == _bag_counts(path)
    n_images = round(DURATION_S * RATE_HZ)
    assert shown['/camera/image_raw'] == ('sensor_msgs/msg/Image', n_images)
    assert shown['/ground_truth/heading'] == ('sensor_msgs/msg/Imu', n_images)
    assert int(re.search(r'Messages:\s+(\d+)', r.stdout).group(1)) == sum(
        n for _, n in shown.values()
    )


def _offline(bag: Path):
    from polarization_compass.replay import default_error_map, replay_bag, ReplayConfig

    return replay_bag(bag, ReplayConfig(methods=METHODS, error_map=default_error_map()))


def _ns(text: str) -> int:
    """Return a stamp of evaluation_samples.csv (float seconds, 9 decimals) to the microsecond."""
    sec, _, frac = text.partition('.')
    ns = int(sec) * 1_000_000_000 + int(frac.ljust(9, '0')[:9])
    return (ns + 500) // 1000 * 1000


def _start_launch(ws, log: Path, *args) -> subprocess.Popen:
    """Start ``ros2 launch polarization_compass replay.launch.py ARGS``, output into ``log``."""
    with open(log, 'w') as f:
        return subprocess.Popen(
            ['ros2', 'launch', 'polarization_compass', 'replay.launch.py', *args],
            env=ws['env'],
            stdout=f,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


def _run_launch(ws, tmp_path, *args, timeout=420):
    log = tmp_path / 'launch.log'
    p = _start_launch(ws, log, *args)
    try:
        rc = p.wait(timeout=timeout)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    return rc, log.read_text(errors='replace')


def _live_errors(report: Path) -> dict:
    with open(report / 'evaluation_samples.csv') as f:
        return {
            (row['stream'], _ns(row['stamp_s'])): float(row['error_deg'])
            for row in csv.DictReader(f)
        }


def _offline_errors(offline) -> dict:
    out = {}
    for r in offline.rows:
        if r.raw_error_deg is not None:
            out[(f'{r.method}/raw', r.stamp_ns)] = r.raw_error_deg
        if r.corrected_error_deg is not None:
            out[(f'{r.method}/corrected', r.stamp_ns)] = r.corrected_error_deg
    return out


def _offline_declined(offline) -> dict:
    """Return ``{method: {status: frames}}`` of the frames the offline replay did not publish."""
    out = {m: collections.Counter() for m in METHODS}
    for r in offline.rows:
        if r.status != 'ok':
            out[r.method][r.status] += 1
    return {m: dict(c) for m, c in out.items()}


def test_launch_with_the_real_player_scores_the_bag_like_the_offline_replay(
    ws, small_bag, tmp_path
):
    bag, info = small_bag
    offline = _offline(bag)
    want = _offline_errors(offline)
    n_images = round(DURATION_S * RATE_HZ)
    # the comparison has substance: most frames scored offline in each stream
    for stream in ('least_squares/raw', 'least_squares/corrected', 'tilt_aware/raw'):
        assert sum(1 for s, _ in want if s == stream) >= n_images - 3, stream
    report = tmp_path / 'report'
    rc, text = _run_launch(
        ws,
        tmp_path,
        f'bag:={bag}',
        'methods:=least_squares',
        'tilt_aware:=true',
        f'report_dir:={report}',
        f'rate:={PLAYER_RATE}',
        'drain_s:=3.0',
        'high_water:=1',  # flow control at every frame: the player pauses while one is behind
        'low_water:=0',
    )
    _check_live_run(rc, text, report, want, _offline_declined(offline), n_images)
    assert 'player paused' in text, text[-4000:]


def _check_live_run(rc, text, report, want, declined, n_images) -> dict:
    """Check a replay.launch.py run against the offline replay's errors; return its summary."""
    assert rc == 0, text[-4000:]
    assert 'all 4 nodes ready' in text and 'the bag has played' in text, text[-4000:]
    started = set(re.findall(r'\[INFO\] \[([\w-]+)\]: process started', text))
    clean = set(re.findall(r'\[INFO\] \[([\w-]+)\]: process has finished cleanly', text))
    # 4 nodes, player_flow, the player, resume
    assert clean == started and len(started) == 7, text[-4000:]
    return _check_report(report, want, declined, n_images)


def _check_report(report, want, declined, n_images) -> dict:
    """Check a live replay's final report against the offline replay's errors; return it."""
    s = json.loads((report / 'evaluation_summary.json').read_text())
    assert s['complete'] is True and s['truth_frames'] == n_images
    live = _live_errors(report)
    # every frame the live graph scored is a frame the offline replay scored, with its error
    assert set(live) <= set(want), sorted(set(live) - set(want))
    worst = max(abs(live[k] - want[k]) for k in live)
    assert worst < 2e-6, worst  # the CSV keeps 6 decimals
    # every truth frame is accounted for: scored or missed, the estimator's reasons among them
    for stream, d in s['streams'].items():
        assert d['count'] + d['missed'] == n_images, (stream, d)
        assert sum(d['not_published'].values()) <= d['missed'], (stream, d)
        assert d['count'] == sum(1 for k in live if k[0] == stream)
    # every frame the offline replay scored is scored (images queue behind a slower estimator,
    # image_qos replay), nothing was lost on the way, and the estimator declined the frames the
    # offline replay declined, for the same reasons
    assert set(live) == set(want), sorted(set(want) ^ set(live))
    for stream, d in s['streams'].items():
        assert d['not_received'] == 0, (stream, d)
        if stream.endswith('/raw'):
            assert d['not_published'] == declined[stream.split('/')[0]], (stream, d)
    return s


#: Waits until the launch has resumed the player, pauses it after 0.5 s of play, checks that it is
#: paused and resumes it after argv[1] s (the player's rosbag2_interfaces services).
PAUSE_SCRIPT = """
import sys
import time
import rclpy
from rosbag2_interfaces.srv import IsPaused, Pause, Resume
rclpy.init()
node = rclpy.create_node('test_pause_player')
clients = {}
for srv, name in ((IsPaused, 'is_paused'), (Pause, 'pause'), (Resume, 'resume')):
    clients[name] = node.create_client(srv, '/rosbag2_player/' + name)
    assert clients[name].wait_for_service(timeout_sec=300.0), name


def call(srv, name):
    future = clients[name].call_async(srv.Request())
    rclpy.spin_until_future_complete(node, future, timeout_sec=30.0)
    return future.result()


t0 = time.monotonic()
while call(IsPaused, 'is_paused').paused and time.monotonic() - t0 < 300.0:
    time.sleep(0.05)
time.sleep(0.5)
call(Pause, 'pause')
paused = call(IsPaused, 'is_paused').paused
time.sleep(float(sys.argv[1]))
call(Resume, 'resume')
print('paused:', paused, flush=True)
node.destroy_node()
rclpy.shutdown()
"""


def test_a_paused_and_resumed_player_with_a_100_hz_imu_scores_like_the_offline_replay(
    ws, tmp_path
):
    """Camera at 10 Hz, IMU at 100 Hz, the player at 1x paused for 3 s mid-bag, then resumed."""
    bag, _ = _record_small(tmp_path, imu_rate_hz=100.0)
    assert _bag_counts(bag)['/imu/data'][1] > 90 * DURATION_S  # twice the default 50 Hz
    offline = _offline(bag)
    want = _offline_errors(offline)
    report = tmp_path / 'report'
    log = tmp_path / 'launch.log'
    p = _start_launch(
        ws,
        log,
        f'bag:={bag}',
        'methods:=least_squares',
        'tilt_aware:=true',
        f'report_dir:={report}',
        'rate:=1.0',
        'drain_s:=3.0',
    )
    try:
        r = subprocess.run(
            [sys.executable, '-c', PAUSE_SCRIPT, '3.0'],
            env=ws['env'],
            capture_output=True,
            text=True,
            timeout=420,
        )
        assert r.returncode == 0 and 'paused: True' in r.stdout, r.stdout + r.stderr
        rc = p.wait(timeout=300)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    _check_live_run(
        rc,
        log.read_text(errors='replace'),
        report,
        want,
        _offline_declined(offline),
        round(DURATION_S * RATE_HZ),
    )


def _wait_for_report(report: Path, n_images: int, timeout_s: float) -> None:
    """Wait until every stream of the evaluator's current report accounts for every frame."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        try:
            streams = json.loads((report / 'evaluation_summary.json').read_text())['streams']
        except (OSError, ValueError, KeyError):
            streams = {}
        if streams and all(d['count'] + d['missed'] >= n_images for d in streams.values()):
            if all(d['missed'] == sum(d['not_published'].values()) for d in streams.values()):
                return
        time.sleep(1.0)


def test_a_player_started_by_hand_before_the_graph_is_resumed_once_it_is_ready(
    ws, small_bag, tmp_path
):
    """Two terminals: ``ros2 bag play BAG --clock --start-paused`` first, the launch next."""
    bag, _ = small_bag
    offline = _offline(bag)
    n_images = round(DURATION_S * RATE_HZ)
    report = tmp_path / 'report'
    player = subprocess.Popen(
        [
            'ros2',
            'bag',
            'play',
            str(bag),
            '--clock',
            '--start-paused',
            '--disable-keyboard-controls',
        ],
        env=ws['env'],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    log = tmp_path / 'launch.log'
    launch = _start_launch(
        ws, log, 'methods:=least_squares', 'tilt_aware:=true', f'report_dir:={report}'
    )
    try:
        assert player.wait(timeout=420) == 0  # resumed by the launch, played to the end
        _wait_for_report(report, n_images, timeout_s=60.0)
        os.killpg(launch.pid, signal.SIGINT)  # Ctrl-C: the evaluator writes its final report
        rc = launch.wait(timeout=60)
    finally:
        for proc in (player, launch):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    text = log.read_text(errors='replace')
    assert rc == 0 and 'all 4 nodes ready' in text and 'player resumed' in text, text[-4000:]
    _check_report(report, _offline_errors(offline), _offline_declined(offline), n_images)


def test_ros2_bag_record_of_the_live_sim_graph_is_scored_offline_like_the_sim(ws, tmp_path):
    """
    Record the sim graph's camera, IMU, reference and fix with ros2 bag record; replay it offline.

    The small fisheye scene (budget_small.yaml, 160 x 160), 18 frames of a 10 deg/s turn: every
    recorded image is scored offline, with the sim evaluator's own errors for its frames.
    """
    from polarization_compass.replay import default_error_map, replay_bag, ReplayConfig

    env = ws['env']
    out = tmp_path / 'rec'
    rec_log = open(tmp_path / 'record.log', 'w')
    recorder = subprocess.Popen(
        [
            'ros2',
            'bag',
            'record',
            '-s',
            'mcap',
            '-o',
            str(out),
            '--topics',
            '/camera/image_raw',
            '/camera/camera_info',
            '/imu/data',
            '/ground_truth/heading',
            '/gps/fix',
        ],
        env=env,
        stdout=rec_log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    report = tmp_path / 'report'
    log = tmp_path / 'launch.log'
    try:
        with open(log, 'w') as f:
            sim = subprocess.run(
                [
                    'ros2',
                    'launch',
                    'polarization_compass',
                    'sim.launch.py',
                    f'scene:={ROOT / "config" / "scenes" / "budget_small.yaml"}',
                    'turns:=0.05',
                    'turn_rate_deg_s:=10.0',
                    'methods:=least_squares',
                    'tilt_aware:=false',
                    f'report_dir:={report}',
                ],
                env=env,
                stdout=f,
                stderr=subprocess.STDOUT,
                timeout=420,
            )
        assert sim.returncode == 0, log.read_text(errors='replace')[-3000:]
    finally:
        os.killpg(recorder.pid, signal.SIGINT)  # Ctrl-C closes the bag
        try:
            recorder.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(recorder.pid, signal.SIGKILL)
            recorder.wait()
        rec_log.close()
    assert recorder.returncode == 0, (tmp_path / 'record.log').read_text()[-2000:]
    sim_errors = _live_errors(report)
    frames = json.loads((report / 'evaluation_summary.json').read_text())['truth_frames']
    assert frames == 18 and len(sim_errors) == 2 * frames
    counts = _bag_counts(out)
    n_images = counts['/camera/image_raw'][1]
    assert counts['/camera/image_raw'][0] == 'sensor_msgs/msg/Image'
    assert n_images >= frames - 2, counts  # the recorder subscribes once it sees the publishers
    offline = replay_bag(
        out, ReplayConfig(methods=('least_squares',), error_map=default_error_map())
    )
    want = _offline_errors(offline)
    assert len(want) == 2 * n_images  # every recorded image scored, raw and corrected
    assert set(want) <= set(sim_errors)
    worst = max(abs(want[k] - sim_errors[k]) for k in want)
    assert worst < 2e-6, worst
