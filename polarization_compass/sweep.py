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
The sweep engine that computes tilt error maps (paper, section 3).

The maps are :class:`~polarization_compass.errormap.ErrorMap`. Here: what to compute
(:class:`SweepSpec`, :func:`parse_range` for its axes), per-process evaluators, checkpoints and the
driver (:func:`run_sweep`).

Sweeps run in chunks of one (sun altitude, pitch) pair each: in this process, or on Dask
distributed (an embedded LocalCluster on all cores, or an existing cluster;
:mod:`~polarization_compass.sweep_dask`), with a tqdm progress bar (rate, ETA) on stderr. Each
finished chunk is written into its own region of a checksummed Zarr store
(:class:`~polarization_compass.errormap_store.SweepStore`, ``<out>.partial.zarr``); an interrupted
sweep rerun with the same arguments continues from the verified chunks and gives the same map
(noise seeds are a function of the cell, not of the order of work or the worker). The complete map
is exported to ``.npz``, NetCDF 3 or kept as the Zarr store.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import hashlib
import json
import math
from pathlib import Path
import shutil
import sys
import time

import numpy as np

from .errormap import (
    AXES,
    DEFAULT_TILT_LIMIT_DEG,
    ErrorMap,
    ErrorMapError,
    FORMAT_VERSION,
    STATUS_ESTIMATOR_ERROR,
    STATUS_LEGEND,
    STATUS_NOT_COMPUTED,
    tilt_domain_mask,
)
from .errors import CompassError
from .sweep_cells import CellEvaluator

__all__ = ['SweepSpec', 'parse_range', 'run_sweep']


# --------------------------------------------------------------------------------------------
# Axes
# --------------------------------------------------------------------------------------------
def parse_range(
    text: str,
    name: str = 'range',
    lo: float = -math.inf,
    hi: float = math.inf,
    max_count: int = 100000,
) -> np.ndarray:
    """
    Parse an axis ``"A:B:STEP"`` (B included when B - A is a multiple of STEP) or ``"A"``.

    Parameters
    ----------
    text : str
        The range, in the axis's unit (e.g. deg).
    name : str, default "range"
        Option name for messages (``--<name>``).
    lo, hi : float, default -inf and inf
        Inclusive bounds every value must lie in.
    max_count : int, default 100000
        Most values allowed.

    Returns
    -------
    numpy.ndarray
        float64, strictly increasing (rounded to 1e-9, so 0.1 * 3 is 0.3).

    Raises
    ------
    ErrorMapError
        Not a number or ``A:B:STEP``, non-finite, STEP <= 0, B < A, too many values, or a value
        outside [lo, hi] (the message says which).

    """
    parts = str(text).split(':')
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise ErrorMapError(
            f'--{name} must be A:B:STEP or a single number, got {text!r}'
        ) from None
    if not all(math.isfinite(v) for v in nums):
        raise ErrorMapError(f'--{name} must be finite, got {text!r}')
    if len(nums) == 1:
        values = np.array(nums)
    elif len(nums) == 3:
        a, b, step = nums
        if step <= 0:
            raise ErrorMapError(f'--{name}: STEP must be > 0, got {step}')
        if b < a:
            raise ErrorMapError(f'--{name}: B must be >= A, got {text!r}')
        n = int(math.floor((b - a) / step + 1e-9)) + 1
        if n > max_count:
            raise ErrorMapError(f'--{name}: {n} values is more than {max_count}')
        values = a + step * np.arange(n)
        values = np.round(values, 9)  # 0.1 * 3 -> 0.3, not 0.30000000000000004
    else:
        raise ErrorMapError(f'--{name} must be A:B:STEP or a single number, got {text!r}')
    if values.min() < lo or values.max() > hi:
        raise ErrorMapError(f'--{name} values must lie in [{lo}, {hi}], got {text!r}')
    return values.astype(float)


