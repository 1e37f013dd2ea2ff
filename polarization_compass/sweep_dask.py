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
The Dask distributed backend of the error-map sweep (:func:`polarization_compass.sweep.run_sweep`).

- where: an embedded ``distributed.LocalCluster`` of ``workers`` single-threaded processes on
  127.0.0.1 (default: one per core; no dashboard), or an existing cluster
  (``scheduler="tcp://HOST:PORT"``, started with ``dask scheduler`` / ``dask worker`` or any
  deployment Dask supports; every worker needs this package and the ``sweep`` extra, same version);
- a task is one sweep chunk, (sun altitude, pitch) x every method, yaw and roll, rendering only the
  pixels each method reads (:class:`~polarization_compass.sweep_cells.CellEvaluator`, built once
  per worker process and sweep). A chunk is 10^2-10^4 estimates (0.1-30 s), so the scheduler's few
  ms per task stay a small share (``bench/errormap_bench.py`` measures it);
- results come back to the client, which writes each chunk's region into the Zarr store as it
  arrives (the workers need no shared file system). A SIGKILLed worker loses only the chunks it was
  running: the scheduler reruns them on another worker. An interrupted client cancels what is left;
  the store keeps every written chunk.

Values do not depend on where or in which order a chunk runs: noise seeds are a function of the
cell, and every worker runs numba with one thread.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

from .errormap import ErrorMapError

__all__ = ['run_chunks', 'run_tasks', 'start']

_THREAD_VARS = ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS', 'NUMBA_NUM_THREADS')

# one evaluator per worker process, for the sweep it was built for
_EVALUATOR: dict = {}


def _chunk_task(spec, digest: str, ia: int, ip: int):
    """
    Run on a Dask worker: one chunk.

    Returns (ia, ip, err, status, estimator errors, compute wall seconds, compute CPU seconds of
    this thread, CPU seconds of building this worker's evaluator (0 once built)).
    """
    from .runtime import keep_large_buffers_in_heap, single_threaded_kernels
    from .sweep_cells import CellEvaluator

    c0 = time.thread_time()
    ev = _EVALUATOR.get(digest)
    if ev is None:
        # distributed's nannies start workers with MALLOC_TRIM_THRESHOLD_=65536: glibc then returns
        # freed buffers to the kernel and every chunk's temporaries page-fault anew (measured: 0.29
        # ms of CPU per estimate instead of 0.14-0.19 ms in process)
        keep_large_buffers_in_heap()
        _EVALUATOR.clear()
        ev = _EVALUATOR[digest] = CellEvaluator(spec)
    t1, c1 = time.perf_counter(), time.thread_time()
    with single_threaded_kernels():  # numba's thread count is per calling thread
        err, status = ev.chunk(ia, ip)
    errors, ev.errors = ev.errors, []
    return ia, ip, err, status, errors, time.perf_counter() - t1, time.thread_time() - c1, c1 - c0


def _require_distributed():
    try:
        import distributed
    except ImportError as exc:
        raise ErrorMapError(
            f'a sweep on more than one worker runs on Dask, which needs the optional extra '
            f"'sweep' (pip install polarization_compass[sweep], installed by make); or pass "
            f'--workers 1 ({exc})'
        ) from None
    return distributed


#: How long an existing scheduler may take to answer, and then to have a worker [s].
SCHEDULER_TIMEOUT_S = 20.0


async def _identity(address: str, timeout_s: float):
    """Ask a scheduler who it is, every step bounded (Dask's own handshake may wait forever)."""
    import asyncio

    from distributed.comm import connect

    comm = await asyncio.wait_for(connect(address, timeout=timeout_s), timeout_s)
    try:
        await asyncio.wait_for(comm.write({'op': 'identity'}), timeout_s)
        return await asyncio.wait_for(comm.read(), timeout_s)
    finally:
        comm.abort()


