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
The ``player_flow`` node: pause ``ros2 bag play`` while an estimator is behind, resume it after.

``ros2 bag play`` publishes at the recorded rate whatever its readers do; a heading estimator
slower than the camera then holds every waiting full-resolution image (10 MB each) in memory, the
middleware loses frames once its queues are full (a 12 s full-resolution bag at 1x on 2 cores: 21
of 120 frames lost). This node gives the replay flow control with the player's own services
(``rosbag2_interfaces`` ``Pause``/``Resume``/``IsPaused``): it counts, per estimator, the
camera_info stamps the player has published that are newer than the newest frame the estimator
has answered on its ``status`` topic (one message per image, failures included). When one
estimator is ``high_water`` frames behind, the player is paused (its ``/clock`` stops with it);
once every estimator is back within ``low_water`` frames it is resumed. A frame lost on the way
does not hold the player: the next answered frame moves the count past it.

It only resumes a pause it made (a player paused by hand or by the launch's start-up stays
paused), and it never holds the player longer than ``max_pause_s`` without an answer from the
estimator it waits for (a node that died): then it resumes, says so, and stops controlling.

``replay.launch.py`` starts it next to the player; with a player started by hand run it as
``ros2 run polarization_compass player_flow --ros-args -p status_topics:=[...]``.
"""

from __future__ import annotations

from collections import deque
import json
import time

from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import String

from .rosparams import ParameterSet
from .runner import run_node
from ..bag import stamp_ns
from ..specs.params import PLAYER_FLOW

__all__ = ['Backlog', 'PlayerFlowNode', 'main']


class Backlog:
    """
    Frames published but not yet answered, per estimator, from stamps alone (ROS-free).

    Parameters
    ----------
    names : iterable of str
        The estimators (their status streams).
    high_water, low_water : int
        Pause at ``high_water`` frames behind (any estimator), resume at ``low_water`` (all).

    """

    def __init__(self, names, high_water: int, low_water: int):
        if not 0 <= low_water < high_water:
            raise ValueError(f'need 0 <= low_water < high_water, got {low_water}, {high_water}')
        self.high_water, self.low_water = int(high_water), int(low_water)
        self.done_ns = dict.fromkeys(names)  # newest answered stamp per estimator
        self._published: deque = deque()  # published stamps, ascending, not yet answered by all

    def published(self, stamp_ns: int) -> None:
        """Count one frame the player has sent out, by its camera_info stamp [ns]."""
        if not self._published or stamp_ns > self._published[-1]:
            self._published.append(int(stamp_ns))

    def answered(self, name: str, stamp_ns: int) -> None:
        """Count one frame an estimator has answered, by its status stamp [ns]."""
        prev = self.done_ns.get(name)
        if name in self.done_ns and (prev is None or stamp_ns > prev):
            self.done_ns[name] = int(stamp_ns)
        if any(d is None for d in self.done_ns.values()):
            return  # someone has answered nothing yet: every published frame still counts
        oldest = min(self.done_ns.values(), default=None)
        while self._published and oldest is not None and self._published[0] <= oldest:
            self._published.popleft()

    def behind(self) -> dict:
        """Return ``{estimator: frames published after its newest answered one}``."""
        return {
            n: sum(1 for s in self._published if d is None or s > d)
            for n, d in self.done_ns.items()
        }

    def should_pause(self) -> bool:
        """Return True when some estimator is ``high_water`` frames behind or more."""
        return max(self.behind().values(), default=0) >= self.high_water

    def may_resume(self) -> bool:
        """Return True when every estimator is within ``low_water`` frames."""
        return max(self.behind().values(), default=0) <= self.low_water


class PlayerFlowNode(Node):
    """The ``player_flow`` node (see the module docstring)."""

    def __init__(self, **kwargs):
        from rosbag2_interfaces.srv import IsPaused, Pause, Resume

        super().__init__('player_flow', **kwargs)
        self.params = ParameterSet(self, PLAYER_FLOW)
        p = self.params
        status_topics = [t for t in p.strings('status_topics') if t]
        self.backlog = Backlog(status_topics, p['high_water'], p['low_water'])
        player = p['player'].rstrip('/')
        self.srv = {
            'pause': (Pause, self.create_client(Pause, f'{player}/pause')),
            'resume': (Resume, self.create_client(Resume, f'{player}/resume')),
            'is_paused': (IsPaused, self.create_client(IsPaused, f'{player}/is_paused')),
        }
        self.we_paused = False  # only a pause made here is resumed here
        self.pending = None  # the service call in flight
        self.paused_at = 0.0
        self.pauses = 0
        self.enabled = bool(status_topics)
        deep = QoSProfile(depth=500)  # the player publishes reliably; never lose a stamp here
        self.create_subscription(CameraInfo, p['camera_info_topic'], self._on_info, deep)
        for t in status_topics:
            self.create_subscription(String, t, lambda m, n=t: self._on_status(n, m), deep)
        self.create_timer(0.2, self._check)
        self.get_logger().info(
            f'flow control of {player}: pause at {p["high_water"]} frames behind, resume at '
            f'{p["low_water"]}; estimators: {", ".join(status_topics) or "none (disabled)"}'
        )

    def _on_info(self, msg) -> None:
        self.backlog.published(stamp_ns(msg.header))
        self._check()

    def _on_status(self, name: str, msg) -> None:
        try:
            t_ns = int(json.loads(msg.data)['stamp_ns'])
        except (ValueError, TypeError, KeyError):
            return  # a status without a stamp says nothing about the backlog
        self.backlog.answered(name, t_ns)
        if self.we_paused:  # progress while paused: the stall clock starts again
            self.paused_at = time.monotonic()
        self._check()

    def _call(self, name: str, then) -> None:
        srv, client = self.srv[name]
        if not client.service_is_ready():
            return
        self.pending = client.call_async(srv.Request())
        self.pending.add_done_callback(lambda f: self._done(f, then))

    def _done(self, future, then) -> None:
        self.pending = None
        try:
            then(future.result())
        except Exception as exc:  # noqa: BLE001 - a failed call is retried on the next check
            self.get_logger().warning(f'player service call failed: {exc}')

    def _check(self) -> None:
        if not self.enabled or self.pending is not None:
            return
        if not self.we_paused and self.backlog.should_pause():
            self._call('is_paused', self._pause_unless_paused)
        elif self.we_paused and self.backlog.may_resume():
            self._call('resume', self._resumed)
        elif self.we_paused and time.monotonic() - self.paused_at > self.params['max_pause_s']:
            self.get_logger().warning(
                f'no estimator progress for {self.params["max_pause_s"]:g} s while paused '
                f'(behind: {self.backlog.behind()}); resuming and no longer controlling the player'
            )
            self.enabled = False
            self._call('resume', lambda _r: None)

    def _pause_unless_paused(self, result) -> None:
        if result.paused:
            return  # paused by someone else: theirs to resume
        self._call('pause', self._paused)

    def _paused(self, _result) -> None:
        self.we_paused, self.paused_at = True, time.monotonic()
        self.pauses += 1
        self.get_logger().info(
            f'player paused ({self.pauses}): behind {self.backlog.behind()}',
            throttle_duration_sec=5.0,
        )

    def _resumed(self, _result) -> None:
        self.we_paused = False


def main(argv=None) -> int:
    return run_node(PlayerFlowNode, 'player_flow', argv)


if __name__ == '__main__':
    raise SystemExit(main())
