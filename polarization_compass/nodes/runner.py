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
``main()`` of every node: start, spin, and stop cleanly.

* A configuration error (bad parameter, missing error map, missing optional package) prints one
  line ``<node>: error: ...`` on stderr and exits 2, as the CLI does.
* SIGINT / SIGTERM (Ctrl-C, ``ros2 launch`` shutting down), once or repeatedly, end the spin and
  the process exits 0 without a traceback (:class:`StopSignals`). rclpy's own signal handlers are
  not installed (``SignalHandlerOptions.NO``): they shut the context down at once, so a callback
  already running or queued then publishes on an invalid context (a FATAL traceback), and a second
  signal raised ``KeyboardInterrupt`` inside the C++ executor (``pybind11::error_already_set``,
  abort). Here a signal only records the request; the spin loop sees it within ``SPIN_PERIOD_S``
  between two callbacks, then the node's ``close()`` runs (the evaluator writes its report there),
  the executor and the node are destroyed and only then is rclpy shut down: nothing is published
  after shutdown. Further signals during that sequence are recorded and change nothing. Before
  ``close()``, a node whose output is a report of what it received (the evaluator) handles the
  inputs already waiting in its readers (:func:`drain_inputs`, bounded). A signal while the node
  is being built (imports done, warm-up running) ends the start-up at once, also with exit 0;
  if the start-up goes on anyway (numba compiling in C), the process ends 5 s later
  (:class:`StopSignals`).
