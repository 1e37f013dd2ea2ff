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
sky_simulator ``attitude_source: tf`` with the real tf2_ros (issue 26).

The real ``static_transform_publisher`` (C++, tf2_ros) gives the body's attitude and the camera's
mounting; a tf2_ros ``TransformBroadcaster`` in this process moves the body. Checked: the rendered
sky is the attitude given (tilt_aware's heading from the image equals the TF's bearing); every
published frame's truth is the TF at its stamp; frames while the transform is missing or stale are
counted (``rejected.tf_missing`` / ``tf_stale``), logged and not published, never rendered at
another attitude. Needs tf2_ros and static_transform_publisher (a ROS install; here
../shared/ros-cpp, whose setup.bash ``make test`` sources); skipped otherwise, and then NOT
coverage.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
import subprocess

import numpy as np
import pytest
from test_nodes_helpers import node_env, Proc, Recorder, stamp

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _static_transform_publisher() -> Path | None:
    if importlib.util.find_spec('tf2_ros') is None:
        return None
    try:
        from ament_index_python.packages import get_package_prefix

        exe = (
            Path(get_package_prefix('tf2_ros')) / 'lib' / 'tf2_ros' / 'static_transform_publisher'
        )
    except (ImportError, LookupError, ValueError):
        return None
    return exe if exe.is_file() else None


STP = _static_transform_publisher()
if STP is None:
    pytest.skip(
        'tf2_ros / static_transform_publisher are not installed (a ROS install has them: '
        'ros-<distro>-tf2-ros; here ../shared/ros-cpp/install.sh .venv and source its setup.bash)',
        allow_module_level=True,
    )


def _quat(R) -> list[str]:
    from polarization_compass.conventions import matrix_to_quat

    return [f'{v:.12f}' for v in matrix_to_quat(R)]


def _static(parent: str, child: str, R, env, log: Path) -> subprocess.Popen:
    qx, qy, qz, qw = _quat(R)
    with open(log, 'w') as f:
        return subprocess.Popen(
            [str(STP), '--qx', qx, '--qy', qy, '--qz', qz, '--qw', qw]
            + ['--frame-id', parent, '--child-frame-id', child],
            env=env,
            stdout=f,
            stderr=subprocess.STDOUT,
        )


def _stop(*procs):
    for p in procs:
        if p is None:
            continue
        if isinstance(p, Proc):
            p.stop()
        elif p.poll() is None:
            p.send_signal(2)
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.fixture
def tf_env(ros_env):
    env = node_env(ros_env)
    return env


def _bearing_deg(m) -> float:
    from polarization_compass.nodes.msgs import bearing_from_imu

    return bearing_from_imu(m)


def test_static_tf_attitude_and_mounting_give_the_rendered_sky(tf_env, tmp_path):
    """Body at bearing 60 deg, camera pitch -20 deg from static TFs: tilt_aware reads 60 deg."""
    from polarization_compass.conventions import (
        CameraAttitude,
        R_BODY_CAM_DEFAULT,
        R_enu_body_from_camera_attitude,
    )
    from sensor_msgs.msg import Imu

    R_body = R_enu_body_from_camera_attitude(CameraAttitude(60.0, -20.0, 0.0))
    rec = Recorder(int(tf_env['ROS_DOMAIN_ID']))
    rec.sub(Imu, '/compass/tilt_aware/heading_raw')
    rec.sub(Imu, '/ground_truth/heading')
    procs = []
    try:
        procs.append(_static('map', 'base_link', R_body, tf_env, tmp_path / 'stp_body.log'))
        procs.append(
            _static(
                'base_link', 'camera_optical_frame', R_BODY_CAM_DEFAULT, tf_env, tmp_path / 'm.log'
            )
        )
        est = Proc(
            'heading_estimator_tilt_aware',
            'heading_estimator',
            ['-p', 'method:=tilt_aware', '-p', 'use_sim_time:=true'],
            tf_env,
            tmp_path,
        )
        procs.append(est)
        sim = Proc(
            'sky_simulator',
            'sky_simulator',
            [
                '-p',
                'attitude_source:=tf',
                '-p',
                'duration_s:=0.3',
                '-p',
                'exit_when_done:=true',
                '-p',
                'wait_for_subscribers:=1',
                '-p',
                'wait_for_imu_subscribers:=1',
            ],
            tf_env,
            tmp_path,
        )
        procs.append(sim)
        rec.spin_until(lambda: not sim.alive(), timeout=300, procs=[est])
        rec.spin_until(lambda: len(rec.msgs['/compass/tilt_aware/heading_raw']) >= 3, 15)
        assert sim.wait(30) == 0, sim.stderr[-2000:]
    finally:
        _stop(*procs)
        rec.close()
    truth = {stamp(m): _bearing_deg(m) for _, m in rec.msgs['/ground_truth/heading']}
    est_b = {stamp(m): _bearing_deg(m) for _, m in rec.msgs['/compass/tilt_aware/heading_raw']}
    assert len(truth) == 3 and set(est_b) == set(truth), (truth, est_b, sim.stderr[-2000:])
    for t, b in truth.items():
        assert b == pytest.approx(60.0, abs=1e-6)
        assert abs((est_b[t] - b + 180.0) % 360.0 - 180.0) < 0.1, (est_b[t], b)


