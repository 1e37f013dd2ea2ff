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
Pair header-less sensor messages with the companion header their driver publishes for each of them.

A photodiode-array driver publishes each sample as ``std_msgs/Float32MultiArray`` (no header) on
``compass_array/intensities`` and, right beside it, a ``std_msgs/Header`` on
``compass_array/header`` carrying the sample's acquisition ``stamp`` and ``frame_id``
(docs/photodiode-arrays.md, "Stamps"). The two messages share no field, so they are matched by
*arrival time*: the receiver's monotonic clock when each message's callback starts (both callbacks
in one callback group, so they run one after the other). A driver publishes the two back to back,
so they arrive nearly together, and a sample interval apart from the neighbouring sample's.
(rclpy's ``MessageInfo`` source timestamp would be a better key, but Kilted's EventsExecutor, the
nodes' default, fails with ``SystemError`` on callbacks that take it.) Within each topic messages
keep their order (one writer), so the pairing walks both queues from the oldest:

- the oldest array and the oldest header are a pair when their arrival times differ by at most
  ``tolerance_s``;
- otherwise the older of the two has lost its partner (a best-effort message that never arrived):
  an array is dropped with reason ``no_header``, a header is discarded (``header_without_array``);
- an array still without a header ``timeout_s`` after it arrived is dropped with reason
  ``header_timeout``; a header alone that long is discarded (``header_without_array``).

Dropped arrays are counted by reason, never stamped with another sample's time. Correct pairing
needs ``tolerance_s`` below half the shortest interval between two samples and above the receiver's
callback delay between the two messages (one callback's duration at most; an array's estimate takes
about a millisecond); the default 40 ms suits drivers up to 12 Hz -- set it lower for faster
drivers.

ROS-free: no rclpy import here.
"""

from __future__ import annotations

import bisect
from collections import Counter
from dataclasses import dataclass, field

__all__ = ['PairedSample', 'StampPairer', 'DROP_REASONS']

#: Why an array (or a header) was dropped; the node counts them as ``rejected.array_<reason>``.
DROP_REASONS = (
    'no_header',
    'header_timeout',
    'header_without_array',
    'header_zero_stamp',
    'queue_full',
)


@dataclass(frozen=True)
class PairedSample:
    """
    An array payload with the stamp and frame of its header.

    Attributes
    ----------
    stamp_ns : int
        The header's ``stamp`` [ns] (the sample's acquisition time).
    frame_id : str
        The header's ``frame_id``.
    payload : object
        What was passed to :meth:`StampPairer.add_array` (the decoded sample).
    arrived_s : float
        When the array arrived (the caller's wall clock) [s].

    """

    stamp_ns: int
    frame_id: str
    payload: object
    arrived_s: float


@dataclass(order=True)
class _Entry:
    key_ns: int
    seq: int
    arrived_s: float = field(compare=False)
    value: object = field(compare=False)


class StampPairer:
    """
    Match arrays and headers by arrival time (see the module docstring for the rules).

    Parameters
    ----------
    tolerance_s : float, default 0.04
        Largest difference of the arrival times (``key_ns``) [s] of an array and its header.
    timeout_s : float, default 0.5
        Longest wait [s] (receiver's wall clock) of an array for its header, and of a header for
        its array.
    max_pending : int, default 100
        Arrays (and headers) kept waiting at most; the oldest beyond it is dropped
        (``queue_full``).

    Attributes
    ----------
    drops : collections.Counter
        Dropped arrays and discarded headers by reason (:data:`DROP_REASONS`).
    paired : int
        Arrays paired so far.

    Raises
    ------
    ValueError
        On construction, when ``tolerance_s`` or ``timeout_s`` is negative (or NaN) or
        ``max_pending`` is below 1.

    """

    def __init__(self, tolerance_s: float = 0.04, timeout_s: float = 0.5, max_pending: int = 100):
        if not (tolerance_s >= 0.0 and timeout_s >= 0.0 and max_pending >= 1):
            raise ValueError(
                'StampPairer: tolerance_s and timeout_s must be >= 0 and max_pending >= 1'
            )
        self.tolerance_ns = int(round(tolerance_s * 1e9))
        self.timeout_s = float(timeout_s)
        self.max_pending = int(max_pending)
        self.drops: Counter = Counter()
        self.paired = 0
        self._arrays: list[_Entry] = []
        self._headers: list[_Entry] = []
        self._seq = 0

    @property
    def pending_arrays(self) -> int:
        """Arrays waiting for their header."""
        return len(self._arrays)

    def add_array(self, key_ns: int, arrived_s: float, payload) -> list[PairedSample]:
        """
        Add an array message.

        Parameters
        ----------
        key_ns : int
            Its arrival time [ns] (the pairing key; any clock common to arrays and headers).
        arrived_s : float
            When it arrived [s] (receiver's wall clock, for the timeout).
        payload : object
            The decoded sample, handed back in the :class:`PairedSample`.

        Returns
        -------
        list of PairedSample
            Arrays paired by this call, oldest first (possibly empty).

        """
        self._insert(self._arrays, key_ns, arrived_s, payload, 'no_header')
        return self._match()

    def add_header(
        self, key_ns: int, arrived_s: float, stamp_ns: int, frame_id: str
    ) -> list[PairedSample]:
        """
        Add a companion header.

        Parameters
        ----------
        key_ns : int
            Its arrival time [ns] (the pairing key).
        arrived_s : float
            When it arrived [s] (receiver's wall clock).
        stamp_ns : int
            The header's stamp [ns]; 0 (a driver that did not fill it) pairs with its array and
            drops it (``header_zero_stamp``): a zero stamp is never published.
        frame_id : str
            The header's frame_id.

        Returns
        -------
        list of PairedSample
            Arrays paired by this call, oldest first.

        """
        self._insert(
            self._headers,
            key_ns,
            arrived_s,
            (int(stamp_ns), str(frame_id)),
            'header_without_array',
        )
        return self._match()

    def expire(self, now_s: float) -> list[PairedSample]:
        """
        Drop what waited longer than ``timeout_s``.

        Parameters
        ----------
        now_s : float
            The receiver's wall clock [s] (same clock as ``arrived_s``).

        Returns
        -------
        list of PairedSample
            Always empty (kept for symmetry: nothing pairs by waiting); the drops are in
            :attr:`drops`.

        """
        limit = now_s - self.timeout_s
        # only the oldest entries can be stale (arrival order follows publication order per topic)
        while self._arrays and self._arrays[0].arrived_s < limit:
            self._arrays.pop(0)
            self.drops['header_timeout'] += 1
        while self._headers and self._headers[0].arrived_s < limit:
            self._headers.pop(0)
            self.drops['header_without_array'] += 1
        return []

    # internals ----------------------------------------------------------------------------------
    def _insert(
        self, queue: list, key_ns: int, arrived_s: float, value, overflow_reason: str
    ) -> None:
        self._seq += 1
        bisect.insort(queue, _Entry(int(key_ns), self._seq, float(arrived_s), value))
        while len(queue) > self.max_pending:
            queue.pop(0)
            self.drops['queue_full' if overflow_reason == 'no_header' else overflow_reason] += 1

    def _match(self) -> list[PairedSample]:
        out = []
        while self._arrays and self._headers:
            a, h = self._arrays[0], self._headers[0]
            d = a.key_ns - h.key_ns
            if abs(d) <= self.tolerance_ns:
                self._arrays.pop(0)
                self._headers.pop(0)
                stamp_ns, frame_id = h.value
                if stamp_ns <= 0:
                    self.drops['header_zero_stamp'] += 1
                    continue
                self.paired += 1
                out.append(PairedSample(stamp_ns, frame_id, a.value, a.arrived_s))
            elif d > 0:  # the header is older than the array by more than the tolerance
                self._headers.pop(0)
                self.drops['header_without_array'] += 1
            else:  # the array is older: its header was lost
                self._arrays.pop(0)
                self.drops['no_header'] += 1
        return out
