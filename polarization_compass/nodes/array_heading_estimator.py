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
``array_heading_estimator``: heading from a photodiode-array compass, one node per method.

Subscribes (relative names, remappable):
  ``compass_array/intensities`` std_msgs/Float32MultiArray, units x channels row-major (layout.dim
                         empty or [units, channels]); geometry from ``array_geometry``
  ``compass_array/header`` std_msgs/Header published beside each sample (``array_stamp: header``,
                         the default): the sample takes its stamp and frame_id (stamp_pairing.py);
                         with ``array_stamp: arrival`` a sample is stamped with this node's clock
                         on arrival
  ``imu/data``           sensor_msgs/Imu: the tilt for tilt_aware and the ambiguity prior
                         (prior_source imu)
  ``gps/fix``            sensor_msgs/NavSatFix when site_source is navsatfix
Publishes, stamped with the sample's stamp: ``compass/<method>/heading_raw`` (sensor_msgs/Imu),
``compass/<method>/bearing_raw_deg`` (std_msgs/Float64, true bearing of the body front),
``compass/<method>/status`` (std_msgs/String, JSON, one per sample) and ``/diagnostics``, as
``heading_estimator`` does for a camera (:class:`~.heading_node.HeadingNodeBase`). Its ``knob.*``
parameters are the array knobs (:data:`~polarization_compass.photodiode.knobs.ARRAY_KNOBS`).
"""

from __future__ import annotations

import time

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float32MultiArray, Header

from .diagnostics import _wall_clock
from .heading_node import HeadingNodeBase
from .rosparams import ParameterSet
from .runner import run_node
from ..bag import MessageError, stamp_ns
from ..errors import CompassError
from ..photodiode.geometry import load_array_geometry
from ..photodiode.heading import estimate_recording, make_array_estimator, warm_up_array
from ..photodiode.knobs import ARRAY_KNOBS
from ..photodiode.readings import array_sample_from_flat, ArrayRecordingError
from ..specs import topics
from ..specs.params import ARRAY_ESTIMATOR, knob_params, knob_values
from ..stamp_pairing import StampPairer

__all__ = ['ArrayHeadingEstimatorNode', 'main']

#: History depth [messages] of the sample and header subscriptions: 10 s of a 10 Hz driver, kept
#: while the first estimate compiles its kernels (a reliable reader with a short history loses
#: what it cannot take in time, as a best-effort one does).
ARRAY_DEPTH = 100


class ArrayHeadingEstimatorNode(HeadingNodeBase):
    """The ``array_heading_estimator`` node (see the module docstring)."""

    INPUT_NAME = 'sample'

    def __init__(self, **kwargs):
        super().__init__('array_heading_estimator', **kwargs)
        self.array = None
        self.params = ParameterSet(self, ARRAY_ESTIMATOR, on_change=self._on_change)
        self.method = self.params['method']
        p = self.params
        if not p['array_geometry']:
            raise CompassError('array_heading_estimator needs array_geometry (a sensor YAML)')
        self._geometry = load_array_geometry(p['array_geometry'])
        try:
            knobs = knob_params(self.method, ARRAY_KNOBS)
        except CompassError as exc:
            raise CompassError(f'method {self.method!r}: {exc}') from None
        self.knob_set = ParameterSet(self, knobs, on_change=self._on_knob_change)
        self.array = self._make_array(self.knob_set.values)
        self._warm_up(lambda: warm_up_array(self.array), 'sample')
        self._make_diagnostics(f'array heading estimator ({self.method})')
        self.pairer = None  # array_stamp header: pairs each sample with its header
        self.executor_threads = 2
        small, samples = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
        self._start_common(p, small)
        self._subscribe_array(samples)
        self.get_logger().info(
            f'method {self.method}: {topics.method_topics(self.method)["heading_raw"]} from '
            f'{topics.ARRAY}'
        )

    def _subscribe_array(self, samples) -> None:
        """Subscribe to the samples (and their headers); time the waits of the queue."""
        p = self.params
        # deep queues: a sample waits in its reader's history while an estimate (the first one
        # compiles or loads its kernels, seconds) or a busy CPU holds the callbacks, and a history
        # of 5 silently replaced the older ones (counted nowhere, not even as received)
        reliability = (
            ReliabilityPolicy.BEST_EFFORT
            if p['array_qos'] == 'sensor_data'
            else ReliabilityPolicy.RELIABLE
        )
        qos = QoSProfile(depth=ARRAY_DEPTH, reliability=reliability)
        self.create_subscription(
            Float32MultiArray, topics.ARRAY, self._on_array, qos, callback_group=samples
        )
        if p['array_stamp'] == 'header':
            self.pairer = StampPairer(p['array_header_tolerance_s'], p['array_header_timeout_s'])
            self._pair_drops_seen: dict = {}
            # same callback group as the samples: the pairer is used from one thread only, and a
            # header and its sample reach their callbacks one after the other (the arrival times
            # the pairing compares)
            self.create_subscription(
                Header, topics.ARRAY_HEADER, self._on_array_header, qos, callback_group=samples
            )
            self.create_timer(
                0.05, self._expire_array_pairs, callback_group=samples, clock=_wall_clock()
            )
        if self.needs_tilt:
            self.create_timer(
                0.02, self._drain, callback_group=samples, clock=_wall_clock()
            )  # IMU 50+ Hz

    # parameters ---------------------------------------------------------------------------------
    def _on_change(self, changed: dict):
        if self.array is None:
            return None
        try:
            self._update_common(changed, {**self.params.values, **changed})
        except CompassError as exc:
            return str(exc)
        return None

    def _make_array(self, values: dict):
        return make_array_estimator(
            self.method, self._geometry, **knob_values(self.method, values, ARRAY_KNOBS)
        )

    def _on_knob_change(self, changed: dict):
        if self.array is None:
            return None
        try:
            self.array = self._make_array({**self.knob_set.values, **changed})
        except (CompassError, ValueError) as exc:
            return str(exc)
        return None

    # inputs -------------------------------------------------------------------------------------
    def _on_array(self, msg):
        """
        Decode a sample, stamp it and queue it.

        Decoded against the geometry, stamped by its paired header (or on arrival with
        array_stamp arrival), then queued and processed.
        """
        arrived_ns = time.monotonic_ns()
        t_in = self.diag.input()
        geometry = self.array.geometry

        def decode(m):
            try:
                return array_sample_from_flat(
                    m.data, [d.size for d in m.layout.dim], m.layout.data_offset, geometry
                )
            except ArrayRecordingError as exc:
                raise MessageError('array_layout', str(exc)) from None

        sample = self.diag.decoded('', decode, msg)
        if sample is None:
            if self.pairer is not None:  # it still takes its header with it (never the next one)
                self._enqueue_paired(self.pairer.add_array(arrived_ns, arrived_ns / 1e9, None))
            return
        if self.pairer is None:
            self._queue(self.get_clock().now().nanoseconds, sample, t_in, None)
        else:
            self._enqueue_paired(
                self.pairer.add_array(arrived_ns, arrived_ns / 1e9, (sample, t_in))
            )
        self._drain()

    def _on_array_header(self, msg):
        """Keep the companion header of a sample (array_stamp header)."""
        arrived_ns = time.monotonic_ns()
        self._enqueue_paired(
            self.pairer.add_header(arrived_ns, arrived_ns / 1e9, stamp_ns(msg.stamp), msg.frame_id)
        )
        self._drain()

    def _expire_array_pairs(self) -> None:
        self.pairer.expire(time.monotonic())
        self._count_pair_drops()

    def _queue(self, t_ns: int, sample, t_in: float, frame_id) -> None:
        self.pending.append(
            (
                t_ns,
                sample,
                None,
                None,
                t_in,
                time.monotonic() + self.params['imu_max_wait_s'],
                frame_id,
            )
        )

    def _enqueue_paired(self, paired) -> None:
        """Queue the samples that found their header; count the pairer's drops in /diagnostics."""
        for s in paired:
            if s.payload is None:  # a sample rejected when decoded: already counted
                continue
            sample, t_in = s.payload
            frame_id = s.frame_id or self.params['frame_id']
            if frame_id.endswith(('_optical_frame', '_optical')):
                self.diag.reject(
                    'array_header_optical_frame',
                    f'header frame_id {frame_id!r} is an optical '
                    'frame (z forward); the heading needs a z-up frame',
                )
                continue
            self._queue(s.stamp_ns, sample, t_in, frame_id)
        self._count_pair_drops()

    def _count_pair_drops(self) -> None:
        for reason, n in self.pairer.drops.items():
            for _ in range(n - self._pair_drops_seen.get(reason, 0)):
                self.diag.reject(
                    f'array_{reason}',
                    'array sample without its header'
                    if reason != 'header_without_array'
                    else 'header without its array sample',
                )
            self._pair_drops_seen[reason] = n

    # one sample ---------------------------------------------------------------------------------
    def _estimate(self, prepared, sample, sun_az, sun_alt, inp, status: dict):
        """Return the heading of one sample, checked against the IMU prior."""
        result = estimate_recording(
            self.array,
            sample[None],
            sun_az,
            sun_alt,
            inp.pitch_deg,
            inp.roll_deg,
            inp.prior_bearing_deg,
        )[0]
        return self.tilt_prior.checked(result, inp)  # heading vs. the IMU prior (a named step)


def main(argv=None) -> int:
    """
    Run the node (the ``array_heading_estimator`` console script).

    Parameters
    ----------
    argv : list of str, optional
        ROS arguments; None: the process's.

    Returns
    -------
    int
        The exit code (:func:`~.runner.run_node`).

    """
    return run_node(ArrayHeadingEstimatorNode, 'array_heading_estimator', argv)


if __name__ == '__main__':
    raise SystemExit(main())
