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
Shared machinery of the benchmarks.

Machine description, single-core timing, memory, error statistics, JSON output and the quick/full
configuration.

Timings are wall-clock (``time.perf_counter``) of one call each, reported as median and 95th
percentile in milliseconds. "Single core" means numba's thread pool set to 1 thread and BLAS/OpenMP
pinned to 1 thread (see ``bench/__init__``). Peak memory is measured in a separate call from the
timed ones: the growth of the process' resident set over one call (the kernel's high-water mark,
reset just before the call, so it sees numba kernels', numpy's, OpenCV's and Python's allocations
alike) and, in another call, the ``tracemalloc`` peak (numpy, Python and numba-runtime allocations;
not other C code's ``malloc``). See :func:`peak_memory`.
"""

from __future__ import annotations

import contextlib
import ctypes
from dataclasses import asdict, dataclass, field
import datetime as _dt
import gc
import json
import math
import os
from pathlib import Path
import platform
import subprocess
import time
import tracemalloc

import numpy as np

__all__ = [
    'BenchConfig',
    'machine_info',
    'load_average',
    'single_core',
    'time_calls',
    'timing_stats',
    'peak_memory',
    'error_stats',
    'write_json',
    'read_json',
    'finite_or_none',
    'RESULTS_DIR',
    'Unavailable',
    'Skipped',
    'optional_import',
]

RESULTS_DIR = Path(__file__).resolve().parent / 'results'
REPO_DIR = Path(__file__).resolve().parent.parent


@dataclass
class BenchConfig:
    """
    How much to measure.

    ``quick`` is for checking the suite (< 2 min in all); ``full`` for numbers.
    """

    mode: str = 'quick'
    scenes: int = 3  # seeded random scenes per condition
    repeats: int = 2  # timed calls per scene (after one untimed warm-up per configuration)
    render_repeats: int = 3  # timed renders per simulator configuration
    solar_batch: int = 10000  # timestamps per batch call
    solar_calls: int = 30  # single-timestamp calls
    errormap_cells: int = 60  # cells in the error-map throughput sweep (approximate)
    pipeline_frames: int = 10
    crb_sun_altitudes_deg: tuple = (10.0, 20.0, 30.0, 50.0, 80.0)
    conditions: tuple = ()  # empty: all
    methods: tuple = ()  # empty: all registered
    knob_sets: str = 'quick'  # "quick" | "full"
    out_dir: Path = field(default_factory=lambda: RESULTS_DIR)
    peers_python: str | None = None  # an interpreter where the peers are installed (subprocess)
    tiny: bool = False  # smoke-test size: small camera, 1-2 scenes
    error_map: str | None = (
        None  # map for tilted_corrected (default $BENCH_ERROR_MAP, else the shipped one)
    )
    speed_repeats: int = 10  # estimator_speed: timed front-end calls per method and attitude
    graph_turns: float = (
        0.25  # graph: `sim --realtime --turns` (full: 0.5 = 180 frames at 10 deg/s, 10 Hz)
    )
    graph_turn_rate: float = (
        60.0  # graph: `sim --turn-rate` deg/s (quick: 0.25 turn at 60 deg/s = 15 frames)
    )
    replay_duration_s: float = 3.0  # replay: `record-sim --duration` (full: 20 s)
    # groups named with --only (graph runs in quick mode only when named)
    explicit_groups: tuple = ()

    @staticmethod
    def quick(**kw) -> 'BenchConfig':
        return BenchConfig(**kw)

    @staticmethod
    def full(**kw) -> 'BenchConfig':
        base = {
            'mode': 'full',
            'scenes': 24,
            'repeats': 3,
            'render_repeats': 20,
            'solar_batch': 100000,
            'solar_calls': 200,
            'errormap_cells': 2000,
            'pipeline_frames': 50,
            'speed_repeats': 30,
            'graph_turns': 0.5,
            'graph_turn_rate': 10.0,
            'replay_duration_s': 20.0,
            'crb_sun_altitudes_deg': (5.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0),
            'knob_sets': 'full',
        }
        base.update(kw)
        return BenchConfig(**base)

    def to_json(self) -> dict:
        d = asdict(self)
        d['out_dir'] = str(self.out_dir)
        return d


# ------------------------------------------------------------------------------------------------
# Machine and load
# ------------------------------------------------------------------------------------------------
def _cpu_model() -> str:
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _ram_gib() -> float | None:
    try:
        for line in Path('/proc/meminfo').read_text().splitlines():
            if line.startswith('MemTotal:'):
                return round(int(line.split()[1]) / 2**20, 2)
    except OSError:
        pass
    return None


def _version(mod: str) -> str | None:
    try:
        m = __import__(mod)
    except Exception:  # noqa: BLE001 - any import failure means "not available"
        return None
    return str(getattr(m, '__version__', 'unknown'))


def _git(*args) -> str | None:
    try:
        out = subprocess.run(
            ['git', *args], cwd=REPO_DIR, capture_output=True, text=True, timeout=10
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def machine_info() -> dict:
    """CPU, cores, RAM, library versions, date and git commit of this run."""
    import numba

    status = _git('status', '--porcelain', '--untracked-files=no')
    return {
        'cpu_model': _cpu_model(),
        'logical_cores': os.cpu_count(),
        'usable_cores': len(os.sched_getaffinity(0))
        if hasattr(os, 'sched_getaffinity')
        else os.cpu_count(),
        'ram_gib': _ram_gib(),
        'platform': platform.platform(),
        'python': platform.python_version(),
        'numpy': np.__version__,
        'numba': numba.__version__,
        'opencv': _version('cv2'),
        'scipy': _version('scipy'),
        'pvlib': _version('pvlib'),
        'date_utc': _dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'),
        'git_commit': _git('rev-parse', 'HEAD'),
        'git_dirty': bool(status) if status is not None else None,
        'numba_default_threads': int(numba.config.NUMBA_NUM_THREADS),
        'env_threads': {
            k: os.environ.get(k)
            for k in (
                'OMP_NUM_THREADS',
                'OPENBLAS_NUM_THREADS',
                'MKL_NUM_THREADS',
                'NUMBA_NUM_THREADS',
            )
        },
    }


def load_average() -> list[float]:
    """1, 5 and 15 minute load averages (other work on the machine inflates timings)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return []


# ------------------------------------------------------------------------------------------------
# Timing and memory
# ------------------------------------------------------------------------------------------------
@contextlib.contextmanager
def single_core():
    """Numba's parallel kernels on one thread for the duration (BLAS is pinned at import)."""
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


@contextlib.contextmanager
def numba_threads(n: int | None):
    """Numba's thread count for the duration; ``None`` leaves it (all cores)."""
    import numba

    previous = numba.get_num_threads()
    if n is not None:
        numba.set_num_threads(max(1, min(int(n), int(numba.config.NUMBA_NUM_THREADS))))
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def time_calls(fn, repeats: int, warmup: int = 1) -> list[float]:
    """Seconds per call of ``fn()``, ``repeats`` timed calls after ``warmup`` untimed ones."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def timing_stats(seconds) -> dict:
    """Median, 95th percentile, min and count of a list of durations, in milliseconds."""
    s = np.asarray(list(seconds), dtype=float) * 1e3
    if s.size == 0:
        return {'n': 0, 'median_ms': None, 'p95_ms': None, 'min_ms': None}
    return {
        'n': int(s.size),
        'median_ms': float(np.median(s)),
        'p95_ms': float(np.percentile(s, 95)),
        'min_ms': float(s.min()),
    }


_STATUS = Path('/proc/self/status')
_CLEAR_REFS = Path('/proc/self/clear_refs')


def _status_kib(*fields: str) -> dict[str, int]:
    """``VmRSS``/``VmHWM``... of this process from /proc/self/status, in KiB."""
    out = {}
    for line in _STATUS.read_text().splitlines():
        key, _, rest = line.partition(':')
        if key in fields:
            out[key] = int(rest.split()[0])
    return out


def _reset_rss_peak() -> bool:
    """
    Reset the kernel's resident high-water mark (VmHWM) to the current resident size.

    Works on Linux >= 4.0 (``echo 5 > /proc/self/clear_refs``); returns False where that is not
    possible.
    """
    try:
        _CLEAR_REFS.write_text('5')
    except OSError:
        return False
    return True


_libc_trim = None


def _release_free_heap() -> None:
    """
    Give the C heap's free pages back to the kernel (glibc ``malloc_trim(0)``).

    A call that reuses them then has to fault them in again and shows in the resident set. glibc
    keeps freed blocks resident: those below its (dynamic) mmap threshold, up to 32 MiB, and
    everything when :func:`polarization_compass.runtime.keep_large_buffers_in_heap` applies (the
    replay does).
    """
    global _libc_trim
    if _libc_trim is None:
        try:
            _libc_trim = ctypes.CDLL('libc.so.6').malloc_trim
            _libc_trim.argtypes = (ctypes.c_size_t,)
            _libc_trim.restype = ctypes.c_int
        except (OSError, AttributeError):
            _libc_trim = False
    if _libc_trim:
        _libc_trim(0)


def _numba_alloc_count():
    """Numba runtime (NRT) allocations so far, or None when its statistics are off."""
    from numba.core.runtime import _nrt_python as nrt

    return int(nrt.memsys_get_stats_alloc()) if nrt.memsys_stats_enabled() else None


def peak_memory(fn) -> dict:
    """
    Peak memory of one call of ``fn()`` (call it once beforehand to compile and warm caches).

    Two extra calls, neither timed, give two figures (MiB):

    1. ``resident_peak_mib`` (the headline figure): the process' peak resident set during the call
       minus its resident set just before it. Before the call: ``gc.collect()``, glibc
       ``malloc_trim(0)`` (freed heap pages go back to the kernel, so a call reusing them counts:
       glibc keeps freed blocks up to 32 MiB resident, and everything once
       :func:`polarization_compass.runtime.keep_large_buffers_in_heap` applied) and a reset of the
       kernel's high-water mark (``/proc/self/clear_refs`` = 5); after it: ``VmHWM`` from
       ``/proc/self/status``. Counted: every page the call touches that was not resident, whoever
       allocated it: arrays that numba kernels allocate internally, numpy and Python objects,
       OpenCV's and other C libraries' own ``malloc`` buffers, the first touch of lazily loaded
       code or data. Not counted: memory allocated but never written (numpy's ``np.zeros`` is
       ``calloc``: its untouched pages are not resident), memory already resident before the call
       (caches the warm-up filled), swapped-out pages. Allocations by other threads of the process
       during the call are counted with it (the benchmarks make one call at a time). Resolution: a
       page (4 KiB) plus allocator granularity (pymalloc arenas of 1 MiB are touched page by page).
       None, with ``resident_method`` saying why, where the high-water mark cannot be reset (not
       Linux, or /proc not writable).
    2. ``tracemalloc_peak_mib``: the ``tracemalloc`` peak above the traced size at the start of the
       call: numpy buffers (touched or not), Python objects, and numba kernels' arrays (numba's
       runtime allocates through ``PyMem_RawMalloc``, which tracemalloc traces:
       ``numba/core/runtime/nrt.py`` installs it at import in numba 0.68); not OpenCV's, BLAS's or
       other C code's own ``malloc``. Measured in a call of its own because tracing adds memory and
       time.

    ``numba_allocations``: numba runtime (NRT) allocations during the first call. numba's NRT
    statistics count allocations and frees, not bytes; they are switched on for that call only
    (unless ``NUMBA_NRT_STATS`` had them on already).

    The previous figure, the growth of ``ru_maxrss``, is gone: it only grows on a new process-wide
    peak, so after the warm-up call it read 0 for almost every call.
    """
    from numba.core.runtime import _nrt_python as nrt

    # 1. resident set: everything the call touches
    stats_were_on = bool(nrt.memsys_stats_enabled())
    if not stats_were_on:
        nrt.memsys_enable_stats()
    try:
        gc.collect()
        _release_free_heap()
        method = 'VmHWM growth (clear_refs reset, after malloc_trim)'
        try:
            reset = _reset_rss_peak()
            rss0 = _status_kib('VmRSS')['VmRSS'] if reset else None
        except (OSError, KeyError, ValueError):
            reset, rss0 = False, None
        n0 = _numba_alloc_count()
        fn()
        n1 = _numba_alloc_count()
        resident_kib = None
        if reset:
            try:
                resident_kib = max(0, _status_kib('VmHWM')['VmHWM'] - rss0)
            except (OSError, KeyError, ValueError):
                resident_kib = None
        if resident_kib is None:
            method = 'unavailable (needs Linux /proc/self/clear_refs and /proc/self/status)'
    finally:
        if not stats_were_on:
            nrt.memsys_disable_stats()

    # 2. tracemalloc: numpy, Python and numba-runtime allocations
    was_tracing = tracemalloc.is_tracing()
    if not was_tracing:
        tracemalloc.start()
    tracemalloc.reset_peak()
    base_cur, _ = tracemalloc.get_traced_memory()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    if not was_tracing:
        tracemalloc.stop()

    traced_mib = round(max(0, peak - base_cur) / 2**20, 3)
    resident_mib = None if resident_kib is None else round(resident_kib / 2**10, 3)
    return {
        'resident_peak_mib': resident_mib,
        'tracemalloc_peak_mib': traced_mib,
        'numba_allocations': None if n0 is None or n1 is None else n1 - n0,
        'resident_method': method,
    }


# ------------------------------------------------------------------------------------------------
# Errors
# ------------------------------------------------------------------------------------------------
def error_stats(errors_deg, failures: int = 0) -> dict:
    """
    RMS, 95th percentile of |error|, max |error| and mean of heading errors (degrees).

    ``failures`` counts estimates that returned no heading; they are not in the statistics.
    """
    e = np.asarray(list(errors_deg), dtype=float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {
            'n': 0,
            'failures': int(failures),
            'rms_deg': None,
            'p95_deg': None,
            'max_deg': None,
            'mean_deg': None,
        }
    a = np.abs(e)
    return {
        'n': int(e.size),
        'failures': int(failures),
        'rms_deg': float(np.sqrt(np.mean(e * e))),
        'p95_deg': float(np.percentile(a, 95)),
        'max_deg': float(a.max()),
        'mean_deg': float(e.mean()),
    }


# ------------------------------------------------------------------------------------------------
# JSON
# ------------------------------------------------------------------------------------------------
def finite_or_none(obj):
    """
    Make a result strict JSON: NaN/inf become None, numpy values Python values.

    Recursively replace NaN/inf by None and numpy scalars/arrays by Python values (strict JSON).
    """
    if isinstance(obj, dict):
        return {str(k): finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_none(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite_or_none(obj.tolist())
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: Path, obj: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + '.tmp')
    tmp.write_text(
        json.dumps(finite_or_none(obj), indent=1, sort_keys=False, allow_nan=False) + '\n'
    )
    tmp.replace(path)
    return path


def read_json(path: Path) -> dict:
    return json.loads(Path(path).read_text())


# ------------------------------------------------------------------------------------------------
# Optional pieces (parts of the project still being written, peers)
# ------------------------------------------------------------------------------------------------
class Unavailable(Exception):
    """A piece this benchmark needs is not there (module not written yet or peer not installed)."""


class Skipped(Exception):
    """
    A benchmark group that does not run in this mode.

    The group does not run in this mode (e.g. a minute-long ROS graph in the smoke test); the
    reason says how to run it.
    """


def optional_import(name: str):
    """Import ``name`` or raise :class:`Unavailable` saying what is missing."""
    import importlib

    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise Unavailable(f'{exc.name} not available') from None
