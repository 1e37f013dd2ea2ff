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
Run a node graph as processes without ``ros2 launch``: start, watch, stop, report.

Every node of a :class:`~polarization_compass.graphs.spec.Graph` is started as its own process
(this package's console scripts, or another package's executable found through the ament index),
with DDS kept on this machine; the run waits for the simulator to finish, stops every node with
SIGINT (SIGTERM / SIGKILL for stragglers, as the launch files do) and prints the evaluator's table
(:func:`~polarization_compass.evaluation_report.format_table`). The ``sim`` command uses it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from ..errors import CompassError
from ..evaluation_report import format_table


def _child_env(out: Path) -> dict:
    from ..graphs import FASTDDS_PROFILE, share_dir

    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', '73')
    if 'FASTDDS_DEFAULT_PROFILES_FILE' not in env and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in env:
        prof = share_dir() / FASTDDS_PROFILE
        if prof.is_file():
            env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(prof)
    env['ROS_LOG_DIR'] = str(out / 'ros_log')
    env['PYTHONUNBUFFERED'] = '1'
    env.setdefault(
        'NUMBA_NUM_THREADS', '1'
    )  # many processes on few cores: no thread oversubscription
    env.setdefault('OMP_NUM_THREADS', '1')
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    return env


def foreign_executable(package: str, executable: str) -> Path | None:
    """
    Return another ROS package's node executable, found through the ament index, or None.

    Parameters
    ----------
    package : str
        ROS package (e.g. ``"robot_localization"``).
    executable : str
        Executable in the package's ``lib/<package>`` (e.g. ``"ekf_node"``).

    Returns
    -------
    pathlib.Path or None
        The executable, or None when the package or the file is not there (nothing sourced).

    """
    try:
        from ament_index_python.packages import get_package_prefix, PackageNotFoundError
    except ImportError:
        return None
    try:
        prefix = get_package_prefix(package)
    except (PackageNotFoundError, LookupError, ValueError, OSError):  # OSError: nothing sourced
        return None
    exe = Path(prefix) / 'lib' / package / executable
    return exe if exe.is_file() and os.access(exe, os.X_OK) else None


def _node_command(n) -> list[str]:
    """Return the argv prefix of graph node ``n`` (this package's scripts, or the ament index)."""
    from .. import graphs

    if n.package == graphs.PACKAGE:
        return graphs.node_command(n.executable)
    exe = foreign_executable(n.package, n.executable)
    if exe is None:
        raise CompassError(f'{n.package} {n.executable} is not found through the ament index')
    return [str(exe)]


def _sigterm_as_interrupt(signum, frame):
    raise KeyboardInterrupt


def _run_graph(graph, out: Path, env: dict, args) -> int:
    from ..graphs import share_dir

    # SIGTERM (a test runner, a supervisor) stops the nodes like Ctrl-C does: never orphan them
    previous = signal.signal(signal.SIGTERM, _sigterm_as_interrupt)
    try:
        return _run_graph_inner(graph, out, env, args, share_dir)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run_graph_inner(graph, out: Path, env: dict, args, share_dir) -> int:
    share = share_dir()
    logs = out / 'logs'
    logs.mkdir(parents=True, exist_ok=True)
    procs: dict[str, subprocess.Popen] = {}
    files = []
    sim_name = graph.shutdown_with or 'sky_simulator'
    order = [n for n in graph.nodes if n.name != sim_name] + [graph.node(sim_name)]
    print(
        f'sim: starting {len(order)} nodes (ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}, loopback only); '
        f'logs in {logs}',
        flush=True,
    )
    t_start = time.monotonic()
    code = 0
    try:
        for n in order:
            f = open(logs / f'{n.name}.log', 'w')
            files.append(f)
            cmd = _node_command(n) + n.ros_arguments(share)
            procs[n.name] = subprocess.Popen(
                cmd, env=env, stdout=f, stderr=subprocess.STDOUT, cwd=os.getcwd()
            )
        sim = procs[sim_name]
        last_note = t_start
        while sim.poll() is None:
            time.sleep(0.2)
            dead = [k for k, p in procs.items() if k != sim_name and p.poll() is not None]
            if dead:
                raise CompassError(
                    f'node(s) {", ".join(dead)} stopped early: ' + _tail(logs, dead[0])
                )
            if time.monotonic() - t_start > args.timeout:
                raise CompassError(f'the run took longer than --timeout {args.timeout:g} s')
            if time.monotonic() - last_note > 15:
                last_note = time.monotonic()
                print(
                    f'sim: running ({time.monotonic() - t_start:.0f} '
                    f's{_progress(logs / f"{sim_name}.log")})',
                    flush=True,
                )
        if sim.returncode != 0:
            raise CompassError(
                f'sky_simulator exited with {sim.returncode}: ' + _tail(logs, sim_name)
            )
        time.sleep(1.0)
    except KeyboardInterrupt:
        print('sim: interrupted, stopping the nodes', file=sys.stderr)
        code = 130
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)  # let the shutdown finish
        stopped = _stop_all(procs)
        for f in files:
            f.close()
    bad = {k: rc for k, rc in stopped.items() if rc not in (0, None)}
    if bad and code == 0:
        raise CompassError(
            'node(s) did not stop cleanly: '
            + ', '.join(f'{k} (exit {v})' for k, v in bad.items())
            + '; '
            + _tail(logs, next(iter(bad)))
        )
    if code:
        return code
    summary_path = out / 'evaluation_summary.json'
    if not summary_path.is_file():
        raise CompassError(
            f'the evaluator wrote no report ({summary_path}): ' + _tail(logs, 'error_evaluator')
        )
    summary = json.loads(summary_path.read_text())
    print(format_table(summary, realtime=args.realtime))
    print(
        f'\nreport: {out}/evaluation_summary.csv, evaluation_samples.csv, evaluation.png, '
        f'evaluation_summary.json; node logs: {logs}/ ({time.monotonic() - t_start:.0f} s)'
    )
    return 0


def _progress(log: Path) -> str:
    """Return ", frame N/M" from the simulator's last progress line, or ""."""
    import re

    try:
        found = re.findall(r'\] frame (\d+(?:/\d+)?)', log.read_text(errors='replace'))
    except OSError:
        return ''
    return f', frame {found[-1]}' if found else ''


def _stop_all(procs: dict) -> dict:
    """
    Stop every running node: SIGINT, then SIGTERM / SIGKILL for stragglers; return exit codes.

    Stragglers get the launch files' timeouts (graphs.STOP_TIMEOUT_S, SIGKILL_TIMEOUT_S).
    """
    from ..graphs import SIGKILL_TIMEOUT_S, STOP_TIMEOUT_S

    for p in procs.values():
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    deadline = time.monotonic() + STOP_TIMEOUT_S
    for p in procs.values():
        try:
            p.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.terminate()
            try:
                p.wait(timeout=SIGKILL_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    return {k: p.returncode for k, p in procs.items()}


def _tail(logs: Path, name: str, n: int = 6) -> str:
    try:
        lines = (logs / f'{name}.log').read_text(errors='replace').strip().splitlines()
    except OSError:
        return '(no log)'
    return ' | '.join(lines[-n:]) if lines else '(empty log)'
