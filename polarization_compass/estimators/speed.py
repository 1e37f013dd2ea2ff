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
Time each estimator from a raw 2448 x 2048 12-bit mosaic on one core.

The time is demosaic (only the pixels the method reads) + estimate. ``python -m
polarization_compass.estimators.speed [--repeat N] [--json]``.

Reports, per method and setting, the minimum and median wall time and the minimum CPU time of the
process (``time.process_time``, less sensitive to other load on a shared machine) over ``--repeat``
runs, after a warm-up run (numba compilation and caches). The mosaic is a noisy render of the
IMX250MZR scene (config/scenes/imx250mzr_noisy.yaml).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time

#: (label, method, knobs[, occluded]): the defaults, and the sampling knobs that trade accuracy for
#: time. ``occluded``: half the image (a half-plane through the principal point, 30 deg from the
#: meridian) marked invalid, which sends sm_asm and symmetry through their mirror-pair search.
SETTINGS = [
    ('zenith default (32 px window)', 'zenith', {}),
    ('sm_asm default (stride 8)', 'sm_asm', {}),
    ('sm_asm stride 16', 'sm_asm', {'stride': 16}),
    ('sm_asm default, half occluded', 'sm_asm', {}, True),
    ('symmetry default (stride 8, K 2)', 'symmetry', {}),
    ('symmetry stride 16', 'symmetry', {'stride': 16}),
    ('symmetry default, half occluded', 'symmetry', {}, True),
    ('least_squares superpixels (all)', 'least_squares', {}),
    ('least_squares stride 4', 'least_squares', {'stride': 4}),
    ('tilt_aware superpixels (all)', 'tilt_aware', {}),
    ('tilt_aware stride 8', 'tilt_aware', {'stride': 8}),
]


def measure(repeat: int = 15, threads: int = 1, settings=SETTINGS) -> list[dict]:
    """
    Time each setting on one noisy IMX250MZR mosaic: demosaic of its pixels plus estimate.

    The mosaic is rendered once (bearing 40 deg, pitch 5 deg, roll -3 deg, sun at azimuth 0 deg
    and altitude 35 deg, seed 1); each setting runs once to warm up, then ``repeat`` times.

    Parameters
    ----------
    repeat : int, default 15
        Timed runs per setting.
    threads : int, default 1
        numba threads (``numba.set_num_threads``).
    settings : list of tuple, default :data:`SETTINGS`
        ``(label, method, knobs[, occluded])`` per row.

    Returns
    -------
    list of dict
        One row per setting: ``setting``, ``method``, ``knobs``, ``occluded``, ``pixels`` (the
        pixels the estimate used), ``wall_ms_min`` and ``wall_ms_median`` [ms], ``cpu_ms_min``
        [ms, process CPU time], ``error_deg`` (estimated minus true yaw psi [deg], wrapped to
        [-90, 90); None without an estimate), ``sigma_deg`` [deg] and ``status``.

    """
    import numba
    import numpy as np

    from . import make_estimator
    from .mosaic_input import observation_from_mosaic
    from ..conventions import CameraAttitude
    from ..render import Renderer, SunDirection
    from ..scene_load import load_scene

    numba.set_num_threads(threads)
    from pathlib import Path

    cfg = Path(__file__).resolve().parents[2] / 'config' / 'scenes' / 'imx250mzr_noisy.yaml'
    scene = load_scene(str(cfg))
    frame = Renderer(scene).render(
        attitude=CameraAttitude(40.0, 5.0, -3.0), sun=SunDirection(0.0, 35.0), seed=1
    )
    mosaic = frame.mosaic
    cam = scene.camera
    rows = []
    for label, name, knobs, *occluded in settings:
        est = make_estimator(name, **knobs)
        sel = est.pixels_needed(cam)
        edge = math.radians(-40.0 + 30.0)  # the meridian's image axis is -psi = -40 deg

        def once():
            obs = observation_from_mosaic(
                mosaic,
                cam,
                0.0,
                35.0,
                method='superpixel',
                selection=sel,
                saturation_level=4095,
                pitch_deg=5.0,
                roll_deg=-3.0,
            )
            if occluded and occluded[0]:
                u = np.asarray(obs.x_px) - cam.cx_px
                v = np.asarray(obs.y_px) - cam.cy_px
                obs.valid = obs.valid & (u * math.cos(edge) - v * math.sin(edge) >= 0.0)
            return est.estimate(obs)

        res = once()  # warm-up: compilation, ray caches
        wall, cpu = [], []
        for _ in range(repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            res = once()
            cpu.append(time.process_time() - c0)
            wall.append(time.perf_counter() - t0)
        rows.append(
            {
                'setting': label,
                'method': name,
                'knobs': knobs,
                'occluded': bool(occluded and occluded[0]),
                'pixels': res.pixels,
                'wall_ms_min': 1e3 * min(wall),
                'wall_ms_median': 1e3 * statistics.median(wall),
                'cpu_ms_min': 1e3 * min(cpu),
                'error_deg': None
                if res.psi_deg is None
                else float(((res.psi_deg - 40.0 + 90.0) % 180.0) - 90.0),
                'sigma_deg': res.sigma_deg,
                'status': res.status.value,
            }
        )
    return rows


def main(argv=None) -> int:
    """
    Run :func:`measure` from the command line and print a table or JSON.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (``--repeat N``, ``--threads N``, ``--json``); default ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit status 0 (argparse exits 2 itself on bad arguments).

    """
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument('--repeat', type=int, default=15)
    p.add_argument('--threads', type=int, default=1)
    p.add_argument('--json', action='store_true')
    a = p.parse_args(argv)
    rows = measure(a.repeat, a.threads)
    if a.json:
        json.dump(rows, sys.stdout, indent=1)
        sys.stdout.write('\n')
        return 0
    print(
        f'{"setting":36s} {"pixels":>9s} {"wall min":>9s} {"median":>8s} {"cpu min":>8s} '
        f'{"error":>8s} {"sigma":>8s}'
    )
    for r in rows:
        err = '-' if r['error_deg'] is None else f'{r["error_deg"]:8.4f}'
        sig = r['status'] if r['sigma_deg'] is None else f'{r["sigma_deg"]:8.4f}'
        print(
            f'{r["setting"]:36s} {r["pixels"]:9d} {r["wall_ms_min"]:8.2f}  '
            f'{r["wall_ms_median"]:7.2f}  '
            f'{r["cpu_ms_min"]:7.2f}  {err:>8s} {sig:>8s}'
        )
    return 0


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
