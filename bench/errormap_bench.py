"""Error-map throughput: (method, cell) estimates per second of :func:`polarization_compass.errormap.run_sweep`,
in one process and on all cores, and the time that implies for the paper's 1.4e5-cell pitch-only sweep
(issue 4's target: <= 2 minutes for all four methods on this 2-core machine).

The wall time includes the worker pool's start-up (spawn, imports, numba cache load), which is what a
user waits for; a small sweep therefore understates the steady-state rate.
"""
from __future__ import annotations

import os
import time

import numpy as np

from .common import Unavailable, optional_import

PAPER_PITCH_ONLY_CELLS = 1.4e5
#: Pixel stride used for a method that has no entry in ``errormap.DEFAULT_SWEEP_KNOBS``.
BENCH_STRIDE = 16


def _fallback_knobs(method: str) -> dict:
    """Stride ``BENCH_STRIDE`` for a method that has a stride knob, else its defaults (e.g. zenith)."""
    from polarization_compass.estimators import make_estimator
    try:
        make_estimator(method, stride=BENCH_STRIDE)
        return {"stride": BENCH_STRIDE}
    except Exception:  # noqa: BLE001 - no stride knob
        return {}


def _spec(errormap, methods, cells_target: int, tiny: bool):
    """A pitch-only sweep (2 sun altitudes, pitch -20..20 step 10, roll 0) of about ``cells_target`` cells."""
    from polarization_compass.camera import CameraModel
    from polarization_compass.scene import Scene
    scene = Scene(camera=CameraModel(width_px=192, height_px=160)) if tiny else None
    n_alt = 2
    pitches = np.arange(-20.0, 20.0 + 1e-9, 10.0)
    per_yaw = len(methods) * n_alt * pitches.size
    n_yaw = max(2, int(round(cells_target / per_yaw)))
    yaws = np.linspace(-180.0, 180.0, n_yaw, endpoint=False)
    knobs = {m: dict(errormap.DEFAULT_SWEEP_KNOBS[m]) if m in errormap.DEFAULT_SWEEP_KNOBS else _fallback_knobs(m)
             for m in methods}
    return errormap.SweepSpec(methods=tuple(methods), sun_altitude_deg=np.array([20.0, 40.0][:n_alt]),
                              yaw_deg=yaws, pitch_deg=pitches, roll_deg=np.array([0.0]), scene=scene, knobs=knobs)


def run(cfg) -> dict:
    errormap = optional_import("polarization_compass.errormap")
    est = optional_import("polarization_compass.estimators")
    methods = [m for m in est.estimator_names() if m in ("zenith", "sm_asm", "symmetry", "least_squares")]
    if not methods:
        raise Unavailable("the paper's four estimators are not registered yet")
    target = 40 if cfg.tiny else int(cfg.errormap_cells)
    rows = []
    worker_counts = [1] if cfg.tiny else [1, os.cpu_count() or 1]
    spec = None
    for workers in dict.fromkeys(worker_counts):
        # two sweep sizes: wall = start-up + cells / rate, so the steady rate is the slope
        runs = []
        for size in (target, 3 * target):
            spec = _spec(errormap, methods, size, cfg.tiny)
            cells = spec.cell_count()
            t0 = time.perf_counter()
            m = errormap.run_sweep(spec, out=None, workers=workers, progress=False)
            dt = time.perf_counter() - t0
            runs.append((cells, dt, int(np.count_nonzero(m.valid)) if m is not None else 0))
        (c1, t1, _), (c2, t2, ok2) = runs
        steady = (c2 - c1) / (t2 - t1) if t2 > t1 else c2 / t2
        startup = max(0.0, t1 - c1 / steady)
        rows.append({"workers": workers, "cells": [c1, c2], "wall_s": [t1, t2], "cells_per_s_wall": c2 / t2,
                     "cells_per_s_steady": steady, "startup_s": startup, "valid_cells_of_larger": ok2,
                     "paper_pitch_only_sweep_s": startup + PAPER_PITCH_ONLY_CELLS / steady,
                     "within_2_min_target": bool(startup + PAPER_PITCH_ONLY_CELLS / steady <= 120.0)})
    return {"methods": methods, "grid": {"sun_altitude_deg": spec.sun_altitude_deg.tolist(),
                                         "yaw_count": int(spec.yaw_deg.size), "pitch_deg": spec.pitch_deg.tolist(),
                                         "roll_deg": spec.roll_deg.tolist()},
            "knobs": {m: spec.knobs[m] for m in methods}, "rows": rows,
            "note": "two sweep sizes per worker count; the steady rate is the slope, the start-up (spawn, imports, "
                    "numba cache) the intercept; the 1.4e5-cell estimate is start-up + cells / steady rate"}
