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
Clean stop of every node (issue 15), without ros2 launch.

SIGINT and SIGTERM, once or repeatedly, while data flows, end each node with exit 0, no traceback,
no abort; the evaluator keeps a current report on disk while it runs and replaces it atomically.

The same stops under the real ``ros2 launch`` (process group, launch's own SIGINT, its SIGTERM
escalation) are in test_ros2_launch.py, which needs the launch packages.
"""

from __future__ import annotations

import json
import math
import signal
import time

from polarization_compass.nodes import msgs as M
import pytest
from test_nodes_helpers import node_env, Proc, SMALL_SCENE, zenith_evaluator

T0 = 1_700_000_000_000_000_000
FAILURE_MARKS = (
    'Traceback',
    'terminate called',
    'pybind11',
    'context is invalid',
    'FATAL',
    'Segmentation',
)


def _heading(t_ns, bearing):
    return M.heading_imu(t_ns, 'base_link', math.radians(90.0 - bearing), 1e-4, 1000.0)


# ------------------------------------------------------------------------------------------------
# the evaluator's report while it runs
# ------------------------------------------------------------------------------------------------
@pytest.fixture
def evaluator(ctx, tmp_path):
    node = zenith_evaluator(ctx, tmp_path)
    yield node
    node.destroy_node()


def _feed(node, k0, k1, error_deg):
    for k in range(k0, k1):
        t = T0 + k * 100_000_000
        node._on_truth(_heading(t, 10.0 * k))
        node._on_estimate('zenith/raw', _heading(t, 10.0 * k + error_deg))


def test_evaluator_keeps_a_current_report_and_replaces_it_atomically(
    evaluator, tmp_path, monkeypatch
):
    from polarization_compass.nodes import error_evaluator as E

    monkeypatch.setattr(E, 'FIGURE_PERIOD_S', 0.0)
    _feed(evaluator, 0, 4, 2.0)
    evaluator.write_current_report()
    s = json.loads((tmp_path / 'evaluation_summary.json').read_text())
    assert s['complete'] is False and s['truth_frames'] == 4
    assert s['streams']['zenith/raw']['count'] == 4
    assert s['streams']['zenith/raw']['rms'] == pytest.approx(
        2.0, abs=1e-6
    )  # every error is +2 deg
    rows = (tmp_path / 'evaluation_samples.csv').read_text().strip().splitlines()
    assert len(rows) == 1 + 4
    assert (tmp_path / 'evaluation.png').stat().st_size > 0
    png_before = (tmp_path / 'evaluation.png').read_bytes()

    # a failing figure leaves the previous one in place and no temporary file behind
    def broken(path, *a, **k):
        path.write_bytes(b'half a png')
        raise OSError('disk full')

    monkeypatch.setattr(E, 'plot_report', broken)
    _feed(evaluator, 4, 6, -1.0)
    evaluator.write_current_report()  # logged, not raised
    assert (tmp_path / 'evaluation.png').read_bytes() == png_before
    assert (
        json.loads((tmp_path / 'evaluation_summary.json').read_text())['truth_frames'] == 6
    )  # written before
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'evaluation.png',
        'evaluation_samples.csv',
        'evaluation_summary.csv',
        'evaluation_summary.json',
    ]
    monkeypatch.undo()

    evaluator.close()  # the final report: complete, 6 frames
    s = json.loads((tmp_path / 'evaluation_summary.json').read_text())
    assert s['complete'] is True and s['truth_frames'] == 6
    assert s['streams']['zenith/raw']['rms'] == pytest.approx(
        math.sqrt((4 * 4.0 + 2 * 1.0) / 6), abs=1e-6
    )
    assert not [p for p in tmp_path.iterdir() if 'partial' in p.name]


def test_evaluator_writes_no_current_report_without_new_estimates(evaluator, tmp_path):
    evaluator.write_current_report()
    assert not list(tmp_path.iterdir())
    _feed(evaluator, 0, 2, 0.5)
    evaluator.write_current_report()
    first = (tmp_path / 'evaluation_summary.json').stat().st_mtime_ns
    time.sleep(0.01)
    evaluator.write_current_report()  # nothing new: not rewritten
    assert (tmp_path / 'evaluation_summary.json').stat().st_mtime_ns == first


# ------------------------------------------------------------------------------------------------
# signals to running nodes while images flow (DDS on loopback)
# ------------------------------------------------------------------------------------------------
def _wait_for(pred, timeout, what):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if pred():
            return
        time.sleep(0.2)
    raise AssertionError(f'timed out waiting for {what}')


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize(
    'signals',
    [
        (signal.SIGINT, signal.SIGINT, signal.SIGINT),
        (signal.SIGTERM, signal.SIGINT, signal.SIGTERM),
    ],
    ids=['3xSIGINT', 'SIGTERM+SIGINT+SIGTERM'],
)
def test_nodes_stop_with_exit_0_on_repeated_signals_while_data_flows(ros_env, tmp_path, signals):
    scene = tmp_path / 'small.yaml'
    scene.write_text(SMALL_SCENE)
    env = node_env(ros_env)
    report = tmp_path / 'report'
    logs = tmp_path / 'logs'
    sim_args = [
        '-p',
        f'scene:={scene}',
        '-p',
        'clock_mode:=sim',
        '-p',
        'rate_hz:=10.0',
        '-p',
        'turns:=0.0',
        '-p',
        'wait_for_subscribers:=1',
        '-p',
        'wait_for_imu_subscribers:=1',
        '-p',
        'exit_when_done:=false',
    ]
    procs = [
        Proc(
            'heading_estimator_tilt_aware',
            'heading_estimator',
            ['-p', 'method:=tilt_aware', '-p', 'site_source:=parameters'],
            env,
            logs,
        ),
        Proc(
            'error_evaluator',
            'error_evaluator',
            [
                '-p',
                "methods:=['tilt_aware']",
                '-p',
                "direct_methods:=['tilt_aware']",
                '-p',
                f'report_dir:={report}',
            ],
            env,
            logs,
        ),
        Proc('sky_simulator', 'sky_simulator', sim_args, env, logs),
    ]
    try:
        # frames flow through the estimator to the evaluator: its current report counts them
        summary = report / 'evaluation_summary.json'
        _wait_for(
            lambda: summary.is_file() and json.loads(summary.read_text())['truth_frames'] >= 10,
            150,
            'a current report with 10 frames',
        )
        assert all(p.alive() for p in procs)
        for s in signals:
            for p in procs:
                p.p.send_signal(s)
            time.sleep(0.05)
        codes = {p.name: p.wait(timeout=20) for p in procs}
    finally:
        for p in procs:
            if p.alive():
                p.stop(timeout=5)
    assert codes == {p.name: 0 for p in procs}, {p.name: p.stderr[-800:] for p in procs}
    for p in procs:
        out = p.stdout + p.stderr
        assert not [m for m in FAILURE_MARKS if m in out], (p.name, out[-1500:])
        assert 'stopping (SIG' in out, (p.name, out[-800:])
    s = json.loads(summary.read_text())
    assert s['complete'] is True and s['truth_frames'] >= 10
    assert s['streams']['tilt_aware/raw']['count'] >= 8


# ------------------------------------------------------------------------------------------------
# the signal handlers themselves (in this process; pytest's own handlers are put back)
# ------------------------------------------------------------------------------------------------
@pytest.fixture
def own_handlers():
    import os

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield os.getpid()
    for s, h in saved.items():
        signal.signal(s, h)


def test_stop_signals_record_and_never_raise_while_spinning(own_handlers):
    import os

    from polarization_compass.nodes.runner import StopSignals

    stop = StopSignals().install()
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGINT):
        os.kill(own_handlers, s)
        time.sleep(0.01)  # the handler runs at the next bytecode boundary
    assert stop.requested and stop.received == [signal.SIGINT, signal.SIGTERM, signal.SIGINT]
    assert stop.names() == 'SIGINT+SIGTERM+SIGINT'


def test_stop_signals_interrupt_a_start_up_once(own_handlers):
    import os

    from polarization_compass.nodes.runner import StopSignals

    stop = StopSignals().install()
    stop.interrupt_now = True  # the node is being built (warm-up)
    with pytest.raises(KeyboardInterrupt):
        os.kill(own_handlers, signal.SIGTERM)
        time.sleep(1.0)
    os.kill(own_handlers, signal.SIGINT)  # while that interrupt unwinds: recorded only
    time.sleep(0.01)
    assert stop.received == [signal.SIGTERM, signal.SIGINT]


def test_a_start_up_interrupt_inside_a_c_callback_prints_no_traceback(own_handlers, monkeypatch):
    """
    A start-up interrupt that lands in a ctypes callback is recorded, and not reported.

    numba's compilation calls back into Python from C (llvmlite's object cache); an exception
    raised there cannot propagate, and Python handed it to ``sys.unraisablehook``, whose default
    printed "Exception ignored ... Traceback" (one Ctrl-C during a sim graph's cold start). A real
    ctypes callback here; the hook that was there before records what reaches it. Any other
    unraisable exception still reaches it.
    """
    import ctypes
    import os
    import sys

    from polarization_compass.nodes.runner import StopSignals

    reported = []
    monkeypatch.setattr(sys, 'unraisablehook', lambda info: reported.append(info.exc_type))
    before = sys.unraisablehook
    stop = StopSignals().install()
    stop.interrupt_now = True

    @ctypes.CFUNCTYPE(None)
    def interrupted():
        os.kill(own_handlers, signal.SIGINT)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:  # the handler raises at a bytecode boundary in here
            pass

    @ctypes.CFUNCTYPE(None)
    def failing():
        raise ValueError('not ours')

    try:
        interrupted()  # through libffi: Python -> C -> the Python callback
        failing()
    finally:
        stop.restore()
    assert stop.received == [signal.SIGINT]
    assert reported == [ValueError]
    assert sys.unraisablehook is before


def test_a_start_up_that_fails_of_its_interrupt_ends_as_a_stop(own_handlers, capsys):
    """
    A node whose start-up fails because a stop signal interrupted it exits 0, no traceback.

    The interrupt lands in a C callback of numba's compiler (recorded, not raised there) and the
    compilation then fails with a RuntimeError ("no compiled object yet", seen in a tilt_corrector
    stopped during a sim graph's cold start: exit 1 with a traceback). Here the same sequence in a
    real ctypes callback, through :func:`run_node` in this process.
    """
    import ctypes
    import os

    from polarization_compass.nodes.runner import run_node

    @ctypes.CFUNCTYPE(None)
    def interrupted():
        os.kill(own_handlers, signal.SIGINT)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:
            pass

    def factory():
        interrupted()
        raise RuntimeError('no compiled object yet for <Library>')

    capsys.readouterr()
    assert run_node(factory, 'test_node', argv=['test_node'], exit_process=False) == 0
    err = capsys.readouterr().err
    assert 'Traceback' not in err and 'error' not in err, err


def test_a_start_up_that_goes_on_after_a_stop_ends_the_process(ros_env, tmp_path):
    """
    A start-up that does not end after a stop signal ends the process within the deadline, exit 0.

    numba's compiler runs in C, where the start-up interrupt cannot reach Python, and it loses the
    interrupt inside its C callbacks: one Ctrl-C during a sim graph's cold start left an estimator
    compiling past ros2 launch's SIGTERM, killed 45 s later (SIGKILL). Here a factory that swallows
    the interrupt and goes on for 60 s, in a process of its own.
    """
    import subprocess
    import sys

    from polarization_compass.nodes.runner import START_UP_DEADLINE_S

    script = tmp_path / 'slow_start.py'
    script.write_text(
        'import time\n'
        'from polarization_compass.nodes.runner import run_node\n'
        'def factory():\n'
        "    print('building', flush=True)\n"
        '    t0 = time.monotonic()\n'
        '    while time.monotonic() - t0 < 60.0:\n'
        '        try:\n'
        '            time.sleep(0.05)\n'
        '        except KeyboardInterrupt:\n'
        '            pass  # lost, as inside a C callback: the compilation goes on\n'
        "run_node(factory, 'slow_start')\n"
    )
    p = subprocess.Popen(
        [sys.executable, str(script)],
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert p.stdout.readline().strip() == 'building'
        time.sleep(0.5)  # into its loop: a signal before the try would simply stop it
        t0 = time.monotonic()
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=60)
        took = time.monotonic() - t0
    finally:
        p.kill()
    assert p.returncode == 0, err
    assert START_UP_DEADLINE_S - 0.5 <= took < START_UP_DEADLINE_S + 10.0, took
    assert 'slow_start: stopped during start-up (SIGINT)' in out, out
    assert 'Traceback' not in err, err
