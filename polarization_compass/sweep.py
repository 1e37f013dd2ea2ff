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

The maps are :class:`~polarization_compass.errormap.ErrorMap`. What to compute is a
:class:`~polarization_compass.sweep_spec.SweepSpec` (:mod:`~polarization_compass.sweep_spec`);
here: the driver (:func:`run_sweep`), its chunks, checkpoints and the finished map.

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

from pathlib import Path
import shutil
import sys
import time

import numpy as np

from .errormap import (
    ErrorMap,
    ErrorMapError,
    STATUS_ESTIMATOR_ERROR,
    STATUS_NOT_COMPUTED,
)
from .sweep_cells import CellEvaluator
from .sweep_spec import SweepSpec

__all__ = ['run_sweep']


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
        from .errormap_netcdf import export_netcdf

        store.finish(meta)
        if out_path.suffix == '.npz':
            m.save(out_path, float32=float32)
        elif out_path.suffix == '.nc':
            export_netcdf(m, out_path)
        if out_path.suffix != '.zarr':
            shutil.rmtree(store.path, ignore_errors=True)
    return m