def _connect(distributed, address: str, timeout_s: float):
    """
    Return a client on the scheduler at ``address``, checked first within ``timeout_s``.

    The scheduler is asked for its identity on a connection of its own, every step bounded, before
    a client is made: a listener that never answers, a service that is not Dask (whose reply Dask
    would read as a frame length of exabytes), a transport not installed here (``ucx://``) or an
    address of another process (``inproc://``) fail in bounded time with one line. A scheduler
    without workers is refused after ``timeout_s`` too, instead of waiting forever.
    """
    import asyncio

    try:
        reply = asyncio.run(_identity(address, timeout_s))
    except (asyncio.TimeoutError, TimeoutError):
        raise ErrorMapError(
            f'{address} does not answer as a Dask scheduler within {timeout_s:g} s'
        ) from None
    except (MemoryError, ValueError, TypeError, EOFError) as exc:  # a reply Dask cannot parse
        raise ErrorMapError(
            f'{address} answers, but not as a Dask scheduler ({type(exc).__name__})'
        ) from None
    except Exception as exc:  # noqa: BLE001 - refusals, unreachable hosts, missing transports
        why = f'{type(exc).__name__}: {exc}' if str(exc) else type(exc).__name__
        raise ErrorMapError(
            f'cannot reach a Dask scheduler at {address} ({_short(why)})'
        ) from None
    if not isinstance(reply, dict) or reply.get('type') != 'Scheduler':
        raise ErrorMapError(f'{address} answers, but not as a Dask scheduler')
    client = distributed.Client(address, timeout=f'{timeout_s}s', set_as_default=False)
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except TimeoutError:
        client.close()
        raise ErrorMapError(
            f'the Dask scheduler at {address} has no worker after {timeout_s:g} s; start one with '
            f'`dask worker {address}`'
        ) from None
    return client


def _short(text: str) -> str:
    text = ' '.join(text.split())
    return text if len(text) <= 160 else text[:157] + '...'


def start(scheduler: str | None, workers: int | None):
    """
    Return a Dask client on a scheduler or on a new LocalCluster.

    A new ``distributed.LocalCluster`` has ``workers`` single-threaded processes on 127.0.0.1 (no
    dashboard); its processes start with one BLAS/OpenMP/numba thread and with SIGINT ignored, so
    only this client reacts to Ctrl-C. The caller closes both client and cluster.

    Parameters
    ----------
    scheduler : str or None
        Address of an existing scheduler (``"tcp://HOST:PORT"``); None or empty starts a
        LocalCluster.
    workers : int or None
        Worker processes of a new LocalCluster; None: one per core.

    Returns
    -------
    client : distributed.Client
        The client (not set as Dask's default).
    cluster : distributed.LocalCluster or None
        The cluster started here, None on an existing scheduler.

    Raises
    ------
    ErrorMapError
        When Dask's ``distributed`` is not installed (the ``sweep`` extra), or the scheduler does
        not answer as a Dask scheduler or has no worker within :data:`SCHEDULER_TIMEOUT_S` (a
        listener that never answers, another service, an address of a transport not available
        here: :func:`_connect`).

    """
    import logging

    distributed = _require_distributed()
    if scheduler:
        return _connect(distributed, scheduler, SCHEDULER_TIMEOUT_S), None
    n = max(1, int(workers or os.cpu_count() or 1))
    saved = {k: os.environ.get(k) for k in _THREAD_VARS}
    os.environ.update(dict.fromkeys(_THREAD_VARS, '1'))  # inherited by the worker processes only
    # A terminal's Ctrl-C reaches the whole process group, the worker processes too: they start
    # with SIGINT ignored (an ignored signal stays ignored across exec), so only this client reacts
    # to it and closes the cluster, instead of every worker printing a KeyboardInterrupt traceback.
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if in_main else None
    try:
        cluster = distributed.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host='127.0.0.1',
            dashboard_address=None,
            # no dashboard, but the scheduler still serves its health routes over HTTP: on a free
            # port, not on 8787 (a second sweep there warned "Port 8787 is already in use")
            scheduler_kwargs={'dashboard_address': '127.0.0.1:0'},
            # a chunk's failure reaches the client as the task's exception; what distributed logs
            # at ERROR in its processes are its own shutdown races (a worker's heartbeat to a
            # scheduler that just closed: a traceback in 1 of 9 interrupted sweeps, measured)
            silence_logs=logging.CRITICAL,
        )
    finally:
        if in_main:
            signal.signal(signal.SIGINT, previous)
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    try:
        return distributed.Client(cluster, set_as_default=False), cluster
    except BaseException:
        cluster.close()
        raise


