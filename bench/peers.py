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
Peers side by side: pyskylumos for the sky render, polanalyser for demosaicing and Stokes.

Optional: neither is a dependency of the project (never in requirements.txt). The peers are looked
for in this interpreter first; if they are not importable here, in the interpreter named by
``--peers-python`` / ``BENCH_PEERS_PYTHON`` (pyskylumos 0.1.3 needs Python >= 3.12, the project
uses 3.11, so a separate venv is the usual way). Otherwise each is recorded as "not installed".
Both sides are timed in the same run at the same image size, single-threaded, and the ratios are
peer time / our time (> 1: we are faster).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

from polarization_compass.camera import CameraModel
from polarization_compass.camera_pixels import PixelSelection
from polarization_compass.conventions import CameraAttitude
from polarization_compass.render import Renderer, SunDirection
from polarization_compass.scene import Scene

from .common import single_core, time_calls, timing_stats

WORKER = Path(__file__).resolve().parent / 'peer_worker.py'


def _peer_results(size, repeats, python):
    """Run the worker in this interpreter (if the peers import here) or in ``python``."""
    args = json.dumps({'width_px': size[0], 'height_px': size[1], 'repeats': repeats})
    here = all(_importable(m) for m in ('pyskylumos',)) or _importable('polanalyser')
    candidates = []
    if here:
        candidates.append(sys.executable)
    if python:
        candidates.append(python)
    if not candidates:
        return {
            'pyskylumos': {'status': 'not installed'},
            'polanalyser': {'status': 'not installed'},
            'interpreter': None,
        }
    merged = {}
    for exe in candidates:
        env = dict(os.environ, OMP_NUM_THREADS='1', OPENBLAS_NUM_THREADS='1', MKL_NUM_THREADS='1')
        try:
            out = subprocess.run(
                [exe, str(WORKER), args], capture_output=True, text=True, timeout=1800, env=env
            )
        except (OSError, subprocess.TimeoutExpired) as exc:
            merged.setdefault('errors', []).append(f'{exe}: {exc}')
            continue
        if out.returncode != 0:
            merged.setdefault('errors', []).append(
                f'{exe}: exit {out.returncode}: {out.stderr.strip()[-300:]}'
            )
            continue
        res = json.loads(out.stdout.strip().splitlines()[-1])
        for peer in ('pyskylumos', 'polanalyser'):
            if merged.get(peer, {}).get('status') != 'ok':
                merged[peer] = dict(
                    res[peer], interpreter=exe, python=res['python'], numpy=res['numpy']
                )
    for peer in ('pyskylumos', 'polanalyser'):
        merged.setdefault(peer, {'status': 'not installed'})
    return merged


def _importable(name):
    import importlib.util

    return importlib.util.find_spec(name) is not None


def _ours(size, repeats):
    cam = CameraModel(width_px=size[0], height_px=size[1])
    sun = SunDirection(135.0, 35.0)
    out = {}
    r = Renderer(Scene(camera=cam), pixels=PixelSelection.full())
    with single_core():
        out['rayleigh_level'] = timing_stats(
            time_calls(lambda: r.render(attitude=CameraAttitude(40, 0, 0), sun=sun), repeats)
        )
        out['rayleigh_tilt_20deg'] = timing_stats(
            time_calls(lambda: r.render(attitude=CameraAttitude(40, 20, 0), sun=sun), repeats)
        )
    try:
        from . import simulator

        every = simulator.ALL_EFFECTS
        for key, demosaic in (
            ('sensor_measurement_superpixel', 'superpixel'),
            ('sensor_measurement_full_resolution', 'bilinear'),
        ):
            rs = Renderer(Scene(camera=cam, sensor=simulator.sensor_config(every, demosaic)))
            with single_core():
                seeds = iter(range(10, 10 + repeats + 2))
                out[key] = timing_stats(
                    time_calls(
                        lambda: rs.render(
                            attitude=CameraAttitude(40, 0, 0), sun=sun, seed=next(seeds)
                        ),
                        repeats,
                    )
                )
        out.update(_our_demosaic(cam, repeats))
    except Exception as exc:  # noqa: BLE001 - sensor/demosaic still being written
        out['sensor_status'] = f'unavailable: {type(exc).__name__}: {exc}'
    return out


def _our_demosaic(cam, repeats):
    """Our mosaic -> AoP/DoP (superpixel and full resolution), if the demosaic module offers it."""
    from . import accuracy

    return accuracy.time_demosaic_only(cam, repeats)


def run(cfg) -> dict:
    size = (2448, 2048) if cfg.mode == 'full' else (612, 512)
    if cfg.tiny:
        size = (192, 160)
    repeats = 3 if cfg.mode == 'full' else 1
    python = cfg.peers_python or os.environ.get('BENCH_PEERS_PYTHON')
    peers = _peer_results(size, repeats, python)
    ours = _ours(size, max(repeats, 2))
    ratios = {}

    def ratio(name, peer_ms, our_ms):
        if peer_ms and our_ms:
            ratios[name] = {
                'peer_ms': peer_ms,
                'ours_ms': our_ms,
                'peer_over_ours': peer_ms / our_ms,
            }

    sk = peers.get('pyskylumos', {})
    if sk.get('status') == 'ok':
        ratio(
            'sky render, level (pyskylumos / ours)',
            sk['rayleigh_level']['median_ms'],
            ours['rayleigh_level']['median_ms'],
        )
        ratio(
            'sky render, 20 deg tilt (pyskylumos / ours)',
            sk['rayleigh_tilt_20deg']['median_ms'],
            ours['rayleigh_tilt_20deg']['median_ms'],
        )
        if 'sensor_measurement_superpixel' in ours:
            ratio(
                'sensor measurement + superpixel demosaic (pyskylumos / ours)',
                sk['sensor_measurement']['median_ms'],
                ours['sensor_measurement_superpixel']['median_ms'],
            )
    pa = peers.get('polanalyser', {})
    if pa.get('status') == 'ok':
        for our_key in ('demosaic_full_resolution_aop_dop',):
            if our_key in ours:
                ratio(
                    'full-resolution demosaic to AoP/DoP (polanalyser / ours)',
                    pa['demosaic_stokes_aolp_dolp']['median_ms'],
                    ours[our_key]['median_ms'],
                )
        if 'demosaic_superpixel_aop_dop' in ours:
            ratio(
                'polanalyser full-resolution vs our superpixel to AoP/DoP',
                pa['demosaic_stokes_aolp_dolp']['median_ms'],
                ours['demosaic_superpixel_aop_dop']['median_ms'],
            )
    return {
        'image_size_px': list(size),
        'repeats': repeats,
        'peers': peers,
        'ours': ours,
        'ratios': ratios,
        'peers_python': python,
        'note': "peer numbers come from the interpreter named in each peer's entry (a separate "
        'venv when '
        "the project's Python is too old for the peer)",
    }
