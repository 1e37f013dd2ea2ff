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
``replay --plots-every N``: the diagnostic figure of every N-th frame of a replayed bag (issue 25).

A 6-frame simulated bag (record-sim, the paper's field of view on 96 x 80 pixels) is replayed with
two methods; every 2nd frame gets a figure whose heading is the replay's (psi = bearing - sun
azimuth, checked by hand), and the command line writes the same files.
"""

import datetime as dt
import math
from pathlib import Path
import subprocess
import sys

from polarization_compass.camera import CameraModel
from polarization_compass.conventions import CameraAttitude
from polarization_compass.recording import record_sim, RecordSpec
from polarization_compass.replay import replay_bag, ReplayConfig
from polarization_compass.scene_load import load_scene
import pytest

ROOT = Path(__file__).resolve().parents[1]
CAMERA = CameraModel(
    width_px=96,
    height_px=80,
    focal_length_mm=4.0,
    pixel_pitch_x_um=2448 * 3.45 / 96,
    pixel_pitch_y_um=2048 * 3.45 / 80,
)


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    t = dt.datetime(2019, 11, 15, 6, 0, tzinfo=dt.timezone.utc)
    scene = load_scene(None).replace(camera=CAMERA, attitude=CameraAttitude(30.0, 0.0, 0.0))
    spec = RecordSpec(
        duration_s=0.6, rate_hz=10.0, imu_attitude_noise_deg=0.0, reference_noise_deg=0.0
    )
    out = tmp_path_factory.mktemp('bag') / 'run'
    record_sim(scene.replace(time_utc=t), spec, out)
    return out


def test_every_second_frame_gets_a_figure_with_the_replays_heading(bag, tmp_path):
    from polarization_compass.bag.topic_map import default_topic_map
    from polarization_compass.replay_figures import results_of_rows, write_frame_figures

    config = ReplayConfig(methods=('least_squares', 'zenith'), error_map=None)
    result = replay_bag(bag, config, workers=1)
    stamps = sorted({r.stamp_ns for r in result.rows})
    figs = write_frame_figures(bag, result, default_topic_map(), config, 2, tmp_path)
    assert len(figs) == math.ceil(len(stamps) / 2) and all(f.stat().st_size > 5_000 for f in figs)
    assert [int(f.stem.split('_')[2]) for f in figs] == stamps[::2]
    rows = [r for r in result.rows if r.stamp_ns == stamps[0]]
    for row, res in zip(rows, results_of_rows(rows)):
        assert res.method == row.method and res.status.value == row.status
        if row.raw_bearing_deg is not None:
            want = (row.raw_bearing_deg - row.sun_azimuth_deg + 180.0) % 360.0 - 180.0
            assert res.psi_deg == pytest.approx(want, abs=1e-9)


def test_cli_plots_every(bag, tmp_path):
    out = tmp_path / 'out'
    cmd = [
        sys.executable,
        '-m',
        'polarization_compass.cli',
        'replay',
        str(bag),
        '--methods',
        'least_squares',
        '--error-map',
        'none',
        '--no-plots',
        '--plots-every',
        '3',
        '--out',
        str(out),
        '--workers',
        '1',
    ]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    assert len(list((out / 'frames').glob('frame_*.png'))) == 2  # frames 0 and 3 of 6
    bad = subprocess.run(
        cmd[:-6] + ['--plots-every', '-1'], capture_output=True, text=True, timeout=600, cwd=ROOT
    )
    assert bad.returncode == 2 and '--plots-every' in bad.stderr
