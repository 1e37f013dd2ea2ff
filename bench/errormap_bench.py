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
Error-map throughput against issue 4's target.

The target is a pitch-only sweep of 1.4e5 cells for the paper's four methods (zenith, sm_asm,
symmetry, least squares: 5.6e5 estimates) in <= 2 minutes on all cores, at the default sampling.

The paper's "1.4e5 sets of simulation experiments" are scenes each evaluated by the four
approaches, so the target counts cells, not estimates. The target sweep here is sun altitude 0:50:1
deg x yaw -180:176:4 x pitch -30:30:2 x roll 0 = 51 x 90 x 31 = 142 290 cells. Running it takes
several minutes, so a sub-grid spread over the same domain runs through the real engine
(``sweep.run_sweep``, all cores, pool start-up included): every 5th sun altitude x every 3rd pitch
x every yaw (11 x 11 x 90 = 10 890 cells, 43 560 estimates, in full mode; the cost of a cell grows
with the sun's altitude and the tilt, so the sub-grid keeps both ends).

    start-up    the sub-grid sweep's wall time minus its compute time (the LocalCluster's start and
                stop), after a sweep of one cell per worker to warm up (a first run after a code
                change compiles numba's cache)
    rate        sub-grid cells / compute time (from the first chunk submitted to the last one
                received)
    projected   start-up + 142 290 / rate, against 120 s

The CPU time of this process and the workers (``getrusage`` of the reaped children; the start-up
run subtracted) gives the CPU per cell, which other jobs on a shared machine change much less than
the wall time; the load average before and after the timed sweep is recorded with it.

Backends (issue 17): one sub-grid with rolls (``BACKEND_STEPS``, ``BACKEND_ROLLS``: chunks of yaws
x rolls x methods, closer to a real map's than the pitch-only sub-grid's) runs in this process (no
Dask), on an embedded ``LocalCluster`` of 1 and of 2 workers, and on a loopback cluster of separate
processes (``python -m dask scheduler`` + two ``python -m dask worker`` on 127.0.0.1). Each row:
cells/s over the compute time (from the cluster being up to the last chunk received), tasks/s, and
the overhead share ``1 - sum(task compute s) / (workers x compute wall)`` (scheduling, transfer,
the client's bookkeeping, idle workers at the end). Every backend runs an untimed
one-chunk-per-worker probe first (imports, numba's cache). Scaling efficiency = rate(2 workers) /
(2 x rate(1 worker)), LocalCluster. The projection of a 10^8-estimate map on N workers (a core
each) uses the compute thread's CPU time per estimate, which the load from other jobs changes far
less than wall time: ``1e8 x CPU per estimate / N / (1 - the largest overhead share measured)``.
"""

from __future__ import annotations

from contextlib import contextmanager
import json
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from .common import optional_import, Unavailable

TARGET_LIMIT_S = 120.0
#: The target sweep's axes (deg): sun altitude, yaw, pitch (roll 0).
TARGET_AXES = (
    np.arange(0.0, 50.1, 1.0),
    np.arange(-180.0, 176.1, 4.0),
    np.arange(-30.0, 30.1, 2.0),
)
#: Sub-grid run per mode: (every k-th sun altitude, every k-th pitch, every k-th yaw).
SAMPLE_STEPS = {'full': (5, 3, 1), 'quick': (25, 15, 1)}
#: Backend comparison sub-grid per mode: (every k-th sun altitude, every k-th pitch, every k-th
#: yaw).
BACKEND_STEPS = {'full': (10, 5, 5), 'quick': (25, 5, 8)}
#: ... with rolls too, so that a chunk is yaws x rolls x methods estimates, as in a real map
BACKEND_ROLLS = {'full': np.arange(-30.0, 30.1, 10.0), 'quick': np.arange(-30.0, 30.1, 10.0)}
#: The 1-deg map of issue 17: about 1e8 estimates.
BIG_MAP_ESTIMATES = 1e8


def _children_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _timed(sweep, spec, workers: int):
    """
    Time one sweep: wall and CPU seconds of this process and of the cluster's workers.

    (wall s, CPU s of this process and of the cluster's workers, map, the sweep's stats) of one
    sweep; the LocalCluster's processes are reaped when it returns.
    """
    c0 = _children_cpu_s() + time.process_time()
    t0 = time.perf_counter()
    st: dict = {}
    m = sweep.run_sweep(spec, out=None, workers=workers, progress=False, stats=st)
    return time.perf_counter() - t0, _children_cpu_s() + time.process_time() - c0, m, st


@contextmanager
def loopback_cluster(n_workers: int):
    """
    Start a loopback Dask cluster of ``n_workers`` single-threaded workers and yield its address.

    A scheduler and ``n_workers`` single-threaded workers, each its own process, on 127.0.0.1 (no
    dashboard); yields the scheduler address; stops them all (they also stop by themselves:
    idle/death timeouts).
    """
    root = Path(__file__).resolve().parents[1]
    env = dict(
        os.environ,
        PYTHONPATH=str(root) + os.pathsep + os.environ.get('PYTHONPATH', ''),
        NUMBA_NUM_THREADS='1',
        OMP_NUM_THREADS='1',
        OPENBLAS_NUM_THREADS='1',
    )
    procs = []
    with tempfile.TemporaryDirectory(prefix='bench_dask_') as tmp:
        f = Path(tmp) / 'scheduler.json'

        def spawn(*args):
            procs.append(
                subprocess.Popen(
                    [sys.executable, '-m', 'dask', *args],
                    env=env,
                    cwd=tmp,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )

        try:
            spawn(
                'scheduler',
                '--host',
                '127.0.0.1',
                '--port',
                '0',
                '--no-dashboard',
                '--scheduler-file',
                str(f),
                '--idle-timeout',
                '300s',
            )
            deadline = time.monotonic() + 60
            while not (f.exists() and f.read_text().strip()):
                if time.monotonic() > deadline or procs[0].poll() is not None:
                    raise RuntimeError('the loopback scheduler did not start')
                time.sleep(0.1)
            address = json.loads(f.read_text())['address']
            for _ in range(n_workers):
                spawn(
                    'worker',
                    '--scheduler-file',
                    str(f),
                    '--host',
                    '127.0.0.1',
                    '--nthreads',
                    '1',
                    '--no-nanny',
                    '--no-dashboard',
                    '--death-timeout',
                    '30s',
                )
            from distributed import Client

            with Client(address, timeout='30s', set_as_default=False) as c:
                c.wait_for_workers(n_workers, timeout=120)
            yield address
        finally:
            for p in reversed(procs):
                if p.poll() is None:
                    p.terminate()
            for p in procs:
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait(timeout=5)


def _backend_row(sweep, spec, probe, label: str, **kw) -> dict:
    """
    Measure one backend: an untimed probe sweep, then the timed sweep.

    The probe runs one chunk per worker (imports, numba's cache, the evaluators).
    """
    sweep.run_sweep(probe, out=None, progress=False, **kw)
    st: dict = {}
    m = sweep.run_sweep(spec, out=None, progress=False, stats=st, **kw)
    compute = max(st['compute_s'], 1e-9)
    cells = spec.cell_count() // len(spec.methods)
    n = st['workers']
    return {
        'backend': label,
        'workers': n,
        'compute_s': compute,
        'tasks': st['tasks'],
        'cells': cells,
        'cells_per_s': cells / compute,
        'tasks_per_s': (st['dask_tasks'] or st['tasks']) / compute,
        'dask_tasks': st['dask_tasks'],
        'task_s': st['task_s'],
        'task_cpu_s': st['task_cpu_s'],
        'setup_cpu_s': st['setup_cpu_s'],
        'overhead_share': max(0.0, 1.0 - st['task_s'] / (n * compute)),
        'cpu_ms_per_estimate': st['task_cpu_s'] / max(st['estimates'], 1) * 1e3,
        'overhead_s_per_task': max(0.0, n * compute - st['task_s'])
        / max(st['dask_tasks'] or st['tasks'], 1),
        '_map': m,
    }


def run_backends(cfg, sweep, methods, scene) -> dict:
    """
    Compare in-process, LocalCluster and loopback-cluster sweeps on one sub-grid.

    In process vs LocalCluster (1, 2 workers) vs a loopback two-worker cluster on one sub-grid.
    """
    from polarization_compass import sweep_dask

    alt, yaw, pitch = TARGET_AXES
    if cfg.tiny:
        s_alt, s_yaw, s_pitch = alt[[10, 40]], yaw[::30], pitch[[5, 15, 25]]
    else:
        ka, kp, ky = BACKEND_STEPS['full' if cfg.mode == 'full' else 'quick']
        s_alt, s_yaw, s_pitch = alt[::ka], yaw[::ky], pitch[::kp]
    rolls = [0.0] if cfg.tiny else BACKEND_ROLLS['full' if cfg.mode == 'full' else 'quick']
    spec = sweep.SweepSpec(list(methods), s_alt, s_yaw, s_pitch, rolls, scene=scene)
    probe = sweep.SweepSpec(list(methods), [30.0], [0.0], pitch[:2], [0.0], scene=scene)
    load_before = os.getloadavg()
    rows = [_backend_row(sweep, spec, probe, 'in process (no Dask)', workers=1)]
    for n in (2,) if cfg.tiny else (1, 2):  # the smoke test: one cluster, no loopback processes
        t0 = time.perf_counter()
        client, cluster = sweep_dask.start(None, n)
        startup = time.perf_counter() - t0
        try:
            rows.append(
                {
                    **_backend_row(
                        sweep, spec, probe, 'LocalCluster', scheduler=cluster.scheduler_address
                    ),
                    'startup_s': startup,
                }
            )
        finally:
            client.close()
            cluster.close()
    if not cfg.tiny:
        t0 = time.perf_counter()
        with loopback_cluster(2) as address:
            startup = time.perf_counter() - t0
            rows.append(
                {
                    **_backend_row(
                        sweep, spec, probe, 'loopback cluster (3 processes)', scheduler=address
                    ),
                    'startup_s': startup,
                }
            )
    load_after = os.getloadavg()
    rows[0]['startup_s'] = 0.0
    ref = rows[0].pop('_map')
    identical = True
    for r in rows[1:]:
        m = r.pop('_map')
        same = bool(
            np.array_equal(m.error_deg, ref.error_deg) and np.array_equal(m.status, ref.status)
        )
        identical &= same
        # where a backend differs from the in-process map: per method, the largest error
        # difference and the number of cells whose status differs
        r['differs_from_in_process'] = (
            None
            if same
            else {
                str(name): {
                    'max_abs_error_diff_deg': float(
                        np.abs(m.error_deg[i] - ref.error_deg[i]).max()
                    ),
                    'status_diffs': int(np.count_nonzero(m.status[i] != ref.status[i])),
                }
                for i, name in enumerate(ref.methods)
            }
        )
    one = next((r for r in rows[1:] if r['workers'] == 1), None)
    two = next((r for r in rows[1:] if r['workers'] == 2 and r['backend'] == 'LocalCluster'), None)
    cpu_ms = float(np.median([r['cpu_ms_per_estimate'] for r in rows]))
    share = float(max(r['overhead_share'] for r in rows[1:]))
    # the 1e8-estimate map on N single-threaded workers with a core each: CPU per estimate
    # (load-independent), inflated by the largest overhead share measured here
    projection = {
        str(n): BIG_MAP_ESTIMATES * cpu_ms * 1e-3 / n / max(1.0 - share, 0.05)
        for n in (2, 8, 32, 128)
    }
    return {
        'sample': {
            'sun_altitude_deg': s_alt.tolist(),
            'pitch_deg': s_pitch.tolist(),
            'yaw_count': int(s_yaw.size),
            'roll_deg': list(map(float, rolls)),
            'cells': int(spec.cell_count() // len(methods)),
            'chunks': len(spec.chunks()),
            'estimates': int(spec.cell_count()),
        },
        'rows': rows,
        'identical_maps': identical,
        'scaling_efficiency_1_to_2': two['cells_per_s'] / (2 * one['cells_per_s'])
        if one and two
        else None,
        'localcluster_per_worker_vs_in_process': one['cells_per_s'] / rows[0]['cells_per_s']
        if one
        else None,
        'projection_1e8_estimates_s': projection,
        'cpu_ms_per_estimate': cpu_ms,
        'overhead_share_max': share,
        'load_average_before': list(load_before),
        'load_average_after': list(load_after),
        'note': 'rates are wall clock on a shared machine (see the load average); CPU per '
        'estimate is the '
        "compute thread's CPU time; projection = 1e8 x CPU per estimate / N / (1 - overhead "
        'share)',
    }


def run(cfg) -> dict:
    sweep = optional_import('polarization_compass.sweep')
    est = optional_import('polarization_compass.estimators')
    methods = list(est.registry.paper_methods())
    if not methods:
        raise Unavailable("the paper's four estimators are not registered yet")
    # tiny (the smoke test): in this process; the LocalCluster path is run_backends' (two cluster
    # starts and worker imports less, ~10 s)
    workers = 1 if cfg.tiny else max(1, os.cpu_count() or 1)
    scene = None
    alt, yaw, pitch = TARGET_AXES
    target_cells = alt.size * yaw.size * pitch.size
    if cfg.tiny:  # smoke test: a small camera and a few cells
        from polarization_compass.camera import CameraModel
        from polarization_compass.scene_load import default_scene

        scene = default_scene().replace(camera=CameraModel(width_px=192, height_px=160))
        s_alt, s_yaw, s_pitch = alt[[10, 40]], yaw[::15], pitch[[5, 25]]
    else:
        ka, kp, ky = SAMPLE_STEPS['full' if cfg.mode == 'full' else 'quick']
        s_alt, s_yaw, s_pitch = alt[::ka], yaw[::ky], pitch[::kp]
    sample = sweep.SweepSpec(list(methods), s_alt, s_yaw, s_pitch, [0.0], scene=scene)
    cells = sample.cell_count() // len(methods)
    # start-up: one cell per worker (each worker gets a chunk, so every worker starts)
    probe = sweep.SweepSpec(list(methods), [30.0], [0.0], pitch[:workers], [0.0], scene=scene)
    probe_cells = probe.cell_count() // len(methods)
    _timed(sweep, probe, workers)  # warm-up: numba's cache (compiled on a first run), file cache
    _, probe_cpu_s, _, _ = _timed(sweep, probe, workers)
    load_before = os.getloadavg()
    wall_s, cpu_s, m, st = _timed(sweep, sample, workers)
    load_after = os.getloadavg()
    startup_s = wall_s - st['compute_s']  # the cluster's start and stop, the client's set-up
    rate = cells / max(st['compute_s'], 1e-9)
    projected_s = startup_s + target_cells / rate
    cpu_ms_per_cell = max(cpu_s - probe_cpu_s, 0.0) / max(cells - probe_cells, 1) * 1e3
    backends = run_backends(cfg, sweep, methods, scene)
    return {
        'backends': backends,
        'methods': methods,
        'workers': m.meta['workers'],
        'target': {
            'cells': int(target_cells),
            'estimates': int(target_cells * len(methods)),
            'limit_s': TARGET_LIMIT_S,
            'sun_altitude_deg': '0:50:1',
            'yaw_deg': '-180:176:4',
            'pitch_deg': '-30:30:2',
            'roll_deg': '0',
        },
        'sample': {
            'sun_altitude_deg': s_alt.tolist(),
            'pitch_deg': s_pitch.tolist(),
            'yaw_count': int(s_yaw.size),
            'cells': int(cells),
            'estimates': int(cells * len(methods)),
            'valid_fraction': float(m.valid.mean()),
            'camera': 'tiny 192 x 160 (smoke test)' if cfg.tiny else 'default',
        },
        'knobs': {x: sample.knobs[x] for x in methods},
        'pixels': {x: v['pixel_count'] for x, v in m.meta['sampling'].items()},
        'startup_s': startup_s,
        'wall_s': wall_s,
        'cells_per_s': rate,
        'estimates_per_s': rate * len(methods),
        'cpu_ms_per_cell': cpu_ms_per_cell,
        'cpu_ms_per_estimate': cpu_ms_per_cell / len(methods),
        'projected_target_sweep_s': projected_s,
        'pass': bool(projected_s <= TARGET_LIMIT_S),
        'load_average_before': list(load_before),
        'load_average_after': list(load_after),
        'note': 'projected = start-up + target cells / rate; rate = sub-grid cells / (wall - '
        'start-up); '
        "CPU = this process + the LocalCluster's reaped workers (getrusage), probe run subtracted",
    }