# --------------------------------------------------------------------------------------------
# Sweep specification
# --------------------------------------------------------------------------------------------
@dataclass
class SweepSpec:
    """
    Describe what a sweep computes: methods and the four axes of the error map.

    Parameters
    ----------
    methods : tuple of str
        Estimator names (for ``array``: photodiode-array methods); not empty.
    sun_altitude_deg, yaw_deg, pitch_deg, roll_deg : array_like
        Axes [deg], each finite and strictly increasing; yaw psi, pitch alpha and roll beta of
        eq 21 (the sun azimuth is 0, so bearing == psi).
    scene : Scene, optional
        :class:`~polarization_compass.scene.Scene` (its attitude, sun and pixel selection are
        overridden per cell); default :func:`~polarization_compass.scene.default_scene`.
    knobs : dict, default {}
        ``{method: knobs}``; absent: the estimator class's ``sweep_knobs``, chosen so that errors
        change by < 0.05 deg against full resolution (docs/error-maps.md).
    full_domain : bool, default False
        Compute every (pitch, roll) node, not only |pitch| + |roll| <= ``tilt_limit_deg``.
    tilt_limit_deg : float, default 30
        Tilt domain limit [deg] (the paper's |pitch| + |roll| <= 30).
    support : int, default 2
        Grid nodes outside the limit kept for interpolation inside it.
    array : bool, default False
        Sweep the scene's photodiode array instead of its camera.

    Raises
    ------
    ErrorMapError
        No methods, an axis not finite or not increasing, or array methods that the scene or the
        array do not support.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3 (the simulated
       errors over sun altitude, yaw, pitch and roll).

    """

    methods: tuple
    sun_altitude_deg: np.ndarray
    yaw_deg: np.ndarray
    pitch_deg: np.ndarray
    roll_deg: np.ndarray
    scene: object = None
    knobs: dict = field(default_factory=dict)
    full_domain: bool = False
    tilt_limit_deg: float = DEFAULT_TILT_LIMIT_DEG
    support: int = 2
    array: bool = False  # sweep the scene's photodiode_array instead of its camera

    def __post_init__(self):
        from .scene_load import default_scene

        if self.scene is None:
            self.scene = default_scene()
        self.methods = tuple(self.methods)
        if not self.methods:
            raise ErrorMapError('no methods to sweep')
        for name in AXES:
            a = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if a.size > 1 and not np.all(np.diff(a) > 0):
                raise ErrorMapError(f'{name} must be strictly increasing')
            if not np.all(np.isfinite(a)):
                raise ErrorMapError(f'{name} must be finite')
            setattr(self, name, a)
        from .estimators import registry

        if self.array:
            if self.scene.photodiode_array is None:
                raise ErrorMapError(
                    'an array sweep needs a scene that declares a photodiode_array'
                )
            from .photodiode.heading import array_methods

            bad = [m for m in self.methods if m not in array_methods()]
            if bad:
                raise ErrorMapError(
                    f'method(s) {", ".join(bad)} need an image; a photodiode array supports '
                    f'{", ".join(array_methods())}'
                )
            self.knobs = {
                m: dict(self.knobs.get(m, {})) for m in self.methods
            }  # array knobs, default values
            return
        self.knobs = {
            m: dict(self.knobs[m]) if m in self.knobs else registry.sweep_knobs(m)
            for m in self.methods
        }
        if self.scene.effects:
            self._contiguous_pixels()

    def _contiguous_pixels(self) -> None:
        """
        Tell whether a sweep must read contiguous pixels (scenes with sensor effects).

        A scene with sensor effects renders a mosaic, which needs contiguous pixels (the renderer
        refuses strided selections): such sweeps read every pixel of each method's block (stride
        1), which is slow but what a noisy frame is.
        """
        from .estimators import make_estimator

        cam = self.scene.camera
        for m in self.methods:
            k = self.knobs[m]
            try:
                sel = make_estimator(m, **k).pixels_needed(cam)
            except CompassError:
                continue  # reported when the sweep builds its estimators
            if sel.mode in ('stride', 'region') and sel.stride > 1:
                cand = {**k, 'stride': 1}
                try:
                    make_estimator(m, **cand)
                except CompassError:
                    continue
                self.knobs[m] = cand

    @property
    def shape(self) -> tuple:
        """Shape of the map: (methods, sun altitudes, yaws, pitches, rolls)."""
        return (
            len(self.methods),
            self.sun_altitude_deg.size,
            self.yaw_deg.size,
            self.pitch_deg.size,
            self.roll_deg.size,
        )

    def tilt_mask(self) -> np.ndarray:
        """
        Return the (pitch, roll) nodes to compute.

        Returns
        -------
        numpy.ndarray
            bool (pitches, rolls): every node for ``full_domain``, else the tilt domain and its
            support (:func:`~polarization_compass.errormap.tilt_domain_mask`).

        """
        if self.full_domain:
            return np.ones((self.pitch_deg.size, self.roll_deg.size), dtype=bool)
        return tilt_domain_mask(
            self.pitch_deg, self.roll_deg, self.tilt_limit_deg, support=self.support
        )

    def chunks(self) -> list[tuple[int, int]]:
        """
        Return the chunks of work: (sun altitude, pitch) pairs with a node to compute.

        Returns
        -------
        list of tuple of int
            ``(sun altitude index, pitch index)`` pairs.

        """
        mask = self.tilt_mask()
        return [
            (ia, ip)
            for ia in range(self.sun_altitude_deg.size)
            for ip in range(self.pitch_deg.size)
            if mask[ip].any()
        ]

    def cell_count(self) -> int:
        """
        Return the number of (method, cell) estimates the sweep runs.

        Returns
        -------
        int
            Methods x sun altitudes x yaws x (pitch, roll) nodes of :meth:`tilt_mask`.

        """
        return int(
            len(self.methods)
            * self.sun_altitude_deg.size
            * self.yaw_deg.size
            * self.tilt_mask().sum()
        )

    def to_meta(self) -> dict:
        """
        Return the map's metadata for this sweep.

        Returns
        -------
        dict
            Format and package versions, scene, knobs per method, tilt domain rule, sun azimuth 0,
            the error definition (``fold_axial(estimated psi - true psi)`` [deg] in (-90, 90]) and
            the status legend.

        """
        from . import __version__

        return {
            'format_version': FORMAT_VERSION,
            'package_version': __version__,
            'scene': self.scene.to_dict(),
            'sampling': {m: {'knobs': self.knobs[m]} for m in self.methods},
            'domain': {
                'rule': 'full'
                if self.full_domain
                else '|pitch|+|roll| <= limit, plus the grid nodes within `support` steps of it '
                '(what interpolation inside it reads)',
                'tilt_limit_deg': self.tilt_limit_deg,
                'full_domain': self.full_domain,
                'support': self.support,
            },
            'sun_azimuth_deg': 0.0,
            'error_definition': 'fold_axial(estimated psi - true psi), deg, in (-90, 90]; '
            'bearing == psi',
            'status_codes': STATUS_LEGEND,
        } | ({'sensor': 'photodiode_array'} if self.array else {})

    def digest(self) -> str:
        """
        Return the identity of a sweep for resuming: same digest, same cells and values.

        Returns
        -------
        str
            20 hex digits of the SHA-256 of the metadata (package version excluded) and the axes.

        """
        meta = self.to_meta()
        meta.pop('package_version', None)
        key = {
            'meta': meta,
            'methods': list(self.methods),
            **{k: [float(x) for x in getattr(self, k)] for k in AXES},
        }
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]


