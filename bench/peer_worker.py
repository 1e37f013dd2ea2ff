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
Times the peer libraries (pyskylumos, polanalyser) in whatever interpreter runs this file.

Standalone on purpose: it imports neither ``bench`` nor ``polarization_compass`` (a peer may need a
Python this project does not use; pyskylumos 0.1.3 needs >= 3.12). Prints one JSON object on
stdout. Usage: ``python bench/peer_worker.py '{"width_px": 2448, "height_px": 2048, "repeats":
3}'``. Each measurement is single-threaded (OpenCV and BLAS limited to one thread) and either a
result or ``{"status": "not installed" | "failed: ..."}``.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402


def _times(fn, repeats):
    fn()  # warm-up (imports, caches)
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    s = np.asarray(out) * 1e3
    return {
        'n': len(out),
        'median_ms': float(np.median(s)),
        'p95_ms': float(np.percentile(s, 95)),
        'min_ms': float(s.min()),
    }


def pyskylumos_bench(width, height, repeats):
    try:
        from astropy.coordinates import EarthLocation
        from astropy.time import Time
        import pyskylumos
        from pyskylumos.engine import Engine
        from pyskylumos.sensor import SlicingPattern
    except ImportError as exc:
        return {'status': 'not installed', 'detail': str(exc)}
    try:
        slicing = {
            90: SlicingPattern(start_row=0, start_column=0, step=2),
            45: SlicingPattern(start_row=0, start_column=1, step=2),
            135: SlicingPattern(start_row=1, start_column=0, step=2),
            0: SlicingPattern(start_row=1, start_column=1, step=2),
        }
        engine = Engine(
            sensor_pixel_pitch_micrometers=3.45,
            lens_conjugation_type='thin',
            number_pixels_vertical=height,
            number_pixels_horizontal=width,
            lens_focal_length_micrometers=4000.0,
            polarizer_tolerance_radians=0.0,
            extinction_ratio=0.99,
            auto_exposure_saturation_fraction=0.9,
            adc_resolution_bits=12,
            multiplicative_noise_snr=100,
            wire_grid_orientations_slicing=slicing,
            random_seed=0,
        )
        az, alt = engine.get_initial_azimuth_altitude()
        site = EarthLocation(lat=32.026778, lon=118.853306, height=30.0)
        times = Time(['2019-11-15T06:00:00'])

        def sky(tilt_rad=None):
            kw = {}
            if tilt_rad is not None:
                kw = {
                    'sensor_azimuthal_tilt_radians': 0.0,
                    'sensor_tilt_angle_radians': float(tilt_rad),
                }
            return engine.simulate_sky_polarization(
                sky_model='RAYLEIGH',
                observation_location=site,
                times=times,
                cie_sky_type=12,
                altitudes=alt,
                azimuths=az,
                **kw,
            )

        level = _times(lambda: sky(None), repeats)
        tilted = _times(lambda: sky(np.radians(20.0)), repeats)
        vals, names = sky(None)
        d = dict(zip(names, vals))
        meas = _times(
            lambda: engine.simulate_measurement(
                degree_of_polarization=d['degree of polarization'],
                angle_of_polarization=d['angle of polarization'],
                radiance=d['radiance'],
            ),
            repeats,
        )
        return {
            'status': 'ok',
            'version': pyskylumos.__version__
            if hasattr(pyskylumos, '__version__')
            else _dist_version('pyskylumos'),
            'rayleigh_level': level,
            'rayleigh_tilt_20deg': tilted,
            'sensor_measurement': meas,
            'note': 'Engine.simulate_sky_polarization (RAYLEIGH, float64, astropy sun) on the '
            "lens' own "
            '2448x2048 direction grid; simulate_measurement = mosaic, noise, ADC, demosaic',
        }
    except Exception as exc:  # noqa: BLE001 - report, do not crash the suite
        return {'status': f'failed: {type(exc).__name__}: {exc}'}


def polanalyser_bench(width, height, repeats):
    try:
        import cv2
        import polanalyser as pa
    except ImportError as exc:
        return {'status': 'not installed', 'detail': str(exc)}
    try:
        cv2.setNumThreads(1)
        rng = np.random.default_rng(0)
        raw = rng.integers(0, 4096, size=(height, width), dtype=np.uint16)
        angles = np.radians([0, 45, 90, 135])

        def demosaic():
            return pa.demosaicing(raw, pa.COLOR_PolarMono)

        def demosaic_stokes():
            imgs = pa.demosaicing(raw, pa.COLOR_PolarMono)
            s = pa.calcLinearStokes(np.asarray(imgs, dtype=np.float32), angles)
            return pa.cvtStokesToAoLP(s), pa.cvtStokesToDoLP(s)

        return {
            'status': 'ok',
            'version': _dist_version('polanalyser'),
            'opencv': cv2.__version__,
            'demosaic_bilinear': _times(demosaic, repeats),
            'demosaic_stokes_aolp_dolp': _times(demosaic_stokes, repeats),
            'note': 'polanalyser.demosaicing(COLOR_PolarMono, OpenCV bilinear, full resolution) '
            'then '
            'calcLinearStokes + cvtStokesToAoLP/DoLP, one OpenCV thread',
        }
    except Exception as exc:  # noqa: BLE001
        return {'status': f'failed: {type(exc).__name__}: {exc}'}


def _dist_version(name):
    try:
        from importlib.metadata import version

        return version(name)
    except Exception:  # noqa: BLE001
        return None


def main(argv):
    cfg = json.loads(argv[1]) if len(argv) > 1 else {}
    w, h, r = (
        int(cfg.get('width_px', 2448)),
        int(cfg.get('height_px', 2048)),
        int(cfg.get('repeats', 3)),
    )
    out = {
        'python': platform.python_version(),
        'executable': sys.executable,
        'numpy': np.__version__,
        'pyskylumos': pyskylumos_bench(w, h, r),
        'polanalyser': polanalyser_bench(w, h, r),
    }
    print(json.dumps(out))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
