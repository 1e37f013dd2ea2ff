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
Threads: the method groups of one replay share one read of the bag.

The groups and their threads (:func:`method_groups`, :func:`_replay_threads`), and the whole bag
(:func:`replay_bag`, :class:`ReplayResult`).
"""

from __future__ import annotations

from contextlib import closing, ExitStack
from dataclasses import dataclass
import time

from .processing import _Corrector, _make_corrector, FramePipeline, MethodRow, ReplayConfig
from .sync import BagPlan, iter_synced_frames, plan_bag, prefetched
from ..bag.errors import BagError
from ..bag.reader import BagReader, Tally
from ..bag.topic_map import default_topic_map, TopicMap
from ..estimators import registry
from ..runtime import keep_large_buffers_in_heap, single_threaded_kernels

__all__ = ['ReplayResult', 'method_groups', 'default_workers', 'replay_bag']


@dataclass
class ReplayResult:
    """
    Hold the result of an offline replay.

    Parameters
    ----------
    rows : list of MethodRow
        One row per frame and method, by stamp then method order.
    summary : dict
        The evaluator's statistics per stream (:meth:`StampMatcher.summary`, errors [deg]).
    tally : Tally
        Messages read, used and skipped per topic and reason.
    plan : BagPlan
        What the bag holds and its problems.
    frames : int
        Images processed.
    bag_duration_s : float
        Recorded time the frames cover [s].
    wall_s : float
        Wall-clock time of the replay [s].
    matches : list of Match
        Estimates paired with the reference.
    timing_ms : dict
        ``{stage or method: [ms per frame]}``.
    error_map : str, optional
        The error map used for the tilt correction.
    cpu_s : float, default 0
        CPU time of the process (all threads) while replaying [s].
    workers : int, default 1
        Threads that shared the methods.

    """

    rows: list
    summary: dict  # evaluator summary per stream
    tally: Tally
    plan: BagPlan
    frames: int
    bag_duration_s: float
    wall_s: float
    matches: list
    timing_ms: dict
    error_map: str | None = None
    cpu_s: float = 0.0  # CPU time of the process (all threads) while replaying
    workers: int = 1  # threads that shared the methods

    @property
    def speed_x_real_time(self) -> float:
        """Return the recorded seconds per wall-clock second."""
        return self.bag_duration_s / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def speed_x_real_time_cpu(self) -> float:
        """
        Return the recorded seconds per CPU second (load-independent).

        Recorded seconds per CPU second: the speed on an otherwise idle core (load-independent).
        """
        return self.bag_duration_s / self.cpu_s if self.cpu_s > 0 else 0.0


def method_groups(methods: list[str], workers: int) -> list[list[str]]:
    """
    Split ``methods`` into at most ``workers`` groups of similar cost.

    Largest first onto the lightest group (cost: the estimator's ``relative_cost``), each group
    keeping the given method order.

    Parameters
    ----------
    methods : list of str
        Estimator names.
    workers : int
        Groups wanted (clipped to [1, number of methods]).

    Returns
    -------
    list of list of str
        The non-empty groups.

    """
    workers = max(1, min(int(workers), len(methods)))
    groups: list[list[str]] = [[] for _ in range(workers)]
    load = [0.0] * workers
    for m in sorted(
        methods, key=lambda m: -registry.relative_cost(m)
    ):  # the estimator's relative_cost
        g = load.index(min(load))
        groups[g].append(m)
        load[g] += registry.relative_cost(m)
    return [[m for m in methods if m in g] for g in groups if g]


@dataclass
class _Read:
    """What the method groups made of one read of the bag (corrections still pending)."""

    rows: list  # every group's, in no particular order
    truths: list  # (stamp_ns, true bearing) per frame with a reference
    tally: Tally
    plan: BagPlan
    frames: int
    first_stamp: int | None
    last_stamp: int | None
    timing_ms: dict  # per method (and "observation"), every group's
    cpu_s: float  # the process, every thread


def _replay_threads(
    path, config: ReplayConfig, topic_map: TopicMap, groups: list[list[str]], progress=None
) -> _Read:
    """
    Run every method group in this process, one thread per group.

    The bag is read once; group 0 runs on this thread and each other group on a thread of its own,
    fed the same frames through a bounded queue (a group never lags more than ``_LAG`` frames). The
    compiled kernels release the GIL (``nogil``), so the groups' pixel work runs in parallel; a
    group's frames stay in order on one thread, so its state (the ``last`` prior) is the node's.
    Replaces one process per group, each reading the whole bag: on 2 cores reading a 10 MB image
    took ~7 ms of each process's ~22 ms per frame.
    """
    import queue

    # each 10 MB image read from the bag: 9.1 -> 6.8 ms of CPU (page faults)
    keep_large_buffers_in_heap()
    t_cpu = time.process_time()
    pipes = [FramePipeline(config.for_methods(g), topic_map) for g in groups]
    for pipe in pipes:
        if pipe.corrector is not None:
            pipe.corrector.defer = True
    rows: list[list[MethodRow]] = [[] for _ in groups]
    queues = [queue.Queue(maxsize=_LAG) for _ in groups[1:]]
    failures: list[BaseException] = []
    threads = _start_group_threads(pipes, rows, queues, failures)
    tally = Tally()
    try:
        plan, frames, first_stamp, last_stamp, truths = _read_and_feed(
            path, config, topic_map, tally, (pipes[0], rows[0]), queues, failures, progress
        )
    finally:
        for q in queues:
            q.put(None)
        for th in threads:
            th.join()
    if failures:
        raise failures[0]
    return _Read(
        [r for group_rows in rows for r in group_rows],
        truths,
        tally,
        plan,
        frames,
        first_stamp,
        last_stamp,
        _merged_timing(pipes),
        time.process_time() - t_cpu,
    )


def _start_group_threads(pipes: list, rows: list, queues: list, failures: list) -> list:
    """Start one thread per method group but the first, each processing the frames of its queue."""
    import threading

    def work(k: int):
        import numba

        numba.set_num_threads(1)  # numba's thread count is per calling thread
        q = queues[k - 1]
        while True:
            frame = q.get()
            if frame is None:
                return
            if failures:
                continue  # keep draining so that the reader never blocks
            try:
                rows[k].extend(pipes[k].process(frame))
            except BaseException as exc:  # noqa: BLE001 - re-raised on the calling thread
                failures.append(exc)

    threads = [
        threading.Thread(target=work, args=(k,), name=f'replay-group-{k}', daemon=True)
        for k in range(1, len(pipes))
    ]
    for th in threads:
        th.start()
    return threads


def _read_and_feed(path, config, topic_map, tally, first_group, queues, failures, progress):
    """
    Read the bag once, feed every frame to the other groups' queues, process group 0 here.

    Returns the plan, the number of frames, the first and last image stamps [ns] and the
    ``(stamp_ns, true bearing)`` of the frames with a reference.
    """
    pipe0, rows0 = first_group
    truths: list = []
    first_stamp = last_stamp = None
    frames = 0
    with (
        BagReader(path) as reader,
        single_threaded_kernels(),
        ExitStack() as stack,
    ):  # closing: the reader
        plan = plan_bag(reader, topic_map)  # threads stop too
        if plan.fatal:
            raise BagError(f'{reader.path}: ' + '; '.join(plan.fatal))
        # decoding and pairing run on the reading thread too: the calling thread only processes
        # its group (3 interleaved runs each: 19.4-23.0 ms per frame against 21.6-22.5 with
        # decoding on this thread)
        frames_in = stack.enter_context(
            closing(
                prefetched(
                    iter_synced_frames(reader, topic_map, tally, plan, config.prior_max_age_s),
                    4,
                )
            )
        )
        for frame in frames_in:
            frames += 1
            first_stamp = (
                frame.stamp_ns if first_stamp is None else min(first_stamp, frame.stamp_ns)
            )
            last_stamp = frame.stamp_ns if last_stamp is None else max(last_stamp, frame.stamp_ns)
            if frame.true_bearing_deg is not None:
                truths.append((frame.stamp_ns, frame.true_bearing_deg))
            for q in queues:
                q.put(frame)
            rows0.extend(pipe0.process(frame))
            if failures:
                raise failures[0]
            if progress is not None:
                progress(frames)
        # a truncated bag: read up to the damage, counted
        plan.problems.extend(reader.damage_notes())
    return plan, frames, first_stamp, last_stamp, truths


def _merged_timing(pipes: list) -> dict:
    """Return every group's per-method times [ms] (and ``observation``'s) in one dict."""
    timing: dict = {'observation': []}
    for pipe in pipes:
        for key, v in pipe.timing_ms.items():
            timing.setdefault(key, []).extend(v)
    return timing


_LAG = 8  # frames a method group may fall behind the reader (each holds a 10 MB mosaic)


def default_workers() -> int:
    """
    Return the number of cores this process may run on.

    Returns
    -------
    int
        At least 1.

    """
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def replay_bag(
    path,
    config: ReplayConfig | None = None,
    topic_map: TopicMap | None = None,
    progress=None,
    workers: int | None = None,
) -> ReplayResult:
    """
    Process a bag offline, as the nodes would, and evaluate the headings.

    ``workers`` threads run the methods in groups of similar cost over one read of the bag (a
    method's frames stay in order on one thread, so its state, e.g. the ``last`` prior, is the
    node's); every pending heading is then corrected with one vectorised inversion per method and
    evaluated. The result does not depend on ``workers``.

    Parameters
    ----------
    path : str or os.PathLike
        The rosbag2 directory.
    config : ReplayConfig, optional
        Methods, knobs, priors and error map; default the nodes' shipped parameters.
    topic_map : TopicMap, optional
        Topics and what the bag cannot say; default :func:`default_topic_map`.
    progress : callable, optional
        ``progress(frames_done)`` as frames are processed.
    workers : int, optional
        Threads (default: every core this process may use).

    Returns
    -------
    ReplayResult
        Rows, statistics, skip counts, speed.

    Raises
    ------
    BagError
        A path that is not a usable bag, or a bag with nothing to compute (one line).
    ReplayError
        Unknown method or knob, or a configured error map that does not exist.

    """
    from ..evaluation import StampMatcher

    config = config or ReplayConfig()
    topic_map = topic_map or default_topic_map()
    config.check_knobs()
    methods = config.method_list()
    corrector = _make_corrector(config) if config.error_map else None
    groups = method_groups(methods, default_workers() if workers is None else workers)
    t_wall = time.perf_counter()
    read = _replay_threads(path, config, topic_map, groups, progress)
    order = {m: k for k, m in enumerate(methods)}
    rows = sorted(read.rows, key=lambda r: (r.stamp_ns, order[r.method]))
    matcher = StampMatcher(horizon_ns=10**18, max_pending=10**9)
    for m in methods:
        matcher.add_stream(f'{m}/raw', False)
        if m not in config.direct_methods and corrector is not None:
            matcher.add_stream(f'{m}/corrected', False)
    for stamp, bearing in read.truths:
        matcher.add_truth(stamp, bearing)
    for r in rows:
        if r.status == 'ok' and r.raw_bearing_deg is not None:
            mt = matcher.add_estimate(f'{r.method}/raw', r.stamp_ns, r.raw_bearing_deg)
            if mt is not None:
                r.raw_error_deg = mt.error_deg
        if corrector is not None and r.correction_status == _Corrector.PENDING:
            corrector.enqueue(r)
    if corrector is not None:
        corrector.resolve()
    for r in rows:
        if r.corrected_bearing_deg is not None and f'{r.method}/corrected' in matcher.streams:
            mt = matcher.add_estimate(f'{r.method}/corrected', r.stamp_ns, r.corrected_bearing_deg)
            if mt is not None:
                r.corrected_error_deg = mt.error_deg
    matcher.finish()
    frames = read.frames
    duration = (read.last_stamp - read.first_stamp) / 1e9 if frames > 1 else 0.0
    if frames > 1:
        duration *= frames / (frames - 1)  # n frames cover n periods of recording
    wall = time.perf_counter() - t_wall
    return ReplayResult(
        rows,
        matcher.summary(),
        read.tally,
        read.plan,
        frames,
        duration,
        wall,
        matcher.matches,
        read.timing_ms,
        config.error_map,
        read.cpu_s,
        len(groups),
    )