* The process then ends with ``os._exit`` once stdout/stderr are flushed and rclpy's context (its
  DDS participant, the ROS log files) is shut down and destroyed: Python's own finalisation took
  1.9 s per node alone on this machine (5 s and more with ten nodes on two cores, past ``ros2
  launch``'s default SIGTERM timeout), and it restores the default signal handlers first, so a
  second Ctrl-C during it killed the node (exit -2). Nothing is left for it to do: no atexit
  handler of ours exists.
* A node may end itself (the simulator after its last frame) by setting ``node.exit_code`` (checked
after every spin; no exception crosses the executor, whose C++ implementation logs every callback
exception as FATAL with a traceback), or by raising :class:`ExitRequest` in a callback.
* The executor is rclpy's C++ ``EventsExecutor`` where rclpy has it (Kilted and later): it
  dispatches callbacks in arrival order at about a third of the CPU cost per callback of the Python
  executors (measured here: 0.36 ms against 1.0 ms single-threaded and 1.8 ms multi-threaded per
  small message, on a loaded machine), which matters with eleven nodes on two cores receiving
  /clock, IMU and heading messages. Arrival order also keeps the IMU flowing between images. Where
  it is missing (Jazzy), a node with ``executor_threads = N > 1`` spins on a MultiThreadedExecutor
  (the estimator: small inputs such as the IMU keep flowing while an image is being processed),
  others on a SingleThreadedExecutor. ``POLARIZATION_COMPASS_EXECUTOR=single|multi`` forces the
  Python executors.
* Before ROS starts, glibc's allocator is told to keep large blocks in the heap
(:func:`keep_large_buffers_in_heap`): a 10 MB image otherwise costs every subscriber three fresh
``mmap`` regions per message, zero-filled by the kernel page by page (measured: 21 ms of system
time and 7300 page faults per 2448x2048 mono16 image per subscriber; 0.2 ms and none with it).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

from ..errors import CompassError
from ..runtime import keep_large_buffers_in_heap

__all__ = [
    'run_node',
    'ExitRequest',
    'StopSignals',
    'keep_large_buffers_in_heap',
    'make_executor',
    'SPIN_PERIOD_S',
    'DRAIN_QUIET_S',
    'START_UP_DEADLINE_S',
    'drain_inputs',
]


class ExitRequest(Exception):
    """Raised inside a callback to end the node's spin with an exit code."""

    def __init__(self, code: int = 0):
        super().__init__(code)
        self.code = int(code)


def make_executor(node):
    """Return the executor for ``node``, on the node's context (see the module docstring)."""
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

    choice = os.environ.get('POLARIZATION_COMPASS_EXECUTOR', 'events').strip().lower()
    if choice == 'events':
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:
            choice = ''
        else:
            return EventsExecutor(context=node.context)
    threads = int(getattr(node, 'executor_threads', 1))
    if choice != 'single' and threads > 1:
        return MultiThreadedExecutor(num_threads=threads, context=node.context)
    return SingleThreadedExecutor(context=node.context)


#: Longest wait in one ``spin_once``: how late a stop request is seen at most (between two
#: callbacks).
SPIN_PERIOD_S = 0.1

#: After a stop signal during start-up, the longest the start-up may still take before the
#: process ends at once [wall s] (:class:`StopSignals`); well within ``ros2 launch``'s SIGTERM
#: timeout (``graphs.STOP_TIMEOUT_S``, 20 s).
START_UP_DEADLINE_S = 5.0

#: While draining (:func:`drain_inputs`): the input queues count as empty after this many wall
#: seconds without a new input handled.
DRAIN_QUIET_S = 0.2


def drain_inputs(executor, node) -> int:
    """
    Handle the inputs that already arrived before the node stops; return how many.

    A stop signal ends the spin between two callbacks, and whatever the DDS readers hold then was
    received (and acknowledged to a reliable writer) but would never reach a callback: for the
    error evaluator, frames that the simulator published and the final report then missed (the sim
    graph's evaluator counted 3 of its 5 truth frames once on a loaded CI machine, stopping
    0.66 s after the estimator it was started with). A node opts in with ``drain_on_stop_s`` (the
    longest drain, wall seconds) and ``inputs_handled()`` (a count that grows with every input it
    handles); the drain spins until ``DRAIN_QUIET_S`` pass without a new input or the budget is
    spent, so a live stream cannot keep it going. Other nodes stop at once, as before.
    """
    budget_s = float(getattr(node, 'drain_on_stop_s', 0.0) or 0.0)
    handled = getattr(node, 'inputs_handled', None)
    if budget_s <= 0.0 or handled is None:
        return 0
    start = last = handled()
    t0 = t_progress = time.monotonic()
    while True:
        now = time.monotonic()
        if now - t0 >= budget_s or now - t_progress >= DRAIN_QUIET_S:
            return handled() - start
        executor.spin_once(timeout_sec=min(DRAIN_QUIET_S / 4, t0 + budget_s - now))
        n = handled()
        if n != last:
            last, t_progress = n, time.monotonic()


class StopSignals:
    """
    SIGINT and SIGTERM handlers that record a stop request instead of raising.

    ``received`` lists the signal numbers in arrival order. While ``interrupt_now`` is true (the
    node is being built: pure Python and numba compilation, no executor calling back into Python),
    the first signal raises :class:`KeyboardInterrupt` so that a long warm-up does not delay the
    stop. The interrupt cannot reach Python while numba's compiler runs in C, and inside its C
    callbacks it is lost (below), so the compilation may go on for tens of seconds past
    ``ros2 launch``'s SIGTERM and SIGKILL: with ``start_up_deadline_s`` (a console script's
    process), a start-up still running that long after the first signal ends the process at once
    (exit 0; there is no node yet, nothing to publish or save).

    That interrupt can land inside a callback from C (llvmlite calls numba's object cache
    through ctypes while it compiles), where Python cannot raise it: it printed "Exception ignored
    on calling ctypes callback function" with a traceback, and the compilation then failed on its
    own. Seen with one Ctrl-C while a sim graph's estimators compiled on an empty cache. The stop
    is recorded all the same, so such an unraisable ``KeyboardInterrupt`` is dropped silently
    (``sys.unraisablehook``, while installed); any other unraisable exception still goes to the
    previous hook.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self, name: str = 'node', start_up_deadline_s: float | None = None):
        self.received: list[int] = []
        self.interrupt_now = False
        self.name = name
        self.start_up_deadline_s = start_up_deadline_s
        self._deadline = None
        self._previous: dict = {}
        self._previous_unraisable = None

    def install(self) -> 'StopSignals':
        for s in self.SIGNALS:
            self._previous[s] = signal.signal(s, self._handler)
        self._previous_unraisable = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        return self

    def restore(self) -> None:
        """Put back the handlers that were there before :meth:`install`."""
        for s, h in self._previous.items():
            signal.signal(s, h)
        self._previous.clear()
        if self._previous_unraisable is not None:
            sys.unraisablehook = self._previous_unraisable
            self._previous_unraisable = None

    def _unraisable(self, info) -> None:
        if isinstance(info.exc_value, KeyboardInterrupt) and self.requested:
            return  # our own start-up interrupt, raised where it cannot propagate: recorded
        (self._previous_unraisable or sys.__unraisablehook__)(info)

    @property
    def requested(self) -> bool:
        return bool(self.received)

    def names(self) -> str:
        return '+'.join(signal.Signals(s).name for s in self.received)

    def _handler(self, signum, frame):
        self.received.append(int(signum))
        if self.interrupt_now and self.start_up_deadline_s is not None and self._deadline is None:
            self._deadline = threading.Timer(self.start_up_deadline_s, self._start_up_overdue)
            self._deadline.daemon = True
            self._deadline.start()
        if self.interrupt_now and len(self.received) == 1:
            raise KeyboardInterrupt

    def end_start_up(self) -> None:
        """Mark the start-up over: no more interrupts, and no deadline."""
        self.interrupt_now = False
        if self._deadline is not None:
            self._deadline.cancel()

    def _start_up_overdue(self) -> None:
        """End the process: a stop came during start-up, and the start-up has not ended since."""
        if not self.interrupt_now:
            return
        print(
            f'{self.name}: stopped during start-up ({self.names()}); exiting without waiting '
            'for the compilation',
            flush=True,
        )
        try:
            sys.stderr.flush()
        finally:
            os._exit(0)


def run_node(factory, name: str, argv=None, exit_process: bool | None = None) -> int:
    """
    Run a node: start ROS, spin until a stop, then stop in order.

    Start ROS, build the node with ``factory()``, spin it until a stop signal, ``node.exit_code``
    or :class:`ExitRequest`, then stop in order (``close()``, executor, node, rclpy context). The
    exit code is 0 after a stop signal or a normal end, 2 for a configuration error (one line on
    stderr). With ``exit_process`` (default: when ``argv`` is None, i.e. a console script's
    ``main()``) the process ends here with that code (see the module docstring); otherwise it is
    returned and the signal handlers that were there before are put back (a test calling
    ``main([...])`` in-process).
    """
    if exit_process is None:
        exit_process = argv is None
    # before anything slow: no signal is lost or raised from here on
    stop = StopSignals(name, START_UP_DEADLINE_S if exit_process else None).install()
    try:
        code = _run(factory, name, argv, stop)
    finally:
        if not exit_process:
            stop.restore()
    if exit_process:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001 - a closed pipe must not change the exit code
                pass
        os._exit(code)
    return code


def _run(factory, name: str, argv, stop: StopSignals) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    keep_large_buffers_in_heap()
    try:
        rclpy.init(
            args=argv if argv is not None else sys.argv,
            signal_handler_options=SignalHandlerOptions.NO,
        )
    except Exception as exc:  # noqa: BLE001 - e.g. malformed --ros-args
        print(f'{name}: error: cannot start ROS: {exc}', file=sys.stderr)
        return 2
    node = None
    executor = None
    code = 0
    try:
        if stop.requested:  # stopped while ROS started: do not build the node at all
            raise KeyboardInterrupt
        stop.interrupt_now = True
        try:
            node = factory()
        except Exception:
            if stop.requested:
                # the start-up interrupt landed where it could not propagate (a C callback of
                # numba's compiler) and the start-up then failed of it: that is the stop, not an
                # error of the node
                raise KeyboardInterrupt from None
            raise
        finally:
            stop.end_start_up()
        executor = make_executor(node)
        executor.add_node(node)
        while not stop.requested and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD_S)
            if getattr(node, 'exit_code', None) is not None:
                code = int(node.exit_code)
                break
        drain_inputs(executor, node)
    except ExitRequest as req:
        code = req.code
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    except CompassError as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        code = 2
    finally:
        if node is not None and stop.requested:
            try:
                node.get_logger().info(f'stopping ({stop.names()})')
            except Exception:  # noqa: BLE001 - logging must not stop the shutdown
                pass
        if node is not None:
            try:
                close = getattr(node, 'close', None)
                if close is not None:
                    close()
            except CompassError as exc:
                print(f'{name}: error while stopping: {exc}', file=sys.stderr)
                code = code or 2
            except Exception as exc:  # noqa: BLE001 - never a traceback at shutdown
                print(
                    f'{name}: error while stopping: {type(exc).__name__}: {exc}', file=sys.stderr
                )
                code = code or 1
        if executor is not None:
            try:
                executor.shutdown(timeout_sec=1.0)
            except Exception:  # noqa: BLE001
                pass
        if node is not None:
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001
                pass
        rclpy.try_shutdown()
        try:
            rclpy.get_default_context().destroy()  # the DDS participant leaves the graph now
        except Exception:  # noqa: BLE001
            pass
    return code
