"""``main()`` of every node: start, spin, and stop cleanly.

* A configuration error (bad parameter, missing error map, missing optional package) prints one line
  ``<node>: error: ...`` on stderr and exits 2, as the CLI does.
* SIGINT / SIGTERM (Ctrl-C, ``ros2 launch`` shutting down) end the spin; the node's ``close()`` runs
  (the evaluator writes its report there) and the process exits 0 without a traceback.
* A node may end itself (the simulator after its last frame) by setting ``node.exit_code`` (checked
  after every spin; no exception crosses the executor, whose C++ implementation logs every callback
  exception as FATAL with a traceback), or by raising :class:`ExitRequest` in a callback.
* The executor is rclpy's C++ ``EventsExecutor`` where rclpy has it (Kilted and later): it dispatches
  callbacks in arrival order at about a third of the CPU cost per callback of the Python executors
  (measured here: 0.36 ms against 1.0 ms single-threaded and 1.8 ms multi-threaded per small message,
  on a loaded machine), which matters with eleven nodes on two cores receiving /clock, IMU and
  heading messages. Arrival order also keeps the IMU flowing between images. Where it is missing
  (Jazzy), a node with ``executor_threads = N > 1`` spins on a MultiThreadedExecutor (the estimator:
  small inputs such as the IMU keep flowing while an image is being processed), others on a
  SingleThreadedExecutor. ``POLARIZATION_COMPASS_EXECUTOR=single|multi`` forces the Python executors.
* Before ROS starts, glibc's allocator is told to keep large blocks in the heap
  (:func:`keep_large_buffers_in_heap`): a 10 MB image otherwise costs every subscriber three fresh
  ``mmap`` regions per message, zero-filled by the kernel page by page (measured: 21 ms of system
  time and 7300 page faults per 2448x2048 mono16 image per subscriber; 0.2 ms and none with it).
"""
from __future__ import annotations

import os
import sys

from ..errors import CompassError
from ..runtime import keep_large_buffers_in_heap

__all__ = ["run_node", "ExitRequest", "keep_large_buffers_in_heap", "make_executor"]

class ExitRequest(Exception):
    """Raised inside a callback to end the node's spin with an exit code."""

    def __init__(self, code: int = 0):
        super().__init__(code)
        self.code = int(code)


def make_executor(node):
    """The executor for ``node`` (see the module docstring)."""
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

    choice = os.environ.get("POLARIZATION_COMPASS_EXECUTOR", "events").strip().lower()
    if choice == "events":
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:
            choice = ""
        else:
            return EventsExecutor()
    threads = int(getattr(node, "executor_threads", 1))
    if choice != "single" and threads > 1:
        return MultiThreadedExecutor(num_threads=threads)
    return SingleThreadedExecutor()


def run_node(factory, name: str, argv=None) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException

    keep_large_buffers_in_heap()
    try:
        rclpy.init(args=argv if argv is not None else sys.argv)
    except Exception as exc:  # noqa: BLE001 - e.g. malformed --ros-args
        print(f"{name}: error: cannot start ROS: {exc}", file=sys.stderr)
        return 2
    node = None
    code = 0
    try:
        node = factory()
        executor = make_executor(node)
        executor.add_node(node)
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
            if getattr(node, "exit_code", None) is not None:
                code = int(node.exit_code)
                break
    except ExitRequest as req:
        code = req.code
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    except CompassError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        code = 2
    finally:
        if node is not None:
            try:
                close = getattr(node, "close", None)
                if close is not None:
                    close()
            except CompassError as exc:
                print(f"{name}: error while stopping: {exc}", file=sys.stderr)
                code = code or 2
            except Exception as exc:  # noqa: BLE001 - never a traceback at shutdown
                print(f"{name}: error while stopping: {type(exc).__name__}: {exc}", file=sys.stderr)
                code = code or 1
            try:
                node.destroy_node()
            except Exception:  # noqa: BLE001
                pass
        rclpy.try_shutdown()
    return code
