"""Error-map benchmark: speed of a 1.4e5-cell pitch-only sweep for the paper's four methods, and what the
default sweep sampling costs in accuracy against full resolution.

    python -m bench.errormap_sampling              # the whole sweep (1.42e5 cells x 4 methods)
    python -m bench.errormap_sampling --fraction 0.1 # every 10th sun altitude, time extrapolated

Sweep: sun altitude 0:50:1 (51) x yaw -180:176:4 (90) x pitch -30:30:2 (31) x roll 0 = 142 290 cells.
Accuracy: random cells (sun 0-50, tilt |p|+|r| <= 30), each method at the default sweep sampling
(``errormap.DEFAULT_SWEEP_KNOBS``) and at full resolution (stride 1); the largest |difference| of the error.
(bench/errormap_bench.py measures the engine's steady-state throughput; this one runs the sweep itself.)
Prints one JSON object; the machine's load average is recorded because the machine may be shared.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

METHODS = ("zenith", "sm_asm", "symmetry", "least_squares")


def speed(fraction: float, workers: int | None) -> dict:
    from polarization_compass.errormap import SweepSpec, run_sweep
    spec = SweepSpec(list(METHODS), np.arange(0.0, 50.1, 1.0), np.arange(-180.0, 176.1, 4.0),
                     np.arange(-30.0, 30.1, 2.0), [0.0])
    cells = spec.sun_altitude_deg.size * spec.yaw_deg.size * spec.pitch_deg.size
    step = max(1, int(round(1 / fraction)))
    if step > 1:                                  # every step-th sun altitude; time extrapolated
        spec = SweepSpec(list(METHODS), spec.sun_altitude_deg[::step], spec.yaw_deg, spec.pitch_deg, [0.0])
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    m = run_sweep(spec, workers=workers, progress=False)
    dt = time.perf_counter() - t0
    done = spec.sun_altitude_deg.size * spec.yaw_deg.size * spec.pitch_deg.size
    return {"cells_full_sweep": cells, "cells_run": done, "methods": list(METHODS),
            "estimates_run": done * len(METHODS), "seconds": round(dt, 1),
            "seconds_extrapolated_full": round(dt * cells / done, 1), "workers": m.meta["workers"],
            "ms_per_cell_all_methods_per_worker": round(dt * m.meta["workers"] / done * 1e3, 3),
            "loadavg_before": load0, "loadavg_after": os.getloadavg(), "cpus": os.cpu_count(),
            "valid_fraction": float(m.valid.mean()), "sampling": m.meta["sampling"]}


def accuracy(n_cells: int, seed: int) -> dict:
    import numba
    numba.set_num_threads(max(1, (os.cpu_count() or 1)))
    from polarization_compass.conventions import CameraAttitude, fold_axial_deg
    from polarization_compass.errormap import DEFAULT_SWEEP_KNOBS
    from polarization_compass.estimators import make_estimator
    from polarization_compass.estimators.base import Observation
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import default_scene
    rng = np.random.default_rng(seed)
    scene = default_scene()
    cells = []
    while len(cells) < n_cells:
        p, r = rng.uniform(-30, 30, 2)
        if abs(p) + abs(r) <= 30:
            cells.append((float(rng.uniform(0, 50)), float(rng.uniform(-180, 180)), float(p), float(r)))
    out = {}
    for method in METHODS:
        errs = {}
        try:
            full = {"stride": 1}
            make_estimator(method, **full)
        except Exception:            # no stride knob (zenith reads its window): its default is full resolution
            full = {}
        for label, knobs in (("default", DEFAULT_SWEEP_KNOBS.get(method, {})), ("full", full)):
            est = make_estimator(method, **knobs)
            renderer = Renderer(scene, pixels=est.pixels_needed(scene.camera))
            e = []
            t0 = time.perf_counter()
            for h, y, p, r in cells:
                f = renderer.render(attitude=CameraAttitude(y, p, r), sun=SunDirection(0.0, h))
                obs = Observation(f.aop_rad, f.dop, f.valid, f.rays_cam, f.x_px, f.y_px, scene.camera, 0.0, h,
                                  f.intensity, p, r, None)
                res = est.estimate(obs)
                e.append(float(fold_axial_deg(res.psi_deg - y)) if res.ok else np.nan)
            errs[label] = (np.array(e), (time.perf_counter() - t0) / len(cells), renderer.pixels.count)
        d = np.abs(fold_axial_deg(errs["default"][0] - errs["full"][0]))
        out[method] = {"max_abs_diff_deg": float(np.nanmax(d)), "failed": int(np.isnan(d).sum()),
                       "pixels_default": errs["default"][2], "pixels_full": errs["full"][2],
                       "ms_per_estimate_default": round(errs["default"][1] * 1e3, 2),
                       "ms_per_estimate_full": round(errs["full"][1] * 1e3, 1),
                       "max_abs_error_deg": float(np.nanmax(np.abs(errs["full"][0])))}
    return {"cells": n_cells, "seed": seed, "per_method": out}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fraction", type=float, default=1.0, help="share of the sweep to run (time extrapolated)")
    ap.add_argument("--workers", type=int, help="processes (default: all cores)")
    ap.add_argument("--accuracy-cells", type=int, default=24, help="random cells for the sampling check")
    ap.add_argument("--skip-speed", action="store_true")
    ap.add_argument("--skip-accuracy", action="store_true")
    a = ap.parse_args(argv)
    report = {}
    if not a.skip_accuracy:
        report["sampling_vs_full_resolution"] = accuracy(a.accuracy_cells, 1)
    if not a.skip_speed:
        report["pitch_only_sweep"] = speed(min(1.0, max(1e-3, a.fraction)), a.workers)
    json.dump(report, sys.stdout, indent=1)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
