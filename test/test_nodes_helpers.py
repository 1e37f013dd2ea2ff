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
Helpers for the DDS integration tests.

Node executables started as processes with a test's environment, and a recording rclpy node in the
test process on the same (loopback) domain.
"""

from __future__ import annotations

from collections import defaultdict
import json
from pathlib import Path
import signal
import subprocess
import time

import numpy as np
from polarization_compass.graphs import node_command

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / 'config'
SHM_PROFILE = CONFIG / 'fastdds_large_images.xml'

SMALL_SCENE = """\
name: small_paper_fov
camera: {model: pinhole, width_px: 612, height_px: 512, focal_length_mm: 4.0,
         pixel_pitch_x_um: 13.8, pixel_pitch_y_um: 13.8}
"""


def node_env(ros_env: dict) -> dict:
    env = dict(ros_env)
    env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(SHM_PROFILE)
    env['NUMBA_NUM_THREADS'] = '1'
    return env


def stop_process(p: subprocess.Popen, timeout: float, *logs) -> int:
    """
    Stop a node process (SIGINT, then kill) and return its exit code.

    SIGINT (a node's clean shutdown), then kill after ``timeout`` s; close the log files; the exit
    code.
    """
    if p.poll() is None:
        p.send_signal(signal.SIGINT)
    try:
        p.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()
    for f in logs:
        f.close()
    return p.returncode


class Proc:
    """A node executable running as a process, its output in log files."""

    def __init__(self, name: str, exe: str, ros_args: list, env: dict, log_dir: Path):
        self.name = name
        log_dir.mkdir(parents=True, exist_ok=True)
        self.out_path = log_dir / f'{name}.out'
        self.err_path = log_dir / f'{name}.err'
        self._out = open(self.out_path, 'w')
        self._err = open(self.err_path, 'w')
        self.p = subprocess.Popen(
            [*node_command(exe), '--ros-args', '-r', f'__node:={name}', *ros_args],
            env=env,
            stdout=self._out,
            stderr=self._err,
        )

    def alive(self) -> bool:
        return self.p.poll() is None

    def stop(self, timeout: float = 20.0) -> int:
        return stop_process(self.p, timeout, self._out, self._err)

    def wait(self, timeout: float) -> int:
        self.p.wait(timeout=timeout)
        self._out.close()
        self._err.close()
        return self.p.returncode

    @property
    def stderr(self) -> str:
        return self.err_path.read_text(errors='replace')

    @property
    def stdout(self) -> str:
        return self.out_path.read_text(errors='replace')


class Recorder:
    """An rclpy node in the test process (own context, the test's domain) recording messages."""

    def __init__(self, domain_id: int, name: str = 'test_recorder'):
        import warnings

        with warnings.catch_warnings():
            # rclpy's type support imports lark, which imports the deprecated sre_parse (third
            # party)
            warnings.simplefilter('ignore', DeprecationWarning)
            import rosidl_generator_py  # noqa: F401
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.rclpy = rclpy
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=int(domain_id))
        self.node = Node(name, context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.msgs = defaultdict(list)  # topic -> [(wall time, msg)]

    def sub(self, msg_type, topic: str, depth: int = 500):
        from rclpy.qos import QoSProfile

        self.node.create_subscription(
            msg_type,
            topic,
            lambda m, t=topic: self.msgs[t].append((time.monotonic(), m)),
            QoSProfile(depth=depth),
        )

    def pub(self, msg_type, topic: str, depth: int = 50):
        from rclpy.qos import QoSProfile

        return self.node.create_publisher(msg_type, topic, QoSProfile(depth=depth))

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.02)

    def spin_until(self, cond, timeout: float, procs=()) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return True
            for p in procs:
                if not p.alive():
                    raise AssertionError(f'{p.name} died: {p.stderr[-2000:]}')
            self.ex.spin_once(timeout_sec=0.02)
        return cond()

    def statuses(self, topic: str) -> list[dict]:
        return [json.loads(m.data) for _, m in self.msgs[topic]]

    def node_topics(self, name: str, ns: str = '/'):
        pubs = {
            t: tuple(ty) for t, ty in self.node.get_publisher_names_and_types_by_node(name, ns)
        }
        subs = {
            t: tuple(ty) for t, ty in self.node.get_subscriber_names_and_types_by_node(name, ns)
        }
        return pubs, subs

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.ctx)


def quat(m):
    return np.array([m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w])


def stamp(m) -> int:
    return int(m.header.stamp.sec) * 1_000_000_000 + int(m.header.stamp.nanosec)


def no_traceback(text: str) -> bool:
    return 'Traceback' not in text


def zenith_evaluator(context, report_dir):
    """Return an in-process ``error_evaluator`` scoring only ``zenith/raw``, on ``context``."""
    from polarization_compass.nodes.error_evaluator import ErrorEvaluatorNode
    from rclpy.parameter import Parameter

    return ErrorEvaluatorNode(
        context=context,
        parameter_overrides=[
            Parameter('report_dir', value=str(report_dir)),
            Parameter('methods', value=['zenith']),
            Parameter('direct_methods', value=['']),
            Parameter('include_corrected', value=False),
        ],
    )
