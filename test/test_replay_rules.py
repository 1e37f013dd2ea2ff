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
Replay applies exactly the node's rules (issue 24 item 5).

The same frames go through the ``heading_estimator`` node (in-process, callbacks called directly)
and through replay's :class:`~polarization_compass.replay.processing.FramePipeline`; the statuses
must be equal, frame by frame: a good frame (``ok``), an IMU yaw 90 deg away from the image's
heading (the IMU-prior check: ``prior_disagrees``; replay used to say ``ok``), and a polarizer
configuration the sky contradicts (``poor_fit`` naming the fix).
"""

import numpy as np
from polarization_compass.bag.topic_map import default_topic_map
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import body_quat_from_camera_attitude, CameraAttitude
from polarization_compass.mosaic import IMX250MZR_POL45
from polarization_compass.nodes import msgs as M
from polarization_compass.pipeline import AttitudeBuffer, SunSource
from polarization_compass.replay.processing import FramePipeline, ReplayConfig
from polarization_compass.replay.sync import SyncedFrame
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

T0 = 1_573_797_600_000_000_000  # 2019-11-15T06:00:00Z (sun ~30 deg up at SITE)
SITE = (32.026778, 118.853306, 30.0)
CAM = CameraModel('pinhole', 96, 80, 0.12, 3.45, 3.45)
LAYOUT = ((90, 45), (135, 0))

# (image bearing, IMU bearing) per frame, deg
FRAMES = [(40.0, 40.0), (40.0, 130.0), (200.0, 200.0)]


def mosaic(bearing, sun_az, sun_alt):
    """Malus's law on the IMX250MZR layout as delivered (+45 deg towards +x-y), 32FC1."""
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene

    f = Renderer(Scene(camera=CAM)).render(
        attitude=CameraAttitude(bearing, 0.0, 0.0), sun=SunDirection(sun_az, sun_alt)
    )
    sign = 1.0 if IMX250MZR_POL45 == '+x+y' else -1.0
    tiles = (CAM.height_px // 2, CAM.width_px // 2)
    phi = sign * np.radians(np.tile(np.array(LAYOUT, float), tiles))
    aolp = np.pi / 2 - f.aop_rad.astype(float)
    m = 0.5 * (1 + f.dop.astype(float) * np.cos(2 * (phi - aolp)))
    return np.where(f.valid, m, 0.5).astype(np.float32)


def imu_msg(t_ns, q):
    m = Imu()
    m.header.stamp = M.time_msg(t_ns)
    m.header.frame_id = 'base_link'
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (float(v) for v in q)
    m.orientation_covariance = [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1.0]
    return m


def frames():
    """(stamp, mosaic, IMU quaternion) per frame, one second apart."""
    out = []
    for k, (img_b, imu_b) in enumerate(FRAMES):
        t = T0 + k * 10**9
        az, alt = SunSource(*SITE).at_ns(t)
        q = body_quat_from_camera_attitude(CameraAttitude(imu_b, 0.0, 0.0))
        out.append((t, mosaic(img_b, az, alt), q))
    return out


def node_statuses(ctx, pol45):
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='least_squares'),
            Parameter('site_source', value='navsatfix'),
            Parameter('pol45_toward', value=pol45),
        ],
    )
    node.statuses = []
    node._publish_status = node.statuses.append
    out = []
    try:
        for t, img, q in frames():
            node._on_camera_info(M.camera_info_msg(CAM, t, 'camera_optical_frame'))
            node._on_fix(M.navsatfix_msg(*SITE, t, 'gps'))
            node._on_imu(imu_msg(t - 10_000_000, q))
            node._on_imu(imu_msg(t + 10_000_000, q))
            node._on_image(M.image_msg(img, t, 'camera_optical_frame'))
            out.append(node.statuses[-1]['status'])
    finally:
        node.destroy_node()
    return out


def replay_statuses(pol45):
    tm = default_topic_map()
    mos = {'layout': [list(r) for r in LAYOUT], 'pol45_toward': pol45}
    tm = type(tm)(**{**tm.__dict__, 'mosaic': mos})
    # the node's knob defaults (replay's default_knobs are the shipped config's stride 8)
    pipe = FramePipeline(ReplayConfig(methods=('least_squares',), default_knobs={}), tm)
    out = []
    for t, img, q in frames():
        buf = AttitudeBuffer()
        buf.add(t - 10_000_000, q)
        buf.add(t + 10_000_000, q)
        tilt = buf.camera_tilt(t, 50_000_000)
        f = SyncedFrame(t, t, img, CAM, SITE, tilt, None, tilt)
        out.append(pipe.process(f)[0].status)
    return out


@pytest.mark.parametrize('pol45', ['+x-y', '+x+y'])
def test_replay_gives_the_node_statuses(ctx, pol45):
    node = node_statuses(ctx, pol45)
    assert replay_statuses(pol45) == node
    if pol45 == '+x-y':  # the images' own convention: the good frames ok, the prior catches one
        assert node == ['ok', 'prior_disagrees', 'ok']
    else:  # contradicted: no heading is ok
        assert 'ok' not in node and node[0] == 'poor_fit'
