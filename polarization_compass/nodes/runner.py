"""``main()`` of every node: start, spin, and stop cleanly.

* A configuration error (bad parameter, missing error map, missing optional package) prints one line
  ``<node>: error: ...`` on stderr and exits 2, as the CLI does.
* SIGINT / SIGTERM (Ctrl-C, ``ros2 launch`` shutting down) end the spin; the node's ``close()`` runs
  (the evaluator writes its report there) and the process exits 0 without a traceback.
* A node may end itself (the simulator after its last frame) by raising :class:`ExitRequest`.
* A node with ``executor_threads = N > 1`` spins on a MultiThreadedExecutor (the estimator: small
  inputs such as the IMU keep flowing while an image is being processed).
"""
from __future__ import annotations

import sys

from ..errors import CompassError

__all__ = ["run_node", "ExitRequest"]


class ExitRequest(Exception):
    """Raised inside a callback to end the node's spin with an exit code."""

    def __init__(self, code: int = 0):
        super().__init__(code)
        self.code = int(code)


def run_node(factory, name: str, argv=None) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor

    try:
        rclpy.init(args=argv if argv is not None else sys.argv)
    except Exception as exc:  # noqa: BLE001 - e.g. malformed --ros-args
        print(f"{name}: error: cannot start ROS: {exc}", file=sys.stderr)
        return 2
    node = None
    code = 0
    try:
        node = factory()
        threads = int(getattr(node, "executor_threads", 1))
        executor = MultiThreadedExecutor(num_threads=threads) if threads > 1 else SingleThreadedExecutor()
        executor.add_node(node)
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
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
