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
Issue 28: what a photodiode array's checks and its mount calibration cost.

One core, the shipped 8-unit geometry (``config/arrays/pol_op_8unit.yaml``) mounted at pitch -3,
roll -2 deg, three simulated turns in place of 72 samples each (2 % noise, sun at 60 deg):

* ``estimate_per_sample_ms``: :func:`~polarization_compass.photodiode.heading.estimate_recording`
  per sample, ``tilt_aware`` and ``least_squares`` (the readings checks, the side rule and the
  sigma are inside it);
* ``wiring_check_s``: what :func:`~polarization_compass.photodiode.selfcheck.
  estimate_recording_checked` adds per recording (the seven wiring hypotheses);
* ``mount_fit_s``: :func:`~polarization_compass.mount_fit.fit_mount` on the three turns (the Stokes
  fit and the samples first, then the fit), and how far the fitted mount is from the simulated one
  in its sigmas.
"""

from __future__ import annotations

from pathlib import Path
import time

import numpy as np

from .common import single_core, timing_stats

ROOT = Path(__file__).resolve().parent.parent
TRUE_MOUNT_DEG = (-3.0, -2.0)
SUN_AZ_DEG, SUN_ALT_DEG = 135.0, 60.0
SAMPLES_PER_TURN = 72


def _turns(geometry, rng, samples_per_turn=SAMPLES_PER_TURN):
    """Return readings, IMU yaw [rad] and turn label of three simulated turns (mounted sensor)."""
    from polarization_compass.mount import Mount
    from polarization_compass.photodiode.simulate import simulate_readings

    mounted = geometry.with_mount(Mount(*TRUE_MOUNT_DEG))
    out = []
    for k, offset_deg in enumerate((10.0, 13.5, 200.0)):
        yaw = np.radians(np.linspace(0.0, 360.0, samples_per_turn, endpoint=False))
        bearing = offset_deg - np.degrees(yaw)
        inten = simulate_readings(
            mounted, SUN_AZ_DEG, SUN_ALT_DEG, bearing, noise_rel=0.02, rng=rng
        )
        out.append((inten, yaw, np.full(samples_per_turn, k)))
    return out


def _estimate_costs(geometry, turns, repeats: int) -> dict:
    from polarization_compass.photodiode.heading import estimate_recording, make_array_estimator
    from polarization_compass.photodiode.selfcheck import estimate_recording_checked

    inten = np.concatenate([t[0] for t in turns])
    n = len(inten)
    out = {}
    for method in ('tilt_aware', 'least_squares'):
        est = make_array_estimator(method, geometry)
        args = (est, inten, SUN_AZ_DEG, SUN_ALT_DEG, 0.0, 0.0)
        plain = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            estimate_recording(*args)
            plain.append((time.perf_counter() - t0) / n * 1e3)
        t0 = time.perf_counter()
        estimate_recording_checked(*args)
        checked_s = time.perf_counter() - t0
        out[method] = {
            'estimate_per_sample_ms': timing_stats(np.array(plain) / 1e3),
            'wiring_check_s': round(checked_s - float(np.median(plain)) * n / 1e3, 3),
            'samples': n,
        }
    return out


def _mount_costs(geometry, turns) -> dict:
    from polarization_compass.mount_fit import concat, fit_mount, turn_samples
    from polarization_compass.photodiode.stokes import fit_stokes

    t0 = time.perf_counter()
    parts = [
        turn_samples(fit_stokes(i, geometry), geometry, y, t, SUN_AZ_DEG, SUN_ALT_DEG)
        for i, y, t in turns
    ]
    d = concat(parts)
    t1 = time.perf_counter()
    fit = fit_mount(geometry, d)
    t2 = time.perf_counter()
    est = np.array([fit.mount.pitch_deg, fit.mount.roll_deg])
    sig = np.array([fit.mount.pitch_sigma_deg, fit.mount.roll_sigma_deg])
    return {
        'samples_s': round(t1 - t0, 3),
        'fit_s': round(t2 - t1, 3),
        'pitch_roll_deg': [round(float(v), 4) for v in est],
        'sigma_deg': [round(float(v), 4) for v in sig],
        'error_in_sigmas': [round(float(v), 2) for v in (est - TRUE_MOUNT_DEG) / sig],
    }


def run(cfg) -> dict:
    from polarization_compass.photodiode.geometry import load_array_geometry

    geometry = load_array_geometry(ROOT / 'config' / 'arrays' / 'pol_op_8unit.yaml')
    # tiny (the smoke test): 24 samples a turn, enough to determine the mount
    n = 24 if cfg.mode == 'tiny' else SAMPLES_PER_TURN
    turns = _turns(geometry, np.random.default_rng(7), n)
    with single_core():
        out = {'estimate': _estimate_costs(geometry, turns, 5 if cfg.mode == 'full' else 2)}
        out['mount'] = _mount_costs(geometry, turns)
    out['notes'] = (
        f'3 simulated turns x {n} samples of the shipped 8-unit geometry mounted '
        f'at pitch {TRUE_MOUNT_DEG[0]}, roll {TRUE_MOUNT_DEG[1]} deg, sun {SUN_ALT_DEG} deg, 2 % '
        'noise; one core'
    )
    return out
