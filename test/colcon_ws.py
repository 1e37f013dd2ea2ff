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

"""Test-side helpers for tests that run this package from a colcon install space."""

from __future__ import annotations

from pathlib import Path
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def sourced_env(script: Path, env: dict) -> dict:
    """
    Return the environment after ``source script`` in bash, starting from ``env``.

    Parameters
    ----------
    script : pathlib.Path
        A ``setup.bash`` (a colcon install space's, or ../shared/ros-cpp's).
    env : dict
        The environment bash starts with.

    Returns
    -------
    dict
        Every variable bash exports after sourcing the script.

    """
    dump = subprocess.run(
        ['bash', '-c', f'source {script} && env -0'],
        env=env,
        capture_output=True,
        timeout=60,
        check=True,
    ).stdout.decode()
    return dict(kv.split('=', 1) for kv in dump.split('\0') if '=' in kv)


def colcon_install(ws: Path, env: dict) -> None:
    """
    Build this package with colcon into ``ws/build`` and ``ws/install``; fail the test otherwise.

    Parameters
    ----------
    ws : pathlib.Path
        The workspace directory (the build and install bases go below it).
    env : dict
        The environment colcon runs in.

    """
    colcon = shutil.which('colcon', path=str(BIN)) or shutil.which('colcon')
    r = subprocess.run(
        [
            colcon,
            # its log in the workspace, not in the tree's log/ that another test's build may use
            '--log-base',
            str(ws / 'log'),
            'build',
            '--packages-select',
            'polarization_compass',
            '--build-base',
            str(ws / 'build'),
            '--install-base',
            str(ws / 'install'),
            '--event-handlers',
            'console_direct-',
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
