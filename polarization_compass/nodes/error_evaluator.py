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
``error_evaluator``: heading errors of every method against the ground truth, live.

Subscribes to ``ground_truth/heading`` and, per method, ``compass/<m>/heading_raw`` (stream
``<m>/raw``) and ``compass/<m>/heading`` (stream ``<m>/corrected``; not for ``direct_methods``),
all sensor_msgs/Imu. Estimates are paired with the truth by identical stamp
(:class:`~polarization_compass.evaluation.StampMatcher`); the error is estimated minus true bearing
(the paper's psi error), folded to (-90, 90] for ``axial_methods``.

With ``fused_streams`` (``method=topic``) it also scores a state estimator's nav_msgs/Odometry
(robot_localization's ``/odometry/filtered``) as stream ``<method>/fused``: the filter publishes at
its own stamps, so its yaw is interpolated at each truth stamp
(:class:`~polarization_compass.evaluation.YawTrack`); its sigma is the pose covariance's yaw.

Publishes ``evaluation/summary`` (std_msgs/String, JSON: per stream count, mean, std, RMS, p95,
max, missed frames, latency; among the missed, ``not_published``: the reasons the estimator or the
corrector gave for frames it declined, and ``not_received``: the rest, frames that never reached
a node or whose output was lost on the way, :func:`~polarization_compass.evaluation.not_received`)
and ``/diagnostics``. On shutdown (Ctrl-C, SIGTERM, end of the launch) it writes into
``report_dir``: ``evaluation_samples.csv`` (one row per estimate), ``evaluation_summary.csv`` and
``.json`` (one row per stream) and ``evaluation.png`` (error against true bearing per method, raw
and corrected, like the paper's Fig 17). While it runs it keeps a
current report there (CSV and JSON every ``REPORT_PERIOD_S``, the figure every ``FIGURE_PERIOD_S``
wall seconds when new estimates came in; the JSON's ``complete`` is false until the final one), so
that not even a SIGKILL loses the run. Every file is written to a temporary name and renamed into
place (atomic on POSIX): a reader never sees half a report.

Latency: wall time from the image stamp to the arrival here. Under ``use_sim_time`` the sim time of
arrival is the last ``/clock`` plus the wall time since it (at most 50 ms extrapolated), converted
to wall time with ``time_scale``.
"""

from __future__ import annotations

from collections import OrderedDict
import json
import math
import os
from pathlib import Path
import time

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from .diagnostics import Diagnostics
from .msgs import bearing_from_imu, heading_from_imu, yaw_enu_from_quat
from .rosparams import ParameterSet
from .runner import run_node
from ..bag import stamp_ns
from ..evaluation import not_received, StampMatcher, YawTrack
from ..evaluation_report import plot_report, write_samples_csv, write_summary_csv
from ..specs import topics
from ..specs.params import EVALUATOR

__all__ = ['ErrorEvaluatorNode', 'main', 'bearing_from_imu', 'REPORT_PERIOD_S', 'FIGURE_PERIOD_S']

#: Wall seconds between two current reports (CSV, JSON) and two current figures while the node
#: runs.
REPORT_PERIOD_S = 5.0
FIGURE_PERIOD_S = 30.0


class ErrorEvaluatorNode(Node):
    """The ``error_evaluator`` node (see the module docstring)."""

    #: On a stop signal, first handle what the readers already hold, for at most this long
    #: [wall s] (:func:`~polarization_compass.nodes.runner.drain_inputs`): the report must not miss
    #: frames that arrived before the signal.
    drain_on_stop_s = 2.0

    def __init__(self, **kwargs):
        super().__init__('error_evaluator', **kwargs)
        self.params = ParameterSet(self, EVALUATOR, on_change=self._on_change)
        p = self.params
        methods = p.strings('methods')
        direct = p.strings('direct_methods')
        self.axial = set(p.strings('axial_methods'))
        self.streams = topics.evaluator_streams(
            methods, p['include_raw'], p['include_corrected'], direct
        )
        qos = QoSProfile(depth=200)
        self.matcher = StampMatcher(horizon_ns=int(p['horizon_s'] * 1e9))
        self.latency_ms: dict[str, list] = {}
        for name, _ in self.streams:
            self.matcher.add_stream(name, name.split('/')[0] in self.axial)
            self.latency_ms[name] = []
        self.fused = topics.fused_streams(p.strings('fused_streams'))
        self.yaw_tracks = {name: YawTrack() for name, _ in self.fused}
        for name, _ in self.fused:
            self.matcher.add_stream(name, False)
            self.latency_ms[name] = []
        self.diag = Diagnostics(self, 'error evaluator', period_s=1.0 / p['summary_rate_hz'])
        self._last_clock = None  # (sim ns, perf_counter) of the last /clock
        self._closed = False
        # frame times first: the executor serves ready subscriptions in creation order
        self.frame_wall: OrderedDict = OrderedDict()  # stamp -> wall ns the simulator published it
        self.waiting_latency: list = []  # (stream, stamp, arrival wall ns) before sim/frames
        if p['latency_source'] == 'sim_frames':
            self.create_subscription(String, topics.FRAMES, self._on_frame_time, qos)
        elif self.get_parameter('use_sim_time').value:
            # best effort: ``ros2 bag play --clock`` publishes /clock best effort (rclcpp's
            # ClockQoS), and a reliable reader of a best-effort writer gets nothing ("incompatible
            # QoS"); a best-effort reader also takes the simulator's reliable /clock
            self.create_subscription(
                Clock,
                topics.CLOCK,
                self._on_clock,
                QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
            )
        self.create_subscription(Imu, topics.TRUTH, self._on_truth, qos)
        for name, topic in self.streams:
            self.create_subscription(Imu, topic, lambda m, n=name: self._on_estimate(n, m), qos)
        for name, topic in self.fused:
            self.create_subscription(Odometry, topic, lambda m, n=name: self._on_fused(n, m), qos)
        # why frames were not published (estimator status, corrector status), per stream
        self.not_published: dict[str, dict] = {name: {} for name, _ in self.streams}
        for name, _ in self.streams:
            method, kind = name.split('/')
            t = topics.method_topics(method)['status' if kind == 'raw' else 'correction_status']
            self.create_subscription(String, t, lambda m, n=name: self._on_status(n, m), qos)
        # every node's last /diagnostics values go into the report (processing time, rate,
        # rejections)
        self.node_diagnostics: dict[str, dict] = {}
        self.create_subscription(
            DiagnosticArray, topics.DIAGNOSTICS, self._on_diagnostics, QoSProfile(depth=50)
        )
        self.pub_summary = self.create_publisher(String, topics.EVAL_SUMMARY, QoSProfile(depth=10))
        self.summary_timer = self.create_timer(1.0 / p['summary_rate_hz'], self.publish_summary)
        from .diagnostics import _wall_clock

        self._reported = (0, 0)  # matches in the last current report, figure
        self._figure_wall = time.monotonic()
        self.create_timer(REPORT_PERIOD_S, self.write_current_report, clock=_wall_clock())
        self.get_logger().info(
            f'evaluating {len(self.streams)} stream(s) against {topics.TRUTH}; '
            f'report in {p["report_dir"]} at shutdown'
        )

    def _on_change(self, changed: dict):
        """
        Apply run-time parameter changes (matcher horizon, summary and diagnostics rate).

        Run-time changes: the matcher's horizon (applies from the next message: frames already
        older than a shorter horizon are then counted as missed), the summary and /diagnostics
        rate.
        """
        if not hasattr(self, 'summary_timer'):
            return None  # declaring the parameters
        if 'horizon_s' in changed:
            self.matcher.horizon_ns = int(changed['horizon_s'] * 1e9)
        if 'summary_rate_hz' in changed:
            period_ns = int(round(1e9 / changed['summary_rate_hz']))
            for timer in (
                self.summary_timer,
                self.diag._timer,
            ):  # (Diagnostics' own wall-clock timer)
                timer.timer_period_ns = period_ns
                timer.reset()  # next call one new period from now
        return None

    # inputs -------------------------------------------------------------------------------------
    def _on_clock(self, msg):
        self._last_clock = (stamp_ns(msg.clock), time.perf_counter())

    def _on_frame_time(self, msg):
        try:
            d = json.loads(msg.data)
            st, wall = int(d['stamp_ns']), int(d['wall_ns'])
        except (ValueError, TypeError, KeyError):
            self.diag.reject('bad_frame_time', str(msg.data)[:80])
            return
        self.frame_wall[st] = wall
        while len(self.frame_wall) > 5000:
            self.frame_wall.popitem(last=False)
        still = []
        for stream, s_ns, arrival in self.waiting_latency:
            if s_ns == st:
                self.latency_ms[stream].append((arrival - wall) / 1e6)
            else:
                still.append((stream, s_ns, arrival))
        self.waiting_latency = still[-5000:]

    def _arrival_latency_ms(self, t_ns: int) -> float:
        scale = self.params['time_scale']
        if self._last_clock is not None:
            sim_now = (
                self._last_clock[0]
                + min(time.perf_counter() - self._last_clock[1], 0.05) * scale * 1e9
            )
        else:
            sim_now = self.get_clock().now().nanoseconds
        return (sim_now - t_ns) / scale / 1e6

    def _on_truth(self, msg):
        t_in = self.diag.input()
        b = self.diag.decoded('truth', bearing_from_imu, msg)
        if b is None:
            return
        self.matcher.add_truth(stamp_ns(msg.header), b)
        for track in self.yaw_tracks.values():
            track.add_truth(stamp_ns(msg.header))
        self.diag.done(t_in, None)

    def _on_fused(self, stream: str, msg):
        """Score a state estimator's output: its yaw at the truth stamps it has passed."""
        t_in = self.diag.input()
        o = msg.pose.pose.orientation
        var = float(msg.pose.covariance[35])
        try:
            yaw = yaw_enu_from_quat((o.x, o.y, o.z, o.w))
        except (TypeError, ValueError):
            yaw = math.nan
        if not (math.isfinite(yaw) and math.isfinite(var) and var >= 0.0):
            self.diag.reject('bad_odometry', stream)
            return
        t_ns = stamp_ns(msg.header)
        for ts, bearing, sigma in self.yaw_tracks[stream].add_output(t_ns, yaw, var):
            self.matcher.add_estimate(
                stream, ts, bearing, extra={'latency_ms': '', 'sigma_deg': sigma}
            )
        self.diag.done(t_in, t_ns)

    def _on_diagnostics(self, msg):
        for st in msg.status:
            self.node_diagnostics[st.name.split(':')[0]] = {kv.key: kv.value for kv in st.values}

    def _on_status(self, stream: str, msg):
        try:
            st = json.loads(msg.data)
            published, status = bool(st.get('published', True)), str(st.get('status', '?'))
        except (ValueError, TypeError, AttributeError):
            self.diag.reject('bad_status_json', stream)
            return
        if not published:
            d = self.not_published[stream]
            d[status] = d.get(status, 0) + 1

    def _on_estimate(self, stream: str, msg):
        t_in = self.diag.input()
        t_ns = stamp_ns(msg.header)
        arrival = time.time_ns()
        if self.params['latency_source'] == 'sim_frames':
            wall = self.frame_wall.get(t_ns)
            lat = None if wall is None else (arrival - wall) / 1e6
        else:
            lat = self._arrival_latency_ms(t_ns)
        heading = self.diag.decoded('estimate', heading_from_imu, msg, context=f'{stream}: ')
        if heading is None:
            return
        b, var = heading
        sigma = math.degrees(math.sqrt(var))
        self.matcher.add_estimate(
            stream,
            t_ns,
            b,
            extra={'latency_ms': '' if lat is None else round(lat, 3), 'sigma_deg': sigma},
        )
        if lat is None:
            self.waiting_latency.append((stream, t_ns, arrival))
        else:
            self.latency_ms[stream].append(lat)
        self.diag.done(t_in, t_ns)

    # outputs ------------------------------------------------------------------------------------
    def summary(self) -> dict:
        s = self.matcher.summary()
        for name, d in s.items():
            lat = np.asarray(self.latency_ms.get(name, []), dtype=float)
            d['latency_ms_p50'] = float(np.percentile(lat, 50)) if lat.size else 0.0
            d['latency_ms_p95'] = float(np.percentile(lat, 95)) if lat.size else 0.0
            d['latency_ms_max'] = float(lat.max()) if lat.size else 0.0
            d['not_published'] = dict(self.not_published.get(name, {}))
        for name, d in s.items():
            d['not_received'] = not_received(s, name)
        return {
            'truth_frames': self.matcher.truth_count,
            'streams': s,
            'nodes': {k: dict(v) for k, v in sorted(self.node_diagnostics.items())},
        }

    def publish_summary(self) -> None:
        s = self.summary()
        try:
            self.pub_summary.publish(String(data=json.dumps(s)))
        except Exception:  # noqa: BLE001 - shutting down
            return
        flat = {'truth_frames': s['truth_frames']}
        for name, d in s['streams'].items():
            flat[f'{name}.rms_deg'] = d['rms']
            flat[f'{name}.max_deg'] = d['max']
            flat[f'{name}.missed'] = d['missed']
            flat[f'{name}.not_received'] = d['not_received']
            flat[f'{name}.latency_ms_p95'] = d['latency_ms_p95']
        self.diag.extra = flat
        self.diag.last_status = f'{s["truth_frames"]} truth frame(s)'

    def write_current_report(self) -> None:
        """
        Write the report so far (CSV and JSON, the figure less often).

        Runs on a timer, every REPORT_PERIOD_S: CSV and JSON when new estimates came in, the
        figure too every FIGURE_PERIOD_S. A failure is logged and the node goes on.
        """
        n = len(self.matcher.matches)
        if self._closed or n == self._reported[0]:
            return
        figure = n != self._reported[1] and time.monotonic() - self._figure_wall >= FIGURE_PERIOD_S
        try:
            self._write_report(self.summary(), complete=False, figure=figure)
        except Exception as exc:  # noqa: BLE001 - a full disk must not stop the evaluation
            self.get_logger().warning(
                f'cannot write the current report: {type(exc).__name__}: {exc}',
                throttle_duration_sec=30.0,
            )
            return
        self._reported = (n, n if figure else self._reported[1])
        if figure:
            self._figure_wall = time.monotonic()

    def _write_report(self, s: dict, complete: bool, figure: bool = True) -> list[str]:
        """Write the report files of summary ``s``, each to a temporary name renamed into place."""
        out = Path(self.params['report_dir'])
        out.mkdir(parents=True, exist_ok=True)
        written = []

        def atomic(name, write):
            final = out / name
            tmp = out / f'.{final.stem}.partial{final.suffix}'  # same directory: rename is atomic
            try:
                if write(tmp) is None:
                    return
                os.replace(tmp, final)
            finally:
                tmp.unlink(missing_ok=True)
            written.append(name)

        atomic(
            'evaluation_samples.csv',
            lambda t: write_samples_csv(t, self.matcher.matches, ('latency_ms', 'sigma_deg')),
        )
        extra = {
            n: {k: v for k, v in d.items() if k.startswith('latency')}
            for n, d in s['streams'].items()
        }
        atomic(
            'evaluation_summary.csv',
            lambda t: write_summary_csv(t, dict(s['streams'].items()), extra),
        )
        body = json.dumps({**s, 'complete': complete}, indent=1, sort_keys=True) + '\n'
        atomic('evaluation_summary.json', lambda t: t.write_text(body))
        if figure:
            atomic(
                'evaluation.png',
                lambda t: plot_report(
                    t,
                    self.matcher.matches,
                    f'{s["truth_frames"]} frames; error = estimated - true bearing',
                ),
            )
        return written

    def inputs_handled(self) -> int:
        """Return how many truth, heading and odometry messages reached a callback so far."""
        return self.diag.received

    def close(self) -> None:
        """Write the final report (called once when the node stops)."""
        if self._closed:
            return
        self._closed = True
        self.matcher.finish()
        out = Path(self.params['report_dir'])
        s = self.summary()
        written = self._write_report(s, complete=True)
        counts = ', '.join(f'{n} {d["count"]}' for n, d in s['streams'].items())
        print(
            f'error_evaluator: report written to {out}: {", ".join(written)} '
            f'({s["truth_frames"]} truth frames; estimates: {counts or "none"})',
            flush=True,
        )


def main(argv=None) -> int:
    return run_node(ErrorEvaluatorNode, 'error_evaluator', argv)


if __name__ == '__main__':
    raise SystemExit(main())