OUTPUT_SUFFIXES = ('.npz', '.nc', '.zarr')


def store_path_for(out: Path) -> Path:
    """
    Return where a sweep to ``out`` keeps its Zarr store.

    Parameters
    ----------
    out : pathlib.Path
        The map's output path.

    Returns
    -------
    pathlib.Path
        ``out`` itself for ``.zarr``, else ``<out>.partial.zarr``.

    """
    return out if out.suffix == '.zarr' else out.with_name(out.name + '.partial.zarr')


def run_sweep(
    spec: SweepSpec,
    out=None,
    workers: int | None = None,
    progress: bool = True,
    resume: bool = True,
    max_chunks: int | None = None,
    float32: bool = False,
    scheduler: str | None = None,
    stats: dict | None = None,
    in_process: bool | None = None,
) -> ErrorMap | None:
    """
    Compute the error map of ``spec``.

    Where: ``workers=1`` without ``scheduler`` runs in this process (``in_process``, if given,
    decides instead); otherwise the chunks run on Dask distributed
    (:mod:`~polarization_compass.sweep_dask`). numba runs one thread per chunk everywhere, so
    every backend gives the same bits. Every finished chunk is written into the Zarr store
    :func:`store_path_for` (:class:`~polarization_compass.errormap_store.SweepStore`,
    checksummed regions) as it arrives; a rerun with the same spec resumes from the verified
    chunks (a damaged one is named and recomputed), and the complete map is exported to ``out``
    (the ``.partial.zarr`` store is then removed). A KeyboardInterrupt keeps every written chunk.

    Parameters
    ----------
    spec : SweepSpec
        What to compute.
    out : str or os.PathLike, optional
        ``.npz``, ``.nc`` (NetCDF 3) or ``.zarr``; None: nothing stored.
    workers : int, optional
        Single-threaded worker processes of an embedded ``LocalCluster`` (default: one per core).
    progress : bool, default True
        A tqdm progress bar (rate, ETA) on stderr.
    resume : bool, default True
        Continue an earlier store of the same sweep; False discards it first.
    max_chunks : int, optional
        Stop after this many new chunks (tests of resuming).
    float32 : bool, default False
        Store an ``.npz`` in float32 (half the size).
    scheduler : str, optional
        Address of an existing Dask cluster (``tcp://HOST:PORT``).
    stats : dict, optional
        Receives the run's measurements: ``workers``, ``tasks`` (chunks), ``dask_tasks`` (tasks of
        whole chunks), ``estimates``, ``wall_s``,
        ``startup_s`` (cluster start), ``compute_s`` (from the cluster being up to the last chunk
        received), ``task_s`` and ``task_cpu_s`` (summed wall and CPU seconds of the chunks'
        computation), ``setup_cpu_s`` (the workers' evaluators) [s].
    in_process : bool, optional
        Force (True) or forbid (False) the in-process path.

    Returns
    -------
    ErrorMap or None
        The validated map (errors [deg], statuses), or None when ``max_chunks`` stopped the sweep
        early.

    Raises
    ------
    ErrorMapError
        A bad ``out`` suffix, ``in_process`` with ``scheduler``, a foreign, corrupt or other-sweep
        store, an unreachable scheduler or a missing ``sweep`` extra.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3 (the simulated
       errors over sun altitude, yaw, pitch and roll).

    """
    out_path, in_process = _check_sweep_args(out, workers, scheduler, in_process)
    store = None
    if out_path is not None:
        from .errormap_store import SweepStore

        store = SweepStore.open(store_path_for(out_path), spec, restart=not resume)
    sw = _SweepRun(spec, store, progress)
    todo = store.scan(spec.chunks(), sw.err, sw.status) if store is not None else spec.chunks()
    mask = spec.tilt_mask()
    limit = len(todo) if max_chunks is None else min(len(todo), int(max_chunks))
    run = todo[:limit]
    sw.plan(run, mask)
    t0 = time.perf_counter()
    sampling = _compute_chunks(spec, run, sw, in_process, scheduler, workers)
    sw.close_bar()
    sw.info['wall_s'] = time.perf_counter() - t0
    if stats is not None:
        stats.update(sw.info)
    _warn_estimator_errors(sw.errors)
    if limit < len(todo):
        return None
    return _finish_map(spec, sw, sampling, out_path, float32)


