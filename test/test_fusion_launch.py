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
launch_testing test of fusion.launch.py: robot_localization's real ekf_node fuses the heading.

One run of ``fusion.launch.py`` from an install space (``make test`` -> tools/launch_tests.sh ->
``launch_test``; ``colcon test`` on a robot) with three ekf_node processes configured from the
shipped ``config/ekf_heading_example.yaml``: ``ekf_filter_node`` fusing least_squares' corrected
heading (the file as users copy it), one fusing tilt_aware's heading and one the wheel odometry
alone. 90 frames of a turn at 10 deg/s at pitch -20 deg; the odometry's yaw rate has a 0.5 deg/s
bias. While it runs, this process records the truth, the headings and every filter output, and
injects on the compass topics: 180 deg flips (with the compass's own sigma) into ekf_filter_node
and, as the control that shows an injection reaches a filter, a +2 deg heading into the tilt_aware
one. Checked against the truth and the config file's own numbers:

- each compass-fed filter's yaw tracks the truth within 3 of its own sigmas (and 0.5 deg);
- the odometry-only filter drifts at the odometry's bias (0.5 +- 0.1 deg/s);
- the flips never move ekf_filter_node (its imu0_pose_rejection_threshold), while the +2 deg
  control moves the other filter by ~2 deg;
- the yaw variance the filters report lies between half our smallest heading variance and our
  largest plus the config's yaw process noise over two frames, and its median sigma is below 1 deg
  (robot_localization's default process noise reported 4.4 deg);
- the evaluator's report scores the three filters (``<method>/fused``) with the errors computed
  here; every process, ekf_node included, exits 0 when launch_testing stops the graph with SIGINT
  (the simulator idles after its last frame: exit_when_done false).

Skipped (and ``make test`` says so) without robot_localization: a ROS install has it
(ros-<distro>-robot-localization); here ../shared/ros-cpp/install.sh. Every participant uses the
package's shared-memory Fast DDS profile (the launch sets it; this process too), so that each one
discovers every local peer however many share the domain.
"""

import json
import math
import os
import tempfile
import time
import unittest

import pytest

launch_testing = pytest.importorskip('launch_testing')
pytest.importorskip('launch_ros')

# after the importorskip calls above, hence E402 (not at the top) and I100 (after pytest)
from ament_index_python.packages import (  # noqa: E402, I100
    get_package_prefix,
    get_package_share_directory,
    PackageNotFoundError,
)

try:
    get_package_prefix('robot_localization')
except PackageNotFoundError:
    pytest.skip(
        'robot_localization is not installed (a ROS install has it: '
        'ros-<distro>-robot-localization; here ../shared/ros-cpp/install.sh .venv)',
        allow_module_level=True,
    )

import launch  # noqa: E402
from launch.actions import IncludeLaunchDescription, SetEnvironmentVariable  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402
import launch_testing.actions  # noqa: E402
import launch_testing.asserts  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

REPORT = tempfile.mkdtemp(prefix='pc_fusion_test_')
FRAMES = 90  # 0.25 turn at 10 deg/s and 10 Hz
BIAS_DEG_S = 0.5
ARGS = {
    'methods': 'least_squares',
    'tilt_aware': 'true',
    'fuse': 'least_squares,tilt_aware,none',
    'turns': '0.25',
    'turn_rate_deg_s': '10.0',
    'pitch_deg': '-20.0',
    'odom_yaw_rate_bias_deg_s': str(BIAS_DEG_S),
    'report_dir': REPORT,
    'exit_when_done': 'false',  # the test ends the launch (SIGINT to every process) when done
}
#: injections, seconds after the first frame: (time, filter's compass topic, yaw offset deg)
FLIP_TOPIC = '/compass/least_squares/heading'
CONTROL_TOPIC = '/compass/tilt_aware/heading_raw'
INJECT = (
    (3.0, FLIP_TOPIC, 180.0),
    (3.0, CONTROL_TOPIC, 2.0),
    (5.0, FLIP_TOPIC, 180.0),
    (6.5, FLIP_TOPIC, 180.0),
)
CONTROL_WINDOW_S = (3.0, 4.5)  # the tilt_aware filter is off by the control in here
OUTPUTS = {
    'least_squares': '/odometry/filtered',
    'tilt_aware': '/odometry/filtered_tilt_aware',
    'none': '/odometry/filtered_none',
}
REC: dict = {}  # what the running test recorded, for the post-shutdown checks


@pytest.mark.launch_test
def generate_test_description():
    share = get_package_share_directory('polarization_compass')
    return launch.LaunchDescription(
        [
            SetEnvironmentVariable('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST'),
            IncludeLaunchDescription(
                PythonLaunchDescriptionSource(os.path.join(share, 'launch', 'fusion.launch.py')),
                launch_arguments=ARGS.items(),
            ),
            launch_testing.actions.ReadyToTest(),
        ]
    )


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _record_and_inject(timeout_s: float) -> dict:
    """Spin a node in this process: record truth, headings and filter outputs; inject."""
    share = get_package_share_directory('polarization_compass')
    os.environ.setdefault(
        'FASTDDS_DEFAULT_PROFILES_FILE', os.path.join(share, 'config', 'fastdds_large_images.xml')
    )
    from nav_msgs.msg import Odometry
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Imu

    rec = {'truth': {}, 'heading': {}, 'odom_stamp': 0, 'injected': []}
    rec.update({m: [] for m in OUTPUTS})
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('fusion_launch_test', context=ctx)
    pubs = {t: node.create_publisher(Imu, t, 10) for t in (FLIP_TOPIC, CONTROL_TOPIC)}
    last_heading = {}

    def on_truth(m):
        rec['truth'][_ns(m.header.stamp)] = _yaw(m.orientation)

    def on_heading(topic, m):
        if m.header.frame_id == 'injected':
            return
        last_heading[topic] = m
        rec['heading'].setdefault(topic, {})[_ns(m.header.stamp)] = m.orientation_covariance[8]

    def on_odom(m):
        rec['odom_stamp'] = max(rec['odom_stamp'], _ns(m.header.stamp))

    node.create_subscription(Imu, '/ground_truth/heading', on_truth, 200)
    for t in (FLIP_TOPIC, CONTROL_TOPIC):
        node.create_subscription(Imu, t, lambda m, t=t: on_heading(t, m), 200)
    node.create_subscription(Odometry, '/odometry/wheel', on_odom, qos_profile_sensor_data)
    for name, topic in OUTPUTS.items():
        node.create_subscription(
            Odometry,
            topic,
            lambda m, n=name: rec[n].append(
                (_ns(m.header.stamp), _yaw(m.pose.pose.orientation), m.pose.covariance[35])
            ),
            200,
        )
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    pending = list(INJECT)
    t_end = time.monotonic() + timeout_s
    try:
        while time.monotonic() < t_end and len(rec['truth']) < FRAMES:
            ex.spin_once(timeout_sec=0.05)
            if not rec['truth'] or not pending:
                continue
            t0 = min(rec['truth'])
            newest = max(rec['truth'])
            while pending and newest - t0 >= pending[0][0] * 1e9:
                at_s, topic, offset_deg = pending.pop(0)
                real = last_heading.get(topic)
                assert real is not None, f'no heading on {topic} before the injection at {at_s} s'
                msg = Imu()
                msg.header.frame_id = real.header.frame_id
                stamp = max(rec['odom_stamp'], newest) + 1_000_000  # not older than the filter
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
                yaw = rec['truth'][newest] + math.radians(offset_deg)
                msg.orientation.z, msg.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
                msg.orientation_covariance = list(real.orientation_covariance)
                msg.angular_velocity_covariance[0] = -1.0
                msg.linear_acceleration_covariance[0] = -1.0
                pubs[topic].publish(msg)
                rec['injected'].append((stamp, topic, offset_deg))
        t_more = time.monotonic() + 20.0  # the filters' outputs past the last frame
        last = max(rec['truth'], default=0)
        while time.monotonic() < t_more and not all(
            rec[n] and rec[n][-1][0] >= last for n in OUTPUTS
        ):
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    return rec


class TestFusionRuns(unittest.TestCase):
    """Record and inject while the graph runs."""

    def test_record_the_run_and_inject_flips(self):
        REC.update(_record_and_inject(timeout_s=400))
        self.assertEqual(len(REC['truth']), FRAMES)
        self.assertEqual(len(REC['injected']), len(INJECT))


def _track(outputs, stamps_ns):
    """Filter yaw and variance interpolated at the stamps (independent of evaluation.YawTrack)."""
    out = np.array(sorted(outputs), dtype=float)
    t, yaw, var = out[:, 0], np.unwrap(out[:, 1]), out[:, 2]
    s = np.asarray(stamps_ns, dtype=float)
    ok = (s >= t[0]) & (s <= t[-1])
    return s[ok], np.interp(s[ok], t, yaw), np.interp(s[ok], t, var)


def _errors_deg(name):
    truth = REC['truth']
    stamps = sorted(truth)
    s, yaw, var = _track(REC[name], stamps)
    true = np.array([truth[int(x)] for x in s])
    err = np.degrees(np.angle(np.exp(1j * (yaw - true))))
    return (s - stamps[0]) / 1e9, err, np.degrees(np.sqrt(var))


@launch_testing.post_shutdown_test()
class TestFusionResults(unittest.TestCase):
    """Checks on the recorded run, after every process has stopped."""

    def test_every_node_ekf_node_included_exits_cleanly(self, proc_info):
        launch_testing.asserts.assertExitCodes(proc_info, allowable_exit_codes=[0])
        names = ' '.join(str(p) for p in proc_info.process_names())
        self.assertEqual(names.count('ekf_node'), 3, names)

    def test_compass_filters_track_the_truth_within_their_sigma(self):
        for name in ('least_squares', 'tilt_aware'):
            t, err, sig = _errors_deg(name)
            keep = t >= 0.5  # the first headings
            if name == 'tilt_aware':
                keep &= (t < CONTROL_WINDOW_S[0]) | (t > CONTROL_WINDOW_S[1])
            self.assertGreater(keep.sum(), 60, name)
            self.assertLess(np.max(np.abs(err[keep])), 0.5, (name, err[keep]))
            self.assertTrue(np.all(np.abs(err[keep]) <= 3.0 * sig[keep]), (name, err, sig))

    def test_without_the_compass_the_filter_drifts_like_the_odometry(self):
        t, err, _ = _errors_deg('none')
        slope = np.polyfit(t, np.unwrap(np.radians(err)), 1)[0]
        # ENU yaw error grows at the bias (counter-clockwise positive, as the odometry's rate)
        self.assertAlmostEqual(math.degrees(slope), BIAS_DEG_S, delta=0.1)
        # the fused filter's own stamps: its output may span one truth stamp more or less
        t_fused, fused, _ = _errors_deg('least_squares')
        self.assertGreater(abs(err[-1] - err[0]), 10 * np.max(np.abs(fused[t_fused >= 0.5])))

    def test_a_flip_never_moves_the_filter_and_the_control_does(self):
        t0 = min(REC['truth'])
        for stamp, topic, offset in REC['injected']:
            name = 'least_squares' if topic == FLIP_TOPIC else 'tilt_aware'
            outs = np.array(sorted(REC[name]), dtype=float)
            truth_s = np.array(sorted(REC['truth']), dtype=float)
            truth_yaw = np.unwrap([REC['truth'][int(x)] for x in truth_s])
            after = outs[(outs[:, 0] >= stamp) & (outs[:, 0] <= stamp + 0.5e9)]
            self.assertGreater(len(after), 2, (name, (stamp - t0) / 1e9))
            true = np.interp(after[:, 0], truth_s, truth_yaw)
            dev = np.degrees(np.angle(np.exp(1j * (after[:, 1] - true))))
            if offset == 180.0:
                self.assertLess(np.max(np.abs(dev)), 0.5, ('flip moved the filter', dev))
            else:  # the control: the same injection, within the gate, moves the filter by ~2 deg
                self.assertGreater(np.max(dev), 0.6 * offset, ('control ignored', dev))

    def test_filter_yaw_variance_is_consistent_with_the_compass_sigma(self):
        share = get_package_share_directory('polarization_compass')
        with open(os.path.join(share, 'config', 'ekf_heading_example.yaml')) as f:
            cfg = yaml.safe_load(f)['ekf_filter_node']['ros__parameters']
        q_yaw = cfg['process_noise_covariance'][5 * 15 + 5]  # rad^2/s
        for name, topic in (('least_squares', FLIP_TOPIC), ('tilt_aware', CONTROL_TOPIC)):
            ours = np.array(list(REC['heading'][topic].values()))  # rad^2
            t, _, sig = _errors_deg(name)
            var = np.radians(sig[t >= 0.5]) ** 2
            self.assertGreaterEqual(var.min(), 0.5 * ours.min(), name)
            self.assertLessEqual(var.max(), ours.max() + q_yaw * 0.2, name)
            self.assertLess(np.median(np.sqrt(var)), math.radians(1.0), name)

    def test_the_evaluator_scores_the_filters_with_these_errors(self):
        with open(os.path.join(REPORT, 'evaluation_summary.json')) as f:
            s = json.load(f)
        self.assertTrue(s['complete'])
        for name, stream in (
            ('least_squares', 'least_squares/fused'),
            ('tilt_aware', 'tilt_aware/fused'),
            ('none', 'odometry/fused'),
        ):
            _, err, _ = _errors_deg(name)
            d = s['streams'][stream]
            self.assertGreaterEqual(d['count'], FRAMES - 2, stream)
            self.assertAlmostEqual(d['rms'], float(np.sqrt(np.mean(err**2))), delta=0.05)
        self.assertIn('least_squares/corrected', s['streams'])
        self.assertGreater(os.path.getsize(os.path.join(REPORT, 'evaluation.png')), 0)
