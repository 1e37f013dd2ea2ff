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
Benchmark suite for polarization_compass: what accuracy costs in time (issue 7).

Run with ``make bench`` (full) or ``make bench-quick`` (``python -m bench.run --quick``). Each
group of measurements lives in its own module and writes ``bench/results/<group>.json``;
``bench.report`` turns them into ``summary.md`` and the Pareto plot. Not part of ``make test``
(only a smoke test is).

Importing this package pins BLAS/OpenMP to one thread when numpy has not been imported yet, so
that per-estimate timings are single-core; numba's thread count is set per measurement.
"""

import os
import sys

if 'numpy' not in sys.modules:
    for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
        os.environ[_var] = '1'

__all__ = ['GROUPS']

#: Benchmark groups in run order: name -> module (``bench.<module>``) with ``run(cfg) -> dict``.
GROUPS = {
    'crb': 'crb',
    'accuracy': 'accuracy',
    'simulator': 'simulator',
    'solar': 'solar_bench',
    'errormap': 'errormap_bench',
    'errormap_sampling': 'errormap_sampling',
    'pipeline': 'pipeline',
    'estimator_speed': 'estimator_speed',
    'sky_check': 'sky_check',
    'debug_image': 'debug_image',
    'photodiode': 'photodiode_bench',
    'replay': 'replay_bench',
    'graph': 'graph_bench',
    'peers': 'peers',
}
