"""Error-map sweeps on Dask distributed, written chunk by chunk into a Zarr store (issue 17).

:func:`run_sweep_distributed` computes a :class:`~polarization_compass.errormap.SweepSpec`:

- where: in this process (``workers=1`` and no scheduler: no cluster at all), on an embedded
  ``distributed.LocalCluster`` of ``workers`` single-threaded processes (default: one per core), or on an
  existing cluster (``scheduler="tcp://HOST:PORT"``, started with ``dask scheduler`` / ``dask worker`` or any
  deployment Dask supports; every worker needs this package and the ``sweep`` extra, same version);
- what a task is: one sweep chunk, (sun altitude, pitch) x every method, yaw and roll, rendering only the
  pixels each method reads (:class:`~polarization_compass.errormap._Evaluator`, built once per worker
  process and sweep). A chunk is 10^2-10^4 estimates (0.1-30 s), so the scheduler's few ms per task stay a
  small share; the benchmark measures it (``bench/errormap_bench.py``);
- where results go: each finished chunk is written by this (client) process into its own region of the
  :class:`~polarization_compass.errormap_store.SweepStore`, then its checksum. The workers need no shared
  file system. A SIGKILLed worker loses only the chunks it was running (the scheduler reruns them on another
  worker); an interrupted client keeps every written chunk, and the same call resumes from them;
- the result: the complete map, exported to ``.npz`` (today's format, :meth:`ErrorMap.save`), NetCDF 3
  (``.nc``, :func:`~polarization_compass.errormap_store.export_netcdf`) or kept as the Zarr store (``.zarr``).

Values do not depend on where or in which order a chunk runs: a chunk's noise seeds are a function of its
cells, and every worker runs numba with one thread, as the in-process path does.
"""
from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from .errormap import STATUS_ESTIMATOR_ERROR, STATUS_NOT_COMPUTED, ErrorMap, ErrorMapError, SweepSpec

__all__ = ["run_sweep_distributed", "store_path_for", "OUTPUT_SUFFIXES"]

OUTPUT_SUFFIXES = (".npz", ".nc", ".zarr")
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

# one evaluator per worker process, for the sweep it was built for
_EVALUATOR: dict = {}


def _chunk_task(spec: SweepSpec, digest: str, ia: int, ip: int):
    """Runs on a Dask worker: one chunk. Returns (ia, ip, err, status, estimator errors, compute seconds)."""
    from .errormap import _Evaluator
    t0 = time.perf_counter()
    ev = _EVALUATOR.get(digest)
    if ev is None:
        import numba
        numba.set_num_threads(1)
        _EVALUATOR.clear()
        ev = _EVALUATOR[digest] = _Evaluator(spec)
    err, status = ev.chunk(ia, ip)
    errors, ev.errors = ev.errors, []
    return ia, ip, err, status, errors, time.perf_counter() - t0


def store_path_for(out: Path) -> Path:
    """Where a sweep to ``out`` keeps its Zarr store: ``out`` itself for ``.zarr``, else ``<out>.partial.zarr``."""
    return out if out.suffix == ".zarr" else out.with_name(out.name + ".partial.zarr")


class _Cluster:
    """A distributed Client on an embedded LocalCluster or an existing scheduler; closes what it started."""

    def __init__(self, scheduler: str | None, workers: int | None):
        import logging

        from distributed import Client, LocalCluster
        self.cluster = None
        t0 = time.perf_counter()
        if scheduler:
            try:
                self.client = Client(scheduler, timeout="20s", set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise ErrorMapError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
        else:
            n = max(1, int(workers or os.cpu_count() or 1))
            saved = {k: os.environ.get(k) for k in _THREAD_VARS}
            os.environ.update({k: "1" for k in _THREAD_VARS})        # inherited by the worker processes
            try:
                self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                            dashboard_address=None, silence_logs=logging.ERROR)
            finally:
                for k, v in saved.items():
                    if v is None:
                        os.environ.pop(k, None)
                    else:
                        os.environ[k] = v
            self.client = Client(self.cluster, set_as_default=False)
        self.startup_s = time.perf_counter() - t0

    def n_workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1)["workers"]) if self.client else 0

    def close(self):
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()


