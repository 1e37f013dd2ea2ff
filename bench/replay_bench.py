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
Issue 6's target, measured: offline replay at >= 5x real time.

A full-resolution 10 Hz run, all four methods (``--methods zenith,sm_asm,symmetry,least_squares``:
the issue's configuration), each corrected with the shipped map, at the command's default knobs.
The command's default method set adds ``tilt_aware``; it is replayed too and reported beside the
target (``all_methods``), not as it.

1. ``polarization-compass record-sim --scene config/scenes/imx250mzr_noisy.yaml --duration S --out
   BAG`` into a temporary directory (full: 20 s = 200 frames, ~1.9 GB; quick: 3 s). Its wall time
   is recorded too (not a target).
2. ``polarization-compass replay BAG --methods ... --out DIR`` in a child process
   (:mod:`bench.replay_worker`: the command's replay run through the core, clock on the replay's
   per-frame progress callback). Whole command = wall time of that child process, interpreter start
   to exit (imports, numba caches, the sun table, reading, every method, the deferred tilt
   correction, CSV and figures). Per frame after start-up = mean wall time between frames, from the
   frame after the first tenth (at least the 3rd) to the last; its real-time factor is the
   recording period over it, the speed a long field run approaches. ``overhead_s`` = whole command
   - frames x per-frame time (start-up and the end of the run); from it, the real-time factor of a
   10-minute run is extrapolated.
3. ``summary.json`` of the replay: frames, recorded duration, the replay loop's own wall and CPU
time and speed, the median per-frame time of each estimator and of the demosaic, statuses.

The bag is deleted afterwards (~100 MB per second of recording). Pass: real-time factor >= 5
(shown for the whole command and per frame).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
import random
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from .common import optional_import, Skipped

TARGET_X_REAL_TIME = 5.0
SCENE = 'config/scenes/imx250mzr_noisy.yaml'
REPO = Path(__file__).resolve().parent.parent
LONG_RUN_S = 600.0


def per_frame_figures(
    frame_done_s, bag_duration_s: float, frames: int, whole_wall_s: float | None
) -> dict:
    """
    Compute the per-frame time after start-up and the real-time factors.

    From the wall clock after each frame.
    """
    t = np.asarray(frame_done_s, dtype=float)
    out = {
        'per_frame_ms': None,
        'per_frame_ms_median': None,
        'per_frame_ms_p95': None,
        'per_frame_x_real_time': None,
        'skipped_frames': None,
        'overhead_s': None,
        'long_run_x_real_time': None,
        'first_frame_done_s': float(t[0]) if t.size else None,
    }
    period = bag_duration_s / frames if frames > 0 and bag_duration_s > 0 else None
    k0 = max(2, t.size // 10)
    if t.size - k0 < 2 or period is None:
        return out
    dt = np.diff(t[k0:])
    per = (t[-1] - t[k0]) / (t.size - 1 - k0)
    out.update(
        per_frame_ms=per * 1e3,
        per_frame_ms_median=float(np.median(dt)) * 1e3,
        per_frame_ms_p95=float(np.percentile(dt, 95)) * 1e3,
        skipped_frames=int(k0),
        per_frame_x_real_time=period / per if per > 0 else None,
    )
    if whole_wall_s is not None:
        overhead = whole_wall_s - frames * per
        out['overhead_s'] = overhead
        out['long_run_x_real_time'] = LONG_RUN_S / (max(overhead, 0.0) + LONG_RUN_S / period * per)
    return out


def summarize(summary: dict, times: dict, whole_wall_s: float) -> dict:
    """
    Return the replay's speed figures.

    Read from its ``summary.json``, the worker's clock and the whole wall time.
    """
    frames = int(summary.get('frames', 0))
    dur = float(summary.get('bag_duration_s', 0.0))
    stats = summary.get('statistics', {})
    res = {
        'frames': frames,
        'bag_duration_s': dur,
        'whole_command_s': whole_wall_s,
        'whole_command_x_real_time': dur / whole_wall_s if whole_wall_s > 0 else None,
        'replay_loop_s': summary.get('wall_s'),
        'replay_loop_x_real_time': summary.get('speed_x_real_time'),
        'cpu_s': summary.get('cpu_s'),
        'cpu_x_real_time': summary.get('speed_x_real_time_cpu'),
        'imports_s': times.get('imported_s'),
        'replay_loop_start_s': times.get('replay_start_s'),
        'stage_ms_median': summary.get('timing_ms_median', {}),
        'statuses': summary.get('statuses', {}),
        'streams': {
            k: {'count': v.get('count'), 'missed': v.get('missed'), 'rms_deg': v.get('rms')}
            for k, v in stats.items()
        },
        'error_map': summary.get('error_map'),
        'target_x_real_time': TARGET_X_REAL_TIME,
    }
    res.update(per_frame_figures(times.get('frame_done_s', []), dur, frames, whole_wall_s))
    for key in ('whole_command', 'per_frame', 'long_run'):
        v = res.get(f'{key}_x_real_time')
        res[f'pass_{key}'] = None if v is None else bool(v >= TARGET_X_REAL_TIME)
    return res


#: Issue 6's "all four methods" (the paper's); the command's default adds tilt_aware.
PAPER_METHODS = 'zenith,sm_asm,symmetry,least_squares'


def median_run(runs: list[dict]) -> dict:
    """
    Return the run with the median per-frame time, plus every run's speed figures.

    This host's speed drifts by up to 2x over an hour, so one run can land in a slow spell; every
    run's figures are under ``runs``.
    """
    by_time = sorted(
        runs, key=lambda r: math.inf if r.get('per_frame_ms') is None else r['per_frame_ms']
    )
    mid = dict(by_time[(len(runs) - 1) // 2])
    mid['runs'] = [
        {
            k: r.get(k)
            for k in (
                'per_frame_ms',
                'per_frame_ms_median',
                'per_frame_x_real_time',
                'long_run_x_real_time',
                'whole_command_x_real_time',
            )
        }
        for r in runs
    ]
    return mid


def _env() -> dict:
    dom = os.environ.get('BENCH_ROS_DOMAIN_ID') or str(
        random.Random(os.getpid() + 2).randint(150, 220)
    )
    return dict(
        os.environ,
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_DOMAIN_ID=dom,
        PYTHONUNBUFFERED='1',
    )


def _size_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob('*') if p.is_file())


def run(cfg) -> dict:
    if cfg.tiny:
        raise Skipped(
            'smoke-test size: recording and replaying a full-resolution bag takes ~25 s; '
            'its parsing is tested instead'
        )
    optional_import('rosbags')
    optional_import('polarization_compass.replay')
    duration = float(cfg.replay_duration_s)
    env = _env()
    tmp = Path(tempfile.mkdtemp(prefix='bench_replay_'))
    bag, out, times_path = tmp / 'bag', tmp / 'out', tmp / 'times.json'
    res = {
        'scene': SCENE,
        'duration_s': duration,
        'record_command': f'polarization-compass record-sim --scene {SCENE} --duration '
        f'{duration:g} --out BAG',
        'replay_command': f'polarization-compass replay BAG --methods {PAPER_METHODS} --out DIR',
    }
    try:
        t0 = time.perf_counter()
        p = subprocess.run(
            [
                sys.executable,
                '-m',
                'polarization_compass.cli',
                'record-sim',
                '--scene',
                SCENE,
                '--duration',
                f'{duration:g}',
                '--out',
                str(bag),
            ],
            cwd=REPO,
            env=env,
            capture_output=True,
            text=True,
            timeout=1800,
        )
        res['record_s'] = time.perf_counter() - t0
        if p.returncode != 0:
            raise RuntimeError(
                f'record-sim exit {p.returncode}: {(p.stderr or p.stdout).strip()[-300:]}'
            )
        res['bag_mib'] = _size_bytes(bag) / 2**20
        runs: dict = {PAPER_METHODS: [], 'all': []}
        for _ in range(
            max(1, int(cfg.repeats))
        ):  # interleaved: both see the same spells of the host
            for methods, rs in runs.items():
                shutil.rmtree(out, ignore_errors=True)
                t0 = time.perf_counter()
                p = subprocess.run(
                    [
                        sys.executable,
                        '-m',
                        'bench.replay_worker',
                        str(times_path),
                        'replay',
                        str(bag),
                        '--methods',
                        methods,
                        '--out',
                        str(out),
                    ],
                    cwd=REPO,
                    env=env,
                    capture_output=True,
                    text=True,
                    timeout=1800,
                )
                whole = time.perf_counter() - t0
                if p.returncode != 0:
                    raise RuntimeError(
                        f'replay exit {p.returncode}: {(p.stderr or p.stdout).strip()[-300:]}'
                    )
                summary = json.loads((out / 'summary.json').read_text())
                times = json.loads(times_path.read_text()) if times_path.is_file() else {}
                run_res = summarize(summary, times, whole)
                run_res['replay_stdout_first_line'] = (p.stdout.strip().splitlines() or [''])[0]
                rs.append(run_res)
        res.update(median_run(runs[PAPER_METHODS]))
        res['all_methods'] = dict(
            median_run(runs['all']), replay_command='polarization-compass replay BAG --out DIR'
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return res
