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
``/diagnostics`` for every node: rate, latency, rejected inputs and the last status.

diagnostic_updater is not on PyPI, so this publishes ``diagnostic_msgs/DiagnosticArray`` directly
(the same message the updater sends; ``rqt_runtime_monitor`` and diagnostic_aggregator read it).
One :class:`DiagnosticStatus` per node, once per ``period_s`` (wall clock):

``rate_hz``                processed inputs per second over the last ``window`` inputs (wall clock)
``processing_ms_p50/p95``  wall time from receiving an input to publishing the output
``stamp_age_ms_p95``       node clock now minus the input's stamp when the output left (ROS time:
                           sim time under ``use_sim_time``)
``received`` / ``processed`` / ``rejected`` / ``rejected.<reason>``   counters since start
``last_status``            the last result (e.g. the estimator's status and reason)

Level: ERROR when the node cannot work (``set_error``), WARN when inputs were rejected in the last
period, the last result was not usable, or no input arrived for ``stale_after_s``; OK otherwise.
"""

from __future__ import annotations

from collections import Counter, deque
import math
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
import numpy as np
from rclpy.qos import QoSProfile

from .msgs import kv
from ..bag import MessageError
from ..specs import topics

#: Seconds between two warning lines of the same rejection reason.
REJECT_LOG_PERIOD_S = 5.0

__all__ = ['Diagnostics']


class Diagnostics:
    def __init__(
        self,
        node,
        what: str,
        hardware_id: str = 'polarization_compass',
        period_s: float = 1.0,
        window: int = 100,
        stale_after_s: float = 5.0,
    ):
        self.node = node
        self.name = f'{node.get_name()}: {what}'
        self.hardware_id = hardware_id
        self.received = 0
        self.processed = 0
        self.rejected = Counter()
        self._logged_at: dict = {}  # reason -> monotonic time of its last warning line
        self._rejected_at_last_publish = 0
        self.last_status = 'waiting for input'
        self.last_ok = True
        self.error: str | None = None
        self.extra: dict = {}
        self.stale_after_s = float(stale_after_s)
        self._t_processed = deque(maxlen=window)
        self._proc_ms = deque(maxlen=window)
        self._age_ms = deque(maxlen=window)
        self._t_last_input = None
        self._pub = node.create_publisher(
            DiagnosticArray, topics.DIAGNOSTICS, QoSProfile(depth=10)
        )
        self._timer = node.create_timer(period_s, self.publish, clock=_wall_clock())

    # counters -------------------------------------------------------------------------------
    def input(self) -> float:  # noqa: A003 - counts an input; the public name nodes call
        """Call when an input arrives; returns the wall time to pass to :meth:`done`."""
        self.received += 1
        t = time.perf_counter()
        self._t_last_input = t
        return t

    def done(
        self, t_in: float, stamp_ns: int | None = None, status: str | None = None, ok: bool = True
    ) -> None:
        now = time.perf_counter()
        self.processed += 1
        self._t_processed.append(now)
        self._proc_ms.append((now - t_in) * 1e3)
        if stamp_ns is not None:
            self._age_ms.append((self.node.get_clock().now().nanoseconds - int(stamp_ns)) / 1e6)
        if status is not None:
            self.last_status = status
            self.last_ok = bool(ok)

    def reject(self, reason: str, detail: str = '') -> None:
        """
        Count a dropped input and log it: one line per reason per 5 s.

        Throttled per reason, so that a flood of one kind never hides the first of another.
        """
        self.rejected[reason] += 1
        now = time.monotonic()
        if now - self._logged_at.get(reason, -math.inf) < REJECT_LOG_PERIOD_S:
            return
        self._logged_at[reason] = now
        self.node.get_logger().warning(
            f'dropped an input ({reason}): {detail}' if detail else f'dropped an input ({reason})'
        )

    def decoded(self, what: str, decode, msg, context: str = ''):
        """
        Decode ``msg``, or count the input as rejected and return None.

        ``decode(msg)``, or None after counting the input as rejected with reason ``<what>_<tag>``
        (``<tag>`` the MessageError's ``reason``; just ``<tag>`` when ``what`` is empty).
        """
        try:
            return decode(msg)
        except MessageError as exc:
            tag = getattr(exc, 'reason', 'bad')
            self.reject(f'{what}_{tag}' if what else tag, f'{context}{exc}')
            return None

    def set_error(self, message: str | None) -> None:
        self.error = message

    # reporting ------------------------------------------------------------------------------
    def rate_hz(self) -> float:
        t = self._t_processed
        if len(t) < 2 or t[-1] <= t[0]:
            return 0.0
        return (len(t) - 1) / (t[-1] - t[0])

    def values(self) -> dict:
        proc = np.asarray(self._proc_ms, dtype=float)
        age = np.asarray(self._age_ms, dtype=float)
        v = {
            'rate_hz': self.rate_hz(),
            'received': self.received,
            'processed': self.processed,
            'rejected': sum(self.rejected.values()),
            'last_status': self.last_status,
        }
        if proc.size:
            v['processing_ms_p50'] = float(np.percentile(proc, 50))
            v['processing_ms_p95'] = float(np.percentile(proc, 95))
        if age.size:
            v['stamp_age_ms_p95'] = float(np.percentile(age, 95))
        for reason, n in sorted(self.rejected.items()):
            v[f'rejected.{reason}'] = n
        v.update(self.extra)
        return v

    def level_and_message(self):
        total_rejected = sum(self.rejected.values())
        if self.error:
            return DiagnosticStatus.ERROR, self.error
        if total_rejected > self._rejected_at_last_publish:
            return (
                DiagnosticStatus.WARN,
                f'rejected {total_rejected - self._rejected_at_last_publish} input(s)',
            )
        if (
            self._t_last_input is not None
            and time.perf_counter() - self._t_last_input > self.stale_after_s
        ):
            return DiagnosticStatus.WARN, f'no input for more than {self.stale_after_s:g} s'
        if not self.last_ok:
            return DiagnosticStatus.WARN, self.last_status
        return DiagnosticStatus.OK, self.last_status

    def publish(self) -> None:
        level, message = self.level_and_message()
        self._rejected_at_last_publish = sum(self.rejected.values())
        st = DiagnosticStatus(
            level=level, name=self.name, message=str(message)[:250], hardware_id=self.hardware_id
        )
        st.values = [kv(k, v) for k, v in self.values().items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.node.get_clock().now().to_msg()
        arr.status = [st]
        try:
            self._pub.publish(arr)
        except Exception:  # noqa: BLE001 - the context may be shutting down
            pass


def _wall_clock():
    from rclpy.clock import Clock, ClockType

    return Clock(clock_type=ClockType.STEADY_TIME)
