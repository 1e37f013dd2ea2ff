"""Error-map throughput against issue 4's target: a pitch-only sweep of 1.4e5 cells for the paper's four methods
(zenith, sm_asm, symmetry, least squares: 5.6e5 estimates) in <= 2 minutes on all cores, at the default sampling.

The paper's "1.4e5 sets of simulation experiments" are scenes each evaluated by the four approaches, so the
target counts cells, not estimates. The target sweep here is sun altitude 0:50:1 deg x yaw -180:176:4 x pitch
-30:30:2 x roll 0 = 51 x 90 x 31 = 142 290 cells. Running it takes several minutes, so a sub-grid spread over
the same domain runs through the real engine (``sweep.run_sweep``, all cores, pool start-up included):
every 5th sun altitude x every 3rd pitch x every yaw (11 x 11 x 90 = 10 890 cells, 43 560 estimates, in full
mode; the cost of a cell grows with the sun's altitude and the tilt, so the sub-grid keeps both ends).

    start-up    wall time of a sweep of one cell per worker (spawn, imports, numba cache, estimators), after
                one such sweep to warm up (a first run after a code change compiles numba's cache)
    rate        sub-grid cells / (sub-grid wall time - start-up)
    projected   start-up + 142 290 / rate, against 120 s

The CPU time of this process and the workers (``getrusage`` of the reaped children; the start-up run
subtracted) gives the CPU per
cell, which other jobs on a shared machine change much less than the wall time; the load average before and
after the timed sweep is recorded with it.
"""
from __future__ import annotations

import os
import resource
import time

import numpy as np

from .common import Unavailable, optional_import

TARGET_LIMIT_S = 120.0
#: The target sweep's axes (deg): sun altitude, yaw, pitch (roll 0).
TARGET_AXES = (np.arange(0.0, 50.1, 1.0), np.arange(-180.0, 176.1, 4.0), np.arange(-30.0, 30.1, 2.0))
#: Sub-grid run per mode: (every k-th sun altitude, every k-th pitch, every k-th yaw).
SAMPLE_STEPS = {"full": (5, 3, 1), "quick": (25, 15, 1)}


def _children_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _timed(sweep, spec, workers: int):
    """(wall s, CPU s of this process and of the pool's workers, map) of one sweep; the workers are reaped
    when it returns."""
    c0 = _children_cpu_s() + time.process_time()
    t0 = time.perf_counter()
    m = sweep.run_sweep(spec, out=None, workers=workers, progress=False)
    return time.perf_counter() - t0, _children_cpu_s() + time.process_time() - c0, m


def run(cfg) -> dict:
    sweep = optional_import("polarization_compass.sweep")
    est = optional_import("polarization_compass.estimators")
    methods = list(est.registry.paper_methods())
    if not methods:
        raise Unavailable("the paper's four estimators are not registered yet")
    workers = max(1, os.cpu_count() or 1)
    scene = None
    alt, yaw, pitch = TARGET_AXES
    target_cells = alt.size * yaw.size * pitch.size
    if cfg.tiny:                                  # smoke test: a small camera and a few cells
        from polarization_compass.camera import CameraModel
        from polarization_compass.scene import default_scene
        scene = default_scene().replace(camera=CameraModel(width_px=192, height_px=160))
        s_alt, s_yaw, s_pitch = alt[[10, 40]], yaw[::15], pitch[[5, 25]]
    else:
        ka, kp, ky = SAMPLE_STEPS["full" if cfg.mode == "full" else "quick"]
        s_alt, s_yaw, s_pitch = alt[::ka], yaw[::ky], pitch[::kp]
    sample = sweep.SweepSpec(list(methods), s_alt, s_yaw, s_pitch, [0.0], scene=scene)
    cells = sample.cell_count() // len(methods)
    # start-up: one cell per worker (each worker gets a chunk, so every worker starts)
    probe = sweep.SweepSpec(list(methods), [30.0], [0.0], pitch[:workers], [0.0], scene=scene)
    probe_cells = probe.cell_count() // len(methods)
    _timed(sweep, probe, workers)              # warm-up: numba's cache (compiled on a first run), file cache
    startup_s, probe_cpu_s, _ = _timed(sweep, probe, workers)
    load_before = os.getloadavg()
    wall_s, cpu_s, m = _timed(sweep, sample, workers)
    load_after = os.getloadavg()
    rate = cells / max(wall_s - startup_s, 1e-9)
    projected_s = startup_s + target_cells / rate
    cpu_ms_per_cell = max(cpu_s - probe_cpu_s, 0.0) / max(cells - probe_cells, 1) * 1e3
    return {
        "methods": methods, "workers": m.meta["workers"],
        "target": {"cells": int(target_cells), "estimates": int(target_cells * len(methods)), "limit_s": TARGET_LIMIT_S,
                   "sun_altitude_deg": "0:50:1", "yaw_deg": "-180:176:4", "pitch_deg": "-30:30:2", "roll_deg": "0"},
        "sample": {"sun_altitude_deg": s_alt.tolist(), "pitch_deg": s_pitch.tolist(), "yaw_count": int(s_yaw.size),
                   "cells": int(cells), "estimates": int(cells * len(methods)),
                   "valid_fraction": float(m.valid.mean()), "camera": "tiny 192 x 160 (smoke test)" if cfg.tiny
                   else "default"},
        "knobs": {x: sample.knobs[x] for x in methods},
        "pixels": {x: v["pixel_count"] for x, v in m.meta["sampling"].items()},
        "startup_s": startup_s, "wall_s": wall_s,
        "cells_per_s": rate, "estimates_per_s": rate * len(methods),
        "cpu_ms_per_cell": cpu_ms_per_cell, "cpu_ms_per_estimate": cpu_ms_per_cell / len(methods),
        "projected_target_sweep_s": projected_s, "pass": bool(projected_s <= TARGET_LIMIT_S),
        "load_average_before": list(load_before), "load_average_after": list(load_after),
        "note": "projected = start-up + target cells / rate; rate = sub-grid cells / (wall - start-up); "
                "CPU = this process + the pool's reaped workers (getrusage), start-up run subtracted",
    }