def _check_sweep_args(out, workers, scheduler, in_process):
    """
    Check the output suffix and the backend choice of :func:`run_sweep`.

    Returns
    -------
    tuple
        The output path (or None) and whether to run in this process.

    """
    out_path = Path(out) if out is not None else None
    if out_path is not None and out_path.suffix not in OUTPUT_SUFFIXES:
        raise ErrorMapError(
            f'the map must be written to {", ".join(OUTPUT_SUFFIXES)}, got {str(out_path)!r}'
        )
    if in_process is None:
        in_process = scheduler is None and workers == 1
    elif in_process and scheduler is not None:
        raise ErrorMapError('in_process and scheduler exclude each other')
    return out_path, in_process


class _SweepRun:
    """Hold one sweep's arrays, measurements and progress bar while its chunks arrive."""

    def __init__(self, spec: SweepSpec, store, progress: bool):
        """Allocate the error and status arrays of ``spec`` (nothing computed yet)."""
        self.shape = spec.shape
        self.store = store
        self.progress = progress
        self.err = np.zeros(spec.shape, dtype=float)
        self.status = np.full(spec.shape, STATUS_NOT_COMPUTED, dtype=np.int8)
        self.errors: list[str] = []
        self.bar = None

    def plan(self, run: list, mask: np.ndarray):
        """Count the estimates of the chunks ``run`` and start the clock."""
        M, A, Y, P, R = self.shape
        self.mask = mask
        self.total = int(sum(M * Y * int(mask[ip].sum()) for _, ip in run))
        self.info = {
            'tasks': 0,
            'dask_tasks': 0,
            'task_s': 0.0,
            'task_cpu_s': 0.0,
            'setup_cpu_s': 0.0,
            'estimates': self.total,
            'startup_s': 0.0,
            'workers': 1,
            'compute_s': 0.0,
        }
        self.t_up = time.perf_counter()

    def on_start(self, n_workers: int, where: str, startup_s: float):
        """Record the backend being up and open the progress bar."""
        info = self.info
        info['workers'], info['startup_s'] = n_workers, startup_s
        self.t_up = time.perf_counter()
        if self.progress:
            from tqdm import tqdm

            self.bar = tqdm(
                total=self.total,
                unit=' estimates',
                file=sys.stderr,
                dynamic_ncols=True,
                smoothing=0.1,
                desc=f'errormap ({where}, {n_workers} worker{"s" if n_workers != 1 else ""})',
            )

    def accept(self, ia, ip, e, s, errs, task_s, task_cpu_s, setup_cpu_s=0.0):
        """Take one finished chunk into the arrays, the store and the measurements."""
        M, A, Y, P, R = self.shape
        info = self.info
        self.err[:, ia, :, ip, :] = e
        self.status[:, ia, :, ip, :] = s
        if self.store is not None:
            self.store.write_chunk(ia, ip, e, s)
        self.errors.extend(errs)
        info['tasks'] += 1
        info['task_s'] += task_s
        info['task_cpu_s'] += task_cpu_s
        info['setup_cpu_s'] += setup_cpu_s
        info['compute_s'] = time.perf_counter() - self.t_up
        if self.bar is not None:
            self.bar.update(M * Y * int(self.mask[ip].sum()))

    def close_bar(self):
        """Close the progress bar, if one is open."""
        if self.bar is not None:
            self.bar.close()


