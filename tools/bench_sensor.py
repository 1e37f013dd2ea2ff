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
Timing of the sensor stages on a full 2448 x 2048 frame.

    .venv/bin/python tools/bench_sensor.py [--repeats N]

For each stage: wall-clock median over N calls with numba's default threads, then the process CPU
time median with numba set to one thread (an estimate of the single-core cost that is less
sensitive to other processes sharing the machine than wall time is). Also times the alternatives we
did not choose: numpy's float32 normal generator and three OpenCV ``filter2D`` passes for the
bilinear Stokes.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numba
import numpy as np


def _measure(fn, repeats):
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall) * 1e3), float(np.median(cpu) * 1e3)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--repeats', type=int, default=9)
    args = ap.parse_args(argv)

    import cv2
    from polarization_compass.conventions import CameraAttitude
    from polarization_compass.demosaic import aop_dop_from_stokes, polarization_from_mosaic
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene
    from polarization_compass.sensor import parse_sensor_config, simulate_mosaic

    att, sun = CameraAttitude(30.0, -20.0, 10.0), SunDirection(100.0, 35.0)
    ideal = Renderer(Scene()).render(attitude=att, sun=sun)
    cfg = parse_sensor_config(
        {
            'exposure': {'fill': 0.45},
            'shot_noise': {},
            'read_noise': {'sigma_e': 2.3},
            'quantization': {'bits': 12},
        }
    )
    rng = np.random.default_rng(0)
    mosaic = simulate_mosaic(ideal.aop_rad, ideal.dop, None, cfg, cfg.layout, rng)
    mosaic_f32 = mosaic.astype(np.float32)
    k = np.outer([0.5, 1, 0.5], [0.5, 1, 0.5]).astype(np.float32)
    h, w = mosaic.shape
    p1 = np.tile(np.float32([[-1, 0], [0, 1]]), (h // 2, w // 2))
    p2 = np.tile(np.float32([[0, 1], [-1, 0]]), (h // 2, w // 2))

    def cv2_stokes():
        m = mosaic.astype(np.float32)
        return (
            cv2.filter2D(m, -1, 0.5 * k, borderType=cv2.BORDER_REFLECT_101),
            cv2.filter2D(m * p1, -1, k, borderType=cv2.BORDER_REFLECT_101),
            cv2.filter2D(m * p2, -1, k, borderType=cv2.BORDER_REFLECT_101),
        )

    renderers = {
        m: Renderer(
            Scene(
                sensor={
                    'exposure': {'fill': 0.45},
                    'shot_noise': {},
                    'read_noise': {},
                    'quantization': {'bits': 12},
                    'demosaic': m,
                }
            )
        )
        for m in ('bilinear', 'superpixel')
    }
    ideal_renderer = Renderer(Scene())
    stages = {
        'mosaic + shot + read noise + 12-bit': lambda: simulate_mosaic(
            ideal.aop_rad, ideal.dop, None, cfg, cfg.layout, rng
        ),
        'demosaic bilinear (uint16 -> AoP/DoP/valid)': lambda: polarization_from_mosaic(
            mosaic, cfg.layout, method='bilinear', saturation_level=4095
        ),
        'demosaic superpixel (uint16 -> AoP/DoP/valid)': lambda: polarization_from_mosaic(
            mosaic, cfg.layout, method='superpixel', saturation_level=4095
        ),
        'ideal render (reference)': lambda: ideal_renderer.render(attitude=att, sun=sun),
        'render + full sensor, bilinear': lambda: renderers['bilinear'].render(
            attitude=att, sun=sun
        ),
        'render + full sensor, superpixel': lambda: renderers['superpixel'].render(
            attitude=att, sun=sun
        ),
        '[not used] numpy Generator.standard_normal float32, 5 Mpx': lambda: rng.standard_normal(
            mosaic.size, dtype=np.float32
        ),
        '[not used] 3 x cv2.filter2D bilinear Stokes (no AoP)': cv2_stokes,
        '[not used] cv2 Stokes, then aop_dop_from_stokes': lambda: aop_dop_from_stokes(
            *cv2_stokes()
        ),
        '[not used] numpy float32 arctan2, 5 Mpx': lambda: np.arctan2(mosaic_f32, mosaic_f32),
    }
    threads = numba.get_num_threads()
    out = {
        'threads': threads,
        'cv2_threads': cv2.getNumThreads(),
        'load_average': os.getloadavg(),
        'ms': {},
    }
    for name, fn in stages.items():
        wall, _ = _measure(fn, args.repeats)
        numba.set_num_threads(1)
        cv2.setNumThreads(1)
        try:
            _, cpu1 = _measure(fn, args.repeats)
        finally:
            numba.set_num_threads(threads)
            cv2.setNumThreads(out['cv2_threads'])
        out['ms'][name] = {'wall_median': round(wall, 1), 'cpu_one_thread_median': round(cpu1, 1)}
        print(
            f'{name:58s} wall {wall:7.1f} ms ({threads} threads)   1-thread CPU {cpu1:7.1f} ms',
            flush=True,
        )
    out['load_average_after'] = os.getloadavg()
    print(json.dumps(out))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