def test_moving_tf_frames_match_it_and_a_missing_or_stale_transform_is_a_counted_skip(
    tf_env, tmp_path
):
    """
    A moving broadcaster with a gap, the mounting published late: no frame at a wrong attitude.

    clock_mode system (frames stamped with the wall clock, like a camera): the body turns at
    20 deg/s from a TransformBroadcaster here at 50 Hz, frames at 2 Hz; the mounting
    (static_transform_publisher) starts only after 1.5 s, and the broadcaster pauses for 1 s in the
    middle.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TransformStamped
    from polarization_compass.conventions import R_BODY_CAM_DEFAULT
    from sensor_msgs.msg import Image, Imu
    import tf2_ros

    rec = Recorder(int(tf_env['ROS_DOMAIN_ID']))
    rec.sub(Imu, '/ground_truth/heading')
    rec.sub(Image, '/camera/image_raw', depth=5)
    rec.sub(DiagnosticArray, '/diagnostics', depth=50)
    br = tf2_ros.TransformBroadcaster(rec.node)
    sent = []  # (stamp ns, yaw rad)
    clock = rec.node.get_clock()
    t_start = clock.now().nanoseconds
    gap = (3.5e9, 4.5e9)  # ns after the start: the broadcaster is silent

    def tick():
        now = clock.now().nanoseconds
        rel = now - t_start
        if gap[0] <= rel < gap[1]:
            return
        yaw = math.radians(20.0) * rel / 1e9
        tr = TransformStamped()
        tr.header.stamp.sec, tr.header.stamp.nanosec = divmod(now, 1_000_000_000)
        tr.header.frame_id, tr.child_frame_id = 'map', 'base_link'
        tr.transform.rotation.z, tr.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        br.sendTransform(tr)
        sent.append((now, yaw))

    rec.node.create_timer(0.02, tick)
    procs = []
    try:
        sim = Proc(
            'sky_simulator',
            'sky_simulator',
            [
                '-p',
                'attitude_source:=tf',
                '-p',
                'clock_mode:=system',
                '-p',
                'rate_hz:=2.0',
                '-p',
                'imu_rate_hz:=10.0',
                '-p',
                'encoding:=32FC1',
                '-p',
                'tf_timeout_s:=0.2',
            ],
            tf_env,
            tmp_path,
        )
        procs.append(sim)
        rec.spin_until(lambda: 'attitude tf' in sim.stderr, timeout=300, procs=[sim])
        t_start = clock.now().nanoseconds
        sent.clear()
        rec.spin_for(1.5)  # no mounting yet: tf_missing
        procs.append(
            _static(
                'base_link', 'camera_optical_frame', R_BODY_CAM_DEFAULT, tf_env, tmp_path / 'm.log'
            )
        )
        rec.spin_for(6.0)
    finally:
        _stop(*procs)
        rec.close()
    s = np.array(sent, dtype=float)
    truth = [(stamp(m), m) for _, m in rec.msgs['/ground_truth/heading']]
    assert len(truth) >= 4, sim.stderr[-2000:]
    for t, m in truth:
        rel = t - t_start
        # none in the gap, but for the last tf_timeout_s of it: such a frame waited for the TF to
        # resume, and tf2 interpolates between the samples either side of the gap
        assert not (gap[0] - 0.05e9 < rel < gap[1] - 0.25e9), 'a frame inside the gap of the TF'
        # the truth is the broadcast attitude interpolated at the frame's stamp
        yaw_expected = np.interp(t, s[:, 0], s[:, 1])
        yaw = math.radians(90.0 - _bearing_deg(m))
        assert abs(math.remainder(yaw - yaw_expected, 2 * math.pi)) < math.radians(0.01)
    assert len(rec.msgs['/camera/image_raw']) >= 1
    assert all(stamp(m) in {t for t, _ in truth} for _, m in rec.msgs['/camera/image_raw'])
    counts = {}
    for _, arr in rec.msgs['/diagnostics']:
        for st in arr.status:
            if st.name.startswith('sky_simulator:'):
                counts.update({kv.key: kv.value for kv in st.values})
    err = sim.stderr
    names = [st.name for _, arr in rec.msgs['/diagnostics'] for st in arr.status]
    assert int(counts.get('rejected.tf_missing', 0)) >= 3, (counts, names, err[-2000:])
    assert int(counts.get('rejected.tf_stale', 0)) >= 2, (counts, err[-2000:])
    assert int(counts.get('frames_skipped', 0)) >= 3, counts
    assert 'dropped an input (tf_missing)' in err and 'dropped an input (tf_stale)' in err
    assert 'Traceback' not in err
