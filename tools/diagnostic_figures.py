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
Make the README's "What the compass sees" pictures with the package's own commands.

The real frames (``test/data/real-sky``, else ``../shared/data/real-sky``; ccompass quadrant JPEGs,
MIT) are written as Stokes planes (.npz s0/s1/s2) with their camera file (equidistant fisheye, the
+45 deg polarizer towards +x-y, and a misconfigured copy with +x+y) by ``test/real_sky.py``; then
``polarization-compass estimate ... --plot`` and ``check-polarizer ... --plot`` draw them into
``docs/figures/``. Usage: ``.venv/bin/python tools/diagnostic_figures.py [WORKDIR]``.
"""

from pathlib import Path
import subprocess
import sys
import tempfile

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))
import real_sky  # noqa: E402

FIGS = ROOT / 'docs' / 'figures'


def _data_dir() -> Path:
    for d in (
        ROOT / 'test' / 'data' / 'real-sky',
        ROOT.parent / 'shared' / 'data' / 'real-sky',
        ROOT.parent.parent / 'shared' / 'data' / 'real-sky',
    ):
        if (d / 'sunny.jpg').is_file():
            return d
    raise SystemExit('real sky frames not found (test/data/real-sky)')


def _cli(*args) -> None:
    cmd = [sys.executable, '-m', 'polarization_compass.cli', *map(str, args)]
    print(' '.join(cmd[2:]), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def main(work: Path) -> None:
    real_sky.DATA = _data_dir()
    cams = {}
    for pol in ('+x-y', '+x+y'):
        cams[pol] = work / f'lucid_{pol[-2:].replace("+", "p").replace("-", "m")}.yaml'
        cams[pol].write_text(real_sky.camera_yaml_text(pol))
    for stem in ('sunny', 'cloudy'):
        i, q, u = real_sky.read_quadrants(stem)
        np.savez(work / f'{stem}.npz', s0=i, s1=q, s2=u)
    sun = ['--sun-azimuth', '0', '--sun-altitude']  # no time or place was recorded: azimuth 0
    for stem, pol, out in (
        ('sunny', '+x-y', 'diagnostic_sunny.png'),
        ('cloudy', '+x-y', 'diagnostic_cloudy.png'),
        ('sunny', '+x+y', 'diagnostic_misconfigured.png'),
    ):
        alt = f'{real_sky.sun_altitude_deg(stem):.1f}'
        _cli(
            'estimate',
            work / f'{stem}.npz',
            '--camera',
            cams[pol],
            *sun,
            alt,
            '--plot',
            FIGS / out,
        )
    _cli(
        'check-polarizer',
        work / 'sunny.npz',
        '--camera',
        cams['+x+y'],
        '--plot',
        FIGS / 'polarizer_check_misconfigured.png',
    )


if __name__ == '__main__':
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as d:
            main(Path(d))