def run_sweep_distributed(spec: SweepSpec, out=None, scheduler: str | None = None, workers: int | None = None,
                          progress: bool = True, restart: bool = False, max_chunks: int | None = None,
                          float32: bool = False, stats: dict | None = None) -> ErrorMap | None:
    """Compute the map of ``spec`` (see the module docstring); returns it, or None after ``max_chunks``.

    ``out``: ``.npz``, ``.nc`` or ``.zarr`` path (None: nothing stored, no resuming). ``scheduler``:
    ``tcp://HOST:PORT`` of an existing cluster. ``workers``: LocalCluster processes (default: all cores;
    1 without a scheduler runs in this process). ``restart`` discards an earlier store of this package at
    ``out``. ``max_chunks`` stops after that many new chunks (tests of resuming). ``stats``, if given, is
    filled with the run's measurements: ``workers``, ``tasks``, ``wall_s``, ``startup_s``, ``task_s``
    (summed compute seconds of the chunks) and ``estimates``. Raises :class:`ErrorMapError` for a bad
    ``out``, a foreign/corrupt/other-sweep store or an unreachable scheduler; a KeyboardInterrupt keeps
    every written chunk.
    """
    from .errormap_store import SweepStore, export_netcdf, require_sweep_extra
    out_path = Path(out) if out is not None else None
    if out_path is not None and out_path.suffix not in OUTPUT_SUFFIXES:
        raise ErrorMapError(f"--out must end in {', '.join(OUTPUT_SUFFIXES)}, got {str(out_path)!r}")
    in_process = scheduler is None and workers == 1
    if not in_process:
        try:
            import distributed  # noqa: F401
        except ImportError:
            require_sweep_extra("a sweep on Dask")
            raise ErrorMapError("a sweep on Dask needs the optional extra 'sweep' (pip install "
                                "polarization_compass[sweep])") from None
    store = SweepStore.open(store_path_for(out_path), spec, restart=restart) if out_path is not None else None
    M, A, Y, P, R = spec.shape
    err = np.zeros(spec.shape, dtype=float)
    status = np.full(spec.shape, STATUS_NOT_COMPUTED, dtype=np.int8)
    todo = store.scan(spec.chunks(), err, status) if store is not None else spec.chunks()
    mask = spec.tilt_mask()
    limit = len(todo) if max_chunks is None else min(len(todo), int(max_chunks))
    run = todo[:limit]
    total = int(sum(M * Y * int(mask[ip].sum()) for _, ip in run))
    errors: list[str] = []
    info = {"tasks": 0, "task_s": 0.0, "estimates": total, "startup_s": 0.0}
    t0 = time.perf_counter()
    bar = None

    def accept(ia, ip, e, s, errs, task_s):
        err[:, ia, :, ip, :] = e
        status[:, ia, :, ip, :] = s
        if store is not None:
            store.write_chunk(ia, ip, e, s)
        errors.extend(errs)
        info["tasks"] += 1
        info["task_s"] += task_s
        if bar is not None:
            bar.update(M * Y * int(mask[ip].sum()))

    cluster = None
    try:
        if in_process or not run:
            n_workers = 1
            from .errormap import _Evaluator
            ev = _Evaluator(spec)
            sampling = ev.sampling()
            bar = _bar(progress, total, "errormap (in process)")
            for ia, ip in run:
                t1 = time.perf_counter()
                e, s = ev.chunk(ia, ip)
                accept(ia, ip, e, s, ev.errors, time.perf_counter() - t1)
                ev.errors = []
        else:
            from .errormap import _Evaluator
            sampling = _Evaluator(spec).sampling()
            cluster = _Cluster(scheduler, workers)
            info["startup_s"] = cluster.startup_s
            n_workers = cluster.n_workers()
            where = scheduler or "LocalCluster"
            bar = _bar(progress, total, f"errormap (Dask, {where}, {n_workers} worker{'s' if n_workers != 1 else ''})")
            _run_on_cluster(cluster.client, spec, run, accept)
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        if store is not None:
            print(f"errormap: interrupted after {info['tasks']} new chunk(s); finished chunks are kept in "
                  f"{store.path}; rerun the same command to resume", file=sys.stderr)
        raise
    finally:
        if cluster is not None:
            cluster.close()
    if bar is not None:
        bar.close()
    info["wall_s"] = time.perf_counter() - t0
    info["workers"] = n_workers
    if stats is not None:
        stats.update(info)
    if errors:
        print(f"errormap: warning: estimator exceptions (status {STATUS_ESTIMATOR_ERROR}), first: "
              + "; ".join(errors[:3]), file=sys.stderr)
    if limit < len(todo):
        return None
    meta = spec.to_meta()
    meta["sampling"] = sampling
    meta["cells_estimated"] = spec.cell_count()
    meta["elapsed_s_last_run"] = round(info["wall_s"], 3)
    meta["workers"] = n_workers
    m = ErrorMap(err, status, spec.methods, spec.sun_altitude_deg, spec.yaw_deg, spec.pitch_deg,
                 spec.roll_deg, meta).validate()
    if store is not None:
        store.finish(meta)
        if out_path.suffix == ".npz":
            m.save(out_path, float32=float32)
        elif out_path.suffix == ".nc":
            export_netcdf(m, out_path)
        if out_path.suffix != ".zarr":
            shutil.rmtree(store.path, ignore_errors=True)
    return m


def _bar(progress: bool, total: int, desc: str):
    if not progress:
        return None
    from tqdm import tqdm
    return tqdm(total=total, unit=" estimates", file=sys.stderr, dynamic_ncols=True, smoothing=0.1, desc=desc)


def _run_on_cluster(client, spec: SweepSpec, run: list, accept) -> None:
    """Submit one task per chunk; write each result as it arrives; cancel what is left on any exit."""
    from distributed import as_completed
    digest = spec.digest()
    futures = [client.submit(_chunk_task, spec, digest, ia, ip, key=f"errormap-{digest}-{ia}-{ip}", pure=False)
               for ia, ip in run]
    try:
        for fut, result in as_completed(futures, with_results=True, loop=client.loop):
            accept(*result)
            fut.release()
    except BaseException:
        client.cancel(futures)
        raise
