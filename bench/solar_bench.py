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
Solar position throughput: ``spa`` against ``paper``, batch, per call and cached.

Batch against per-call against the per-frame cache (:class:`polarization_compass.solar.SunCache`).
Single core.

Also records how far ``paper`` is from ``spa`` over the batch (great-circle, sun above the
horizon), so the speed of each model sits beside what it costs in accuracy.
"""

from __future__ import annotations

import datetime as _dt
import time

import numpy as np

from .common import optional_import, single_core, time_calls, timing_stats, Unavailable

SITE = (32.026778, 118.853306, 30.0)  # the paper's roof in Nanjing


def _batch_times(n: int, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    start = np.datetime64('2020-01-01T00:00:00', 'us').astype(np.int64)
    span_us = 10 * 365 * 86400 * 10**6
    return (start + rng.integers(0, span_us, n)).astype('datetime64[us]')


def _great_circle_deg(az1, alt1, az2, alt2):
    from polarization_compass.conventions import enu_direction

    a, b = enu_direction(az1, alt1), enu_direction(az2, alt2)
    c = np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)
    s = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(s, c))


def run(cfg) -> dict:
    solar = optional_import('polarization_compass.solar')
    if not hasattr(solar, 'sun_position'):
        raise Unavailable('polarization_compass.solar.sun_position not available')
    lat, lon, alt_m = SITE
    n = 500 if cfg.tiny else int(cfg.solar_batch)
    calls = 5 if cfg.tiny else int(cfg.solar_calls)
    times = _batch_times(n)
    out = {
        'site': {'latitude_deg': lat, 'longitude_deg': lon, 'altitude_m': alt_m},
        'batch_size': n,
        'single_calls': calls,
        'models': {},
    }
    with single_core():
        for model in ('spa', 'paper'):
            row = {}
            batch = time_calls(
                lambda m=model: solar.sun_position(times, lat, lon, alt_m, model=m),
                repeats=3 if not cfg.tiny else 1,
            )
            bs = timing_stats(batch)
            row['batch'] = {**bs, 'positions_per_s': n / (bs['median_ms'] / 1e3)}
            t_single = [
                _dt.datetime(2019, 11, 15, 6, 0, tzinfo=_dt.timezone.utc)
                + _dt.timedelta(seconds=37 * k)
                for k in range(calls)
            ]
            it = iter(t_single * 3)
            per = time_calls(
                lambda m=model: solar.sun_position(next(it), lat, lon, alt_m, model=m),
                repeats=calls,
                warmup=1,
            )
            ps = timing_stats(per)
            row['per_call'] = {**ps, 'positions_per_s': 1e3 / ps['median_ms']}
            if hasattr(solar, 'SunCache'):
                cache = solar.SunCache(lat, lon, alt_m, model=model)
                t_fill0 = time.perf_counter()
                cache(t_single[0])
                fill_ms = (time.perf_counter() - t_fill0) * 1e3
                # frames at 24 Hz within the cache window
                frames = [
                    t_single[0] + _dt.timedelta(seconds=k / 24.0) for k in range(calls * 3 + 2)
                ]
                it2 = iter(frames)
                cached = time_calls(lambda: cache(next(it2)), repeats=calls, warmup=1)
                cs = timing_stats(cached)
                row['cache_per_frame'] = {
                    **cs,
                    'positions_per_s': 1e3 / cs['median_ms'],
                    'first_fill_ms': fill_ms,
                    'speedup_vs_per_call': ps['median_ms'] / cs['median_ms'],
                }
            row['batch_speedup_vs_per_call'] = (
                row['batch']['positions_per_s'] / row['per_call']['positions_per_s']
            )
            out['models'][model] = row
        spa = solar.sun_position(times, lat, lon, alt_m, model='spa')
        pap = solar.sun_position(times, lat, lon, alt_m, model='paper')
        up = np.asarray(spa.altitude_deg) > 0
        gc = _great_circle_deg(
            np.asarray(pap.azimuth_deg)[up],
            np.asarray(pap.altitude_deg)[up],
            np.asarray(spa.azimuth_deg)[up],
            np.asarray(spa.altitude_deg)[up],
        )
        out['paper_vs_spa_great_circle_deg'] = {
            'n_sun_up': int(up.sum()),
            'mean': float(gc.mean()) if gc.size else None,
            'max': float(gc.max()) if gc.size else None,
        }
    try:
        pvlib = optional_import('pvlib')
        out['pvlib_version'] = pvlib.__version__
    except Unavailable:
        out['pvlib_version'] = None
    return out
