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
The ``sky_simulator``'s scheduler: the sim clock, lockstep and clock_mode system (a mixin).

Before the first frame it waits for the expected readers; then it publishes every frame and IMU
sample that is due, on the simulated clock (``clock_mode sim``, with ``/clock`` and optional
lockstep) or the node's ROS time (``clock_mode system``). See
:mod:`polarization_compass.nodes.sky_simulator` for the parameters.
"""

from __future__ import annotations

import json
import time

from rosgraph_msgs.msg import Clock

from .msgs import camera_info_msg, navsatfix_msg, time_msg
from ..motion import frame_times_ns
from ..specs.params import parse_downstream

__all__ = ['SimulatorClock']


class SimulatorClock:
    """The scheduler of the ``sky_simulator`` node (mixed into its class)."""

    def _publish_clock(self, t_ns: int, force: bool = False) -> None:
        """
        Publish /clock, at most every 1 / clock_rate_hz wall seconds unless forced.

        Every node of the graph receives each one. ``force`` is for the first stamp, sent before
        anything else.
        """
        if self.pub_clock is None:
            return
        now = time.monotonic()
        if force or now - self.last_clock_wall >= 1.0 / self.params['clock_rate_hz']:
            self.pub_clock.publish(Clock(clock=time_msg(t_ns)))
            self.last_clock_wall = now

    # lockstep -----------------------------------------------------------------------------------
    def _on_ack(self, topic: str, msg):
        try:
            st = int(json.loads(msg.data).get('stamp_ns', -1))
        except (ValueError, TypeError, AttributeError):
            self.diag.reject('lockstep_bad_status', topic)
            return
        self.acks[topic] = max(self.acks[topic], st)

    def _acked(self, t_ns: int) -> bool:
        return all(v >= t_ns for v in self.acks.values())

    # the sim clock ------------------------------------------------------------------------------
    def _missing_downstream(self) -> list[tuple[str, list]]:
        """
        Return the (topic, node names) of ``wait_for_downstream`` whose subscriptions are unseen.

        A name is missing while this node has not seen its subscription to the topic.
        """
        out = []
        for topic, names in parse_downstream(self.params['wait_for_downstream']):
            seen = {
                i.node_name
                for i in self.get_subscriptions_info_by_topic(self.resolve_topic_name(topic))
            }
            if not names <= seen:
                out.append((topic, sorted(names - seen)))
        return out

    def _ready(self, now: float) -> bool:
        """
        Wait for the expected subscribers, then send the set-up messages.

        Before the first frame: wait for the expected subscribers (image and camera_info:
        ``wait_for_subscribers``; IMU: ``wait_for_imu_subscribers``; truth: one when either is
        set), then send camera_info, the fix and the first IMU sample, and give them
        ``wait_settle_s`` to arrive (and discovery to settle between the other nodes), so that
        frame 0 is processed with the right intrinsics, site and tilt and its results reach every
        reader.
        """
        if self.started:
            return True
        p = self.params
        if self.t_primed is None:
            need, need_imu = p['wait_for_subscribers'], p['wait_for_imu_subscribers']
            ok = (
                self.pub_image.get_subscription_count() >= need
                and self.pub_info.get_subscription_count() >= need
                and self.pub_imu.get_subscription_count() >= need_imu
                and (need + need_imu == 0 or self.pub_truth.get_subscription_count() >= 1)
                and not self._missing_downstream()
            )
            if not ok and now - self.t_wait0 <= p['wait_timeout_s']:
                return False
            if not ok:
                self.get_logger().warning(
                    f'starting after {p["wait_timeout_s"]:g} s with '
                    f'{self.pub_image.get_subscription_count()} image, '
                    f'{self.pub_imu.get_subscription_count()} IMU and '
                    f'{self.pub_truth.get_subscription_count()} truth '
                    'subscriber(s)'
                    + ''.join(
                        f'; {t} not read by {", ".join(sorted(n))} yet'
                        for t, n in self._missing_downstream()
                    )
                )
            t0 = self.start_ns if self.sim_mode else self.get_clock().now().nanoseconds
            self._publish_clock(t0, force=True)
            self.pub_info.publish(camera_info_msg(self.camera, t0, p['camera_frame_id']))
            self.pub_fix.publish(
                navsatfix_msg(p['latitude_deg'], p['longitude_deg'], p['altitude_m'], t0, 'gps')
            )
            R = self._attitude_at(t0, 0.0)
            if R is not None and self.sim_mode:
                self._publish_imu(t0, R)
                self.k_imu = 1
            self.t_primed = now
            return False
        if now - self.t_primed < p['wait_settle_s']:
            return False
        self.started = True
        return True

    def _tick_sim(self) -> None:
        now = time.monotonic()
        if not self._ready(now):
            self._publish_clock(self.sim_cursor)
            return
        p = self.params
        period_ns = int(round(1e9 / p['rate_hz']))
        imu_period_ns = int(round(1e9 / p['imu_rate_hz']))
        if self.base is None:
            self.base = (self.sim_cursor, now)
        if self.waiting_for is not None:
            stamp, since = self.waiting_for
            limit = (
                max(p['lockstep_timeout_s'], 60.0) if self.frames <= 1 else p['lockstep_timeout_s']
            )
            if self._acked(stamp) or now - since > limit:
                if not self._acked(stamp):
                    self.lockstep_timeouts += 1
                    self.get_logger().warning(
                        f'lockstep: no answer for frame {stamp / 1e9:.3f} s after {limit:g} s',
                        throttle_duration_sec=5.0,
                    )
                self.waiting_for = None
                self.base = (self.sim_cursor, now)
            else:
                self._publish_clock(self.sim_cursor)
                return
        desired = self.base[0] + int((now - self.base[1]) * p['time_scale'] * 1e9)
        next_frame = frame_times_ns(self.start_ns, p['rate_hz'], self.total_s, self.k_frame)
        if next_frame is not None and next_frame < desired - period_ns:
            self.late_frames += 1
            self.get_logger().warning(
                f'frame {self.k_frame} is late: simulated time is '
                f'{(desired - next_frame) / 1e6:.0f} ms past it '
                f'(more than one frame period); time resumes from it',
                throttle_duration_sec=1.0,
            )
            self.base = (next_frame, now)
            desired = next_frame
        while True:
            next_frame = frame_times_ns(self.start_ns, p['rate_hz'], self.total_s, self.k_frame)
            next_imu = self.start_ns + self.k_imu * imu_period_ns
            if (
                next_frame is None
                and self.total_s is not None
                and next_imu - self.start_ns >= self.total_s * 1e9
            ):
                next_imu = None
            cands = [t for t in (next_imu, next_frame) if t is not None]
            if not cands or min(cands) > desired:
                break
            t = min(cands)
            self.sim_cursor = max(self.sim_cursor, t)
            t_rel = (t - self.start_ns) / 1e9
            R = self._attitude_at(t, t_rel)
            if next_imu is not None and next_imu == t:  # IMU first at equal stamps
                if R is not None:
                    self._publish_imu(t, R)
                self.k_imu += 1
                continue
            if R is None:
                self._skip_frame()
            else:
                self._publish_frame(t, R)
            self.k_frame += 1
            if self.lock_topics and R is not None:
                self.waiting_for = (t, time.monotonic())
                return
        if desired > self.sim_cursor:
            self.sim_cursor = desired
        self._publish_clock(self.sim_cursor)
        self._prepare_next_frame(now)
        if (
            self.total_s is not None
            and self.waiting_for is None
            and frame_times_ns(self.start_ns, p['rate_hz'], self.total_s, self.k_frame) is None
        ):
            self._maybe_finish(now)

    def _maybe_finish(self, now: float) -> None:
        """Handle the last frame: log once, and exit after linger_s when exit_when_done."""
        if self.done_wall is None:
            self.done_wall = now
            self.get_logger().info(
                f'run complete: {self.frames} frames, {self.late_frames} late, '
                f'{self.lockstep_timeouts} lockstep timeouts'
            )
            self.diag.last_status = f'done: {self.frames} frames'
        if self.params['exit_when_done'] and now - self.done_wall >= self.params['linger_s']:
            self.diag.publish()
            self.exit_code = 0  # run_node ends the spin (nodes.runner)

    # clock_mode system --------------------------------------------------------------------------
    def _frame_system(self) -> None:
        t_ns = self.get_clock().now().nanoseconds
        if self.t_first_ns is None:
            self.t_first_ns = t_ns
        t_rel = (t_ns - self.t_first_ns) / 1e9
        if self.total_s is not None and t_rel >= self.total_s:
            self._maybe_finish(time.monotonic())
            return
        R = self._attitude_at(t_ns, t_rel)
        if R is None:
            self._skip_frame()
            return
        self._publish_frame(t_ns, R)
        self.k_frame += 1

    def _imu_system(self) -> None:
        t_ns = self.get_clock().now().nanoseconds
        t_rel = 0.0 if self.t_first_ns is None else (t_ns - self.t_first_ns) / 1e9
        R = self._attitude_at(t_ns, t_rel)
        if R is not None:
            self._publish_imu(t_ns, R)