#: A task holds whole chunks and at least this many estimates (~0.3 s of work): the scheduler's
#: ~5-10 ms per task stays a few per cent even for pitch-only sweeps, whose chunks are small.
MIN_TASK_ESTIMATES = 2000
#: ... but the sweep is split into at least this many tasks, so that every worker gets work and the
#: last tasks do not leave workers idle for long.
MIN_TASKS = 8


def _chunks_task(spec, digest: str, keys: list) -> list:
    """Run on a Dask worker: several chunks, one result of :func:`_chunk_task` each."""
    return [_chunk_task(spec, digest, ia, ip) for ia, ip in keys]


def group_chunks(spec, run: list) -> list[list]:
    """
    Group the chunks ``run`` into tasks of at least :data:`MIN_TASK_ESTIMATES` estimates.

    Consecutive chunks are grouped so that each group holds at least
    ``min(MIN_TASK_ESTIMATES, total // MIN_TASKS)`` estimates (a chunk holds methods x yaws x the
    rolls computed at its pitch), which gives at least :data:`MIN_TASKS` groups when there are
    that many chunks; the last group may be smaller.

    Parameters
    ----------
    spec : SweepSpec
        The sweep (its methods, yaw axis and tilt mask count the estimates of a chunk).
    run : list of tuple of int
        ``(ia, ip)`` indices (sun altitude, pitch) of the chunks to run, in order.

    Returns
    -------
    list of list of tuple of int
        The chunks of ``run`` in consecutive groups, order kept.

    """
    mask = spec.tilt_mask()
    per = [len(spec.methods) * spec.yaw_deg.size * int(mask[ip].sum()) for _, ip in run]
    total = sum(per)
    want = max(1, min(MIN_TASK_ESTIMATES, total // MIN_TASKS if total >= MIN_TASKS else 1))
    groups, cur, size = [], [], 0
    for key, n in zip(run, per):
        cur.append(key)
        size += n
        if size >= want:
            groups.append(cur)
            cur, size = [], 0
    if cur:
        groups.append(cur)
    return groups


def run_chunks(
    spec, run: list, accept, on_start, scheduler: str | None = None, workers: int | None = None
) -> int:
    """
    Run the chunks ``run`` of ``spec`` on Dask, accepting each result as it arrives.

    Chunks travel in tasks of :func:`group_chunks`. Closes the client (and the LocalCluster it
    started) on every exit; cancels the tasks left on an exception or interrupt.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.
    run : list of tuple of int
        ``(ia, ip)`` indices (sun altitude, pitch) of the chunks to compute.
    accept : callable
        ``accept(ia, ip, err, status, errors, wall_s, cpu_s, build_cpu_s)``, called in this process
        for each chunk as it arrives: errors [deg] and statuses of the chunk, the estimators'
        exceptions, the compute wall and CPU time [s] and the CPU time of building the worker's
        evaluator [s] (0 once built).
    on_start : callable or None
        ``on_start(n_workers, where, startup_s)``, called once the cluster is up.
    scheduler : str, optional
        Address of an existing Dask scheduler; default a new LocalCluster (:func:`start`).
    workers : int, optional
        Worker processes of a new LocalCluster; default one per core.

    Returns
    -------
    int
        The number of Dask tasks submitted.

    Raises
    ------
    ErrorMapError
        When Dask is missing or the scheduler cannot be reached (:func:`start`).

    """
    digest = spec.digest()
    calls = [
        (f'errormap-{digest}-{g[0][0]}-{g[0][1]}-{len(g)}', _chunks_task, (spec, digest, g))
        for g in group_chunks(spec, run)
    ]

    def on_result(key, results):
        for r in results:
            accept(*r)

    run_tasks(calls, on_result, on_start, scheduler=scheduler, workers=workers)
    return len(calls)


def run_tasks(
    calls: list, on_result, on_start=None, scheduler: str | None = None, workers: int | None = None
) -> None:
    """
    Run ``calls`` on Dask, handing each result to ``on_result`` as it arrives.

    Closes the client (and the LocalCluster it started) on every exit; cancels what is left on an
    exception or interrupt.

    Parameters
    ----------
    calls : list of tuple
        ``(key, function, args)`` per task; the functions must be importable on the workers and
        the keys unique.
    on_result : callable
        ``on_result(key, result)``, called in this process for each task as it finishes (any
        order).
    on_start : callable, optional
        ``on_start(n_workers, where, startup_s)``, called once the cluster is up.
    scheduler : str, optional
        Address of an existing Dask scheduler; default a new LocalCluster (:func:`start`).
    workers : int, optional
        Worker processes of a new LocalCluster; default one per core.

    Raises
    ------
    ErrorMapError
        When Dask is missing or the scheduler cannot be reached (:func:`start`).
    KeyboardInterrupt
        On Ctrl-C, also one that arrived while the client and cluster closed (:func:`_close`).

    """
    t0 = time.perf_counter()
    client, cluster = start(scheduler, workers)
    try:
        n_workers = len(client.scheduler_info(n_workers=-1)['workers'])
        if on_start is not None:
            on_start(n_workers, f'Dask {scheduler or "LocalCluster"}', time.perf_counter() - t0)
        _collect(client, calls, on_result)
    except BaseException:
        _close(client, cluster)
        raise
    if _close(client, cluster):
        raise KeyboardInterrupt  # a Ctrl-C held while the cluster closed after the last result


def _collect(client, calls: list, on_result) -> None:
    """Submit ``calls`` and hand each result to ``on_result``; cancel what is left on any exit."""
    from distributed import as_completed

    futures = [client.submit(fn, *args, key=key, pure=False) for key, fn, args in calls]
    try:
        for fut, result in as_completed(futures, with_results=True, loop=client.loop):
            on_result(fut.key, result)
            fut.release()
    except BaseException:
        client.cancel(futures)
        raise


#: Seconds the client, then the LocalCluster, may take to close before they are left to exit with
#: this process (measured: about 1 s on a quiet machine, several under a full test run).
CLOSE_TIMEOUT_S = 20.0


def _close(client, cluster) -> bool:
    """
    Close the client and the LocalCluster started here, with Ctrl-C held until both are closed.

    A second Ctrl-C (a terminal's, or a supervisor signalling the process group) that lands inside
    ``close()`` leaves the cluster half closed: its comms then print tracebacks and the exit waits
    on distributed's own timeouts or hangs (seen in CI: more than 60 s). So SIGINT is only noted
    while closing (in the main thread; elsewhere Python delivers no signal), each close is bounded
    by :data:`CLOSE_TIMEOUT_S`, and a close that fails is reported, never raised over the exception
    that ended the run.

    Returns
    -------
    bool
        Whether a SIGINT arrived while closing.

    """
    held = []
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, lambda *_: held.append(1)) if in_main else None
    try:
        closes = [('client', client.close)]
        if cluster is not None:
            closes.append(('cluster', cluster.close))
        for what, close in closes:
            try:
                close(timeout=CLOSE_TIMEOUT_S)
            except Exception as exc:  # noqa: BLE001 - the run's own outcome must win
                print(
                    f'errormap: warning: the Dask {what} did not close cleanly '
                    f'({type(exc).__name__}: {_short(str(exc))})',
                    file=sys.stderr,
                )
    finally:
        if in_main:
            signal.signal(signal.SIGINT, previous)
    return bool(held)
