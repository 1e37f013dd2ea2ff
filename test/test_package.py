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
The package builds with colcon as an ament_python package.

It installs what `ros2 run`/`ros2 launch` need.
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXECUTABLES = [
    'sky_simulator',
    'heading_estimator',
    'tilt_corrector',
    'error_evaluator',
    'polarization-compass',
]


def _project_files():
    """
    Return the files git tracks plus untracked, non-ignored ones.

    What a clean clone plus the work tree has.
    """
    out = subprocess.run(
        ['git', 'ls-files', '--cached', '--others', '--exclude-standard'],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return [f for f in out if (ROOT / f).is_file()]


def test_package_xml_is_format_3_ament_python_with_real_dependencies():
    from catkin_pkg.package import parse_package

    pkg = parse_package(str(ROOT / 'package.xml'))
    assert pkg.package_format == 3 and pkg.name == 'polarization_compass'
    assert pkg.get_build_type() == 'ament_python'
    execs = {d.name for d in pkg.exec_depends}
    assert {
        'rclpy',
        'sensor_msgs',
        'geometry_msgs',
        'diagnostic_msgs',
        'python3-numpy',
        'python3-opencv',
    } <= execs
    assert {'launch_testing', 'python3-pytest'} <= {d.name for d in pkg.test_depends}


@pytest.mark.colcon
def test_colcon_build_installs_executables_launch_and_config(tmp_path):
    src = tmp_path / 'ws' / 'src' / 'polarization_compass'
    for f in _project_files():
        if f.startswith(('.venv', 'bench/results')):
            continue
        (src / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, src / f)
    colcon = Path(sys.executable).parent / 'colcon'
    env = dict(os.environ, PYTHONWARNINGS='ignore')
    r = subprocess.run(
        [
            str(colcon),
            '--log-base',
            str(tmp_path / 'log'),
            'build',
            '--base-paths',
            'src',
            '--build-base',
            str(tmp_path / 'build'),
            '--install-base',
            str(tmp_path / 'install'),
        ],
        cwd=tmp_path / 'ws',
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    inst = tmp_path / 'install' / 'polarization_compass'
    for exe in EXECUTABLES:
        p = inst / 'lib' / 'polarization_compass' / exe
        assert p.is_file() and os.access(p, os.X_OK), f'{exe} not installed where `ros2 run` looks'
    share = inst / 'share' / 'polarization_compass'
    assert (share / 'package.xml').is_file()
    assert (inst / 'share/ament_index/resource_index/packages/polarization_compass').is_file()
    launch_src = sorted(p.name for p in (ROOT / 'launch').glob('*.launch.py'))
    assert {'sim.launch.py', 'compass.launch.py', 'replay.launch.py'} <= set(launch_src)
    assert sorted(p.name for p in (share / 'launch').glob('*.launch.py')) == launch_src
    for sub in ('config', 'config/scenes'):
        want = sorted(p.name for p in (ROOT / sub).glob('*.yaml'))
        assert want, f'no {sub}/*.yaml shipped'
        assert sorted(p.name for p in (share / sub).glob('*.yaml')) == want
    # the installed library carries its embedded default scene
    site = next((inst / 'lib').glob('python3*/site-packages'))
    assert (site / 'polarization_compass' / 'data' / 'default_scene.yaml').is_file()