def _compute_chunks(spec: SweepSpec, run: list, sw: _SweepRun, in_process, scheduler, workers):
    """
    Compute the chunks ``run`` in this process or on Dask, each into ``sw`` as it arrives.

    Returns
    -------
    dict
        The sampling of the sweep's evaluator (for the map's meta).

    """
    try:
        ev = CellEvaluator(
            spec
        )  # in the client too: sampling() for the meta, and a bad spec fails here
        sampling = ev.sampling()
        if in_process or not run:
            from .runtime import single_threaded_kernels

            sw.on_start(1, 'in process', 0.0)
            for ia, ip in run:
                t1, c1 = time.perf_counter(), time.thread_time()
                with single_threaded_kernels():  # as on a worker: the same bits everywhere
                    e, s = ev.chunk(ia, ip)
                sw.accept(
                    ia, ip, e, s, ev.errors, time.perf_counter() - t1, time.thread_time() - c1
                )
                ev.errors = []
        else:
            from .sweep_dask import run_chunks

            sw.info['dask_tasks'] = run_chunks(
                spec, run, sw.accept, sw.on_start, scheduler=scheduler, workers=workers
            )
    except KeyboardInterrupt:
        sw.close_bar()
        if sw.store is not None:
            print(
                f'errormap: interrupted after {sw.info["tasks"]} new chunk(s); finished chunks '
                'are kept in '
                f'{sw.store.path}; rerun the same command to resume',
                file=sys.stderr,
            )
        raise
    return sampling


def _warn_estimator_errors(errors: list[str]):
    """Warn on stderr of the estimator exceptions of a sweep, the first three named."""
    if errors:
        print(
            f'errormap: warning: estimator exceptions (status {STATUS_ESTIMATOR_ERROR}), first: '
            + '; '.join(errors[:3]),
            file=sys.stderr,
        )


def _finish_map(spec: SweepSpec, sw: _SweepRun, sampling, out_path, float32: bool) -> ErrorMap:
    """
    Validate the complete map and export it to ``out_path`` (removing a ``.partial.zarr`` store).

    Returns
    -------
    ErrorMap
        The validated map.

    """
    store = sw.store
    meta = spec.to_meta()
    meta['sampling'] = sampling
    meta['cells_estimated'] = spec.cell_count()
    meta['elapsed_s_last_run'] = round(sw.info['wall_s'], 3)
    meta['workers'] = sw.info['workers']
    m = ErrorMap(
        sw.err,
        sw.status,
        spec.methods,
        spec.sun_altitude_deg,
        spec.yaw_deg,
        spec.pitch_deg,
        spec.roll_deg,
        meta,
    ).validate()
    if store is not None:
        from .errormap_store import export_netcdf

        store.finish(meta)
        if out_path.suffix == '.npz':
            m.save(out_path, float32=float32)
        elif out_path.suffix == '.nc':
            export_netcdf(m, out_path)
        if out_path.suffix != '.zarr':
            shutil.rmtree(store.path, ignore_errors=True)
    return m
