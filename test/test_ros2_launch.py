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
The launch files under the real ``ros2 launch`` from a colcon install space (issue 15).

Needs the ROS 2 launch packages and the ``ros2`` command (a ROS install; here
``../shared/ros-launch/install.sh .venv``, which ``.ci/run`` does); skipped otherwise, and then NOT
coverage: ``make test`` says so. The launch_testing file test_launch_files.py (run by
``launch_test``) checks that the three graphs start from the install space and that the sim graph
runs to its end in lockstep (its default) with exit 0 and a complete report; this module drives
``ros2 launch`` from outside, as a user does: --show-args, a bad argument, one and two Ctrl-C to
the process group while frames flow (plus launch's SIGTERM escalation: SIGTERM to every node), the
live compass launch with a full-resolution camera, and ``ros2 param set`` of a bad value.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

from colcon_ws import colcon_install, sourced_env
import pytest

try:
    import launch  # noqa: F401
    import launch_ros  # noqa: F401
    import ros2cli  # noqa: F401
except ImportError:
    pytest.skip(
        'the ROS 2 launch packages and the ros2 command are not installed (a ROS install has '
        'them; '
        'here: ../shared/ros-launch/install.sh .venv)',
        allow_module_level=True,
    )

# after the importorskip / skip above, hence E402 (not at the top) and I100 (after pytest)
from polarization_compass.graphs import ARGUMENTS  # noqa: E402, I100

pytestmark = [pytest.mark.launch, pytest.mark.ros, pytest.mark.slow, pytest.mark.colcon]
ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
FAILURE_MARKS = (
    'Traceback',
    'terminate called',
    'pybind11',
    'context is invalid',
    'FATAL',
    'escalating',
    'process has died',
    'Segmentation',
)


@pytest.fixture(scope='module')
def ws(tmp_path_factory, ros_domains):
    """Build a colcon install space of this package and an environment that has sourced it."""
    ws = tmp_path_factory.mktemp('ws')
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    colcon_install(ws, env)
    env = sourced_env(ws / 'install' / 'setup.bash', env)
    env['PATH'] = f'{BIN}:{env["PATH"]}'
    env['ROS_DOMAIN_ID'] = str(ros_domains())  # this module's own (conftest)
    env['ROS_LOG_DIR'] = str(ws / 'ros_log')
    env.pop('FASTDDS_DEFAULT_PROFILES_FILE', None)
    prefix = subprocess.run(
        ['ros2', 'pkg', 'prefix', 'polarization_compass'],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    ).stdout.strip()
    assert Path(prefix) == ws / 'install' / 'polarization_compass', (
        prefix
    )  # the install space, not the tree
    return {'env': env, 'share': Path(prefix) / 'share' / 'polarization_compass', 'dir': ws}


def _launch(ws, *args, log: Path):
    with open(log, 'w') as f:  # the child keeps its own descriptor
        return subprocess.Popen(
            ['ros2', 'launch', 'polarization_compass', *args],
            env=ws['env'],
            stdout=f,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


def _wait_for(log: Path, pattern: str, proc, timeout: float) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if re.search(pattern, log.read_text(errors='replace')):
            return
        if proc.poll() is not None:
            break
        time.sleep(0.2)
    raise AssertionError(
        f'no {pattern!r} in the launch output: {log.read_text(errors="replace")[-3000:]}'
    )


def _finished_cleanly(text: str) -> tuple[set, set]:
    started = set(re.findall(r'\[INFO\] \[([\w-]+)\]: process started', text))
    clean = set(re.findall(r'\[INFO\] \[([\w-]+)\]: process has finished cleanly', text))
    return started, clean


@pytest.mark.parametrize('name', ['sim', 'compass', 'replay'])
def test_show_args_lists_every_argument_with_its_default(ws, name):
    r = subprocess.run(
        ['ros2', 'launch', 'polarization_compass', f'{name}.launch.py', '--show-args'],
        env=ws['env'],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    for a in ARGUMENTS[name]:
        assert re.search(
            rf"'{a.name}':\n.*\n\s+\(default: '{re.escape(a.default)}'\)", r.stdout
        ), a.name
    assert "'large_image_transport'" in r.stdout


def test_a_bad_argument_is_one_clear_error_and_starts_nothing(ws):
    r = subprocess.run(
        ['ros2', 'launch', 'polarization_compass', 'sim.launch.py', 'turns:=banana'],
        env=ws['env'],
        capture_output=True,
        text=True,
        timeout=120,
    )
    out = r.stdout + r.stderr
    assert r.returncode != 0
    errors = [line for line in out.splitlines() if '[ERROR]' in line]
    assert (
        len(errors) == 1 and "launch argument turns: cannot read 'banana' as float" in errors[0]
    ), out
    assert 'Traceback' not in out and 'process started' not in out


@pytest.mark.parametrize('twice', [False, True], ids=['one-sigint', 'two-sigints-and-sigterm'])
def test_ctrl_c_while_frames_flow_ends_every_process_with_exit_0_and_keeps_the_report(
    ws, tmp_path, twice
):
    log = tmp_path / 'launch.log'
    report = tmp_path / 'report'
    # once: simulator, zenith estimator and corrector, evaluator; twice: tilt_aware too
    p = _launch(
        ws,
        'sim.launch.py',
        'methods:=zenith',
        f'tilt_aware:={str(twice).lower()}',
        'turns:=0',
        f'report_dir:={report}',
        log=log,
    )
    try:
        _wait_for(log, r'\[sky_simulator\]: frame 25\b', p, timeout=240)
        os.killpg(p.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
        if twice:
            time.sleep(0.1)
            os.killpg(p.pid, signal.SIGINT)
            time.sleep(0.1)
            import psutil

            for child in psutil.Process(p.pid).children(
                recursive=True
            ):  # launch's escalation, early
                child.send_signal(signal.SIGTERM)
        rc = p.wait(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    text = log.read_text(errors='replace')
    assert rc == 0, text[-3000:]
    started, clean = _finished_cleanly(text)
    assert len(started) == (5 if twice else 4) and clean == started, text[-3000:]
    assert not [m for m in FAILURE_MARKS if m in text], text[-3000:]
    s = json.loads((report / 'evaluation_summary.json').read_text())
    # frames still in flight at the stop may not reach the evaluator; what did is in the report
    assert s['complete'] is True and s['truth_frames'] >= 15
    streams = ['zenith/raw', 'zenith/corrected'] + (['tilt_aware/raw'] if twice else [])
    for stream in streams:
        assert s['truth_frames'] - 3 <= s['streams'][stream]['count'] <= s['truth_frames'], (
            stream,
            s,
        )
    rows = (report / 'evaluation_samples.csv').read_text().strip().splitlines()
    assert len(rows) - 1 == sum(d['count'] for d in s['streams'].values())


def test_live_compass_launch_gets_full_resolution_headings_and_refuses_a_bad_parameter(
    ws, tmp_path
):
    """
    compass.launch.py live: full-resolution headings, a bad parameter refused.

    compass.launch.py with defaults; the sky_simulator as the camera (2448x2048 mono16), started as
    a driver is, with the documented FASTDDS_DEFAULT_PROFILES_FILE: every image gives a heading.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Imu
    from std_msgs.msg import String

    log = tmp_path / 'launch.log'
    p = _launch(ws, 'compass.launch.py', 'method:=tilt_aware', 'site_source:=parameters', log=log)
    cam_env = dict(
        ws['env'],
        FASTDDS_DEFAULT_PROFILES_FILE=str(ws['share'] / 'config' / 'fastdds_large_images.xml'),
    )
    cam = None
    ctx = Context()
    rclpy.init(context=ctx, domain_id=int(ws['env']['ROS_DOMAIN_ID']))
    node = rclpy.create_node('launch_test_counter', context=ctx)
    statuses = []
    node.create_subscription(
        String, '/compass/tilt_aware/status', lambda m: statuses.append(json.loads(m.data)), 50
    )
    node.create_subscription(
        Imu, '/ground_truth/heading', lambda m: None, 50
    )  # the camera waits for a reader
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    stack = contextlib.ExitStack()
    try:
        _wait_for(log, r'method tilt_aware', p, timeout=180)
        # ros2 param set of a bad value is refused, the node keeps the old one (range [0, 10] s)
        r = _ros2_param(ws, 'set', '-5.0')
        assert 'Setting parameter failed' in r.stdout + r.stderr, r.stdout + r.stderr
        r = _ros2_param(ws, 'get')
        assert '-5.0' not in r.stdout and re.search(r'value is: \d', r.stdout), r.stdout + r.stderr
        # 10 frames at 2 Hz (0.1 turn at 7.2 deg/s = 5 s simulated)
        cam_log = stack.enter_context(open(tmp_path / 'cam.log', 'w'))
        cam_params = (
            'rate_hz:=2.0',
            'turns:=0.1',
            'turn_rate_deg_s:=7.2',
            'wait_for_subscribers:=1',
            'wait_for_imu_subscribers:=1',
            'exit_when_done:=true',
        )
        cam = subprocess.Popen(
            [
                'ros2',
                'run',
                'polarization_compass',
                'sky_simulator',
                '--ros-args',
                *[a for v in cam_params for a in ('-p', v)],
            ],
            env=cam_env,
            stdout=cam_log,
            stderr=subprocess.STDOUT,
        )
        t0 = time.monotonic()
        while cam.poll() is None and time.monotonic() - t0 < 180:
            ex.spin_once(timeout_sec=0.1)
        t1 = time.monotonic()
        while len(statuses) < 10 and time.monotonic() - t1 < 10:
            ex.spin_once(timeout_sec=0.1)
        assert cam.wait(timeout=30) == 0, (tmp_path / 'cam.log').read_text()[-2000:]
        assert 'run complete: 10 frames' in (tmp_path / 'cam.log').read_text()
        assert len(statuses) == 10, statuses
        assert all(s['published'] for s in statuses), statuses
        os.killpg(p.pid, signal.SIGINT)
        assert p.wait(timeout=60) == 0
    finally:
        stack.close()
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
        for q in (cam, p):
            if q is not None and q.poll() is None:
                q.kill()
                q.wait()
    text = log.read_text(errors='replace')
    started, clean = _finished_cleanly(text)
    assert len(started) == 1 and clean == started, text[-3000:]
    assert not [m for m in FAILURE_MARKS if m in text], text[-3000:]


def _ros2_param(ws, verb: str, *value):
    """
    Run ``ros2 param <verb>`` on the estimator, retried while discovery is not done.

    The daemon is not used (``--no-daemon``).
    """
    cmd = [
        'ros2',
        'param',
        verb,
        '--no-daemon',
        '--spin-time',
        '2',
        '/heading_estimator_tilt_aware',
        'imu_max_wait_s',
        *value,
    ]
    for _ in range(5):
        r = subprocess.run(cmd, env=ws['env'], capture_output=True, text=True, timeout=60)
        if 'Node not found' not in r.stdout + r.stderr:
            break
    return r
