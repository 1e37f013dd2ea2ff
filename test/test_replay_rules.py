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
configuration the sky contradicts (``poor_fit`` naming the fix). So must tilt_aware's sigmas, which
take on the IMU tilt's uncertainty (replay used to leave it out), and the statuses of a camera that
mirrors its readout (``readout_flip``, which replay did not have).
"""

import dataclasses
import math


import numpy as np
from polarization_compass.bag.topic_map import default_topic_map
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import body_quat_from_camera_attitude, CameraAttitude
from polarization_compass.demosaic import IMX250MZR_POL45
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


def mosaic(bearing, sun_az, sun_alt, cam=CAM, pitch=0.0, roll=0.0):
    """Malus's law on the IMX250MZR layout as delivered (+45 deg towards +x-y), 32FC1."""
    from polarization_compass.render import Renderer, SunDirection
    from polarization_compass.scene import Scene

    f = Renderer(Scene(camera=cam)).render(
        attitude=CameraAttitude(bearing, pitch, roll), sun=SunDirection(sun_az, sun_alt)
    )
    sign = 1.0 if IMX250MZR_POL45 == '+x+y' else -1.0
    tiles = (cam.height_px // 2, cam.width_px // 2)
    phi = sign * np.radians(np.tile(np.array(LAYOUT, float), tiles))
    aolp = np.pi / 2 - f.aop_rad.astype(float)
    m = 0.5 * (1 + f.dop.astype(float) * np.cos(2 * (phi - aolp)))
    return np.where(f.valid, m, 0.5).astype(np.float32)


def imu_msg(t_ns, q, var_rad2=1e-4):
    m = Imu()
    m.header.stamp = M.time_msg(t_ns)
    m.header.frame_id = 'base_link'
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (float(v) for v in q)
    m.orientation_covariance = [var_rad2, 0.0, 0.0, 0.0, var_rad2, 0.0, 0.0, 0.0, 1.0]
    return m


def frames(cam=CAM, pitch=0.0, roll=0.0, flip=''):
    """
    (stamp, mosaic, IMU quaternion) per frame, one second apart.

    The mosaic is rendered for ``cam`` (the sensor's own image) at the tilt, then mirrored as a
    camera with readout ``flip`` delivers it.
    """
    out = []
    for k, (img_b, imu_b) in enumerate(FRAMES):
        t = T0 + k * 10**9
        az, alt = SunSource(*SITE).at_ns(t)
        q = body_quat_from_camera_attitude(CameraAttitude(imu_b, pitch, roll))
        img = mosaic(img_b, az, alt, cam, pitch, roll)
        if 'x' in flip:
            img = img[:, ::-1]
        if 'y' in flip:
            img = img[::-1, :]
        out.append((t, np.ascontiguousarray(img), q))
    return out


def node_statuses(ctx, pol45, method='least_squares', cam=CAM, imgs=None, var_rad2=1e-4, **par):
    """Return the node's status dicts of the frames (``cam``: the delivered image's K)."""
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value=method),
            Parameter('site_source', value='navsatfix'),
            Parameter('pol45_toward', value=pol45),
        ]
        + [Parameter(k, value=v) for k, v in par.items()],
    )
    node.statuses = []
    node._publish_status = node.statuses.append
    out = []
    try:
        for t, img, q in imgs or frames():
            node._on_camera_info(M.camera_info_msg(cam, t, 'camera_optical_frame'))
            node._on_fix(M.navsatfix_msg(*SITE, t, 'gps'))
            node._on_imu(imu_msg(t - 10_000_000, q, var_rad2))
            node._on_imu(imu_msg(t + 10_000_000, q, var_rad2))
            node._on_image(M.image_msg(img, t, 'camera_optical_frame'))
            out.append(node.statuses[-1])
    finally:
        node.destroy_node()
    return out


def replay_rows(pol45, method='least_squares', cam=CAM, imgs=None, var_deg2=None, flip='', **cfg):
    """Return replay's rows of the same frames (``var_deg2``: the bag IMU's tilt variance)."""
    tm = default_topic_map()
    mos = {'layout': [list(r) for r in LAYOUT], 'pol45_toward': pol45}
    tm = dataclasses.replace(tm, mosaic=mos, readout_flip=flip)
    # the node's knob defaults (replay's default_knobs are the shipped config's stride 8)
    pipe = FramePipeline(ReplayConfig(methods=(method,), default_knobs={}, **cfg), tm)
    out = []
    for t, img, q in imgs or frames():
        buf = AttitudeBuffer()
        buf.add(t - 10_000_000, q)
        buf.add(t + 10_000_000, q)
        tilt = buf.camera_tilt(t, 50_000_000)
        f = SyncedFrame(t, t, img, cam, SITE, tilt, None, tilt, var_deg2)
        out.append(pipe.process(f)[0])
    return out


def node_statuses_only(ctx, pol45):
    return [s['status'] for s in node_statuses(ctx, pol45)]


def replay_statuses(pol45):
    return [r.status for r in replay_rows(pol45)]


@pytest.mark.parametrize('pol45', ['+x-y', '+x+y'])
def test_replay_gives_the_node_statuses(ctx, pol45):
    node = node_statuses_only(ctx, pol45)
    assert replay_statuses(pol45) == node
    if pol45 == '+x-y':  # the images' own convention: the good frames ok, the prior catches one
        assert node == ['ok', 'prior_disagrees', 'ok']
    else:  # contradicted: no heading is ok
        assert 'ok' not in node and node[0] == 'poor_fit'


def test_replay_gives_tilt_aware_the_node_attitude_sigma(ctx):
    """
    The IMU tilt's share of tilt_aware's sigma is the node's, in replay too.

    Tilted frames (pitch 12, roll -7 deg); the IMU states a tilt variance of 4e-4 rad^2 and the
    node's ``attitude_sigma_deg`` is 1.5 deg: the tilt 1-sigma is sqrt(degrees(0.02)^2 + 1.5^2)
    deg, computed here from the message. The added variance must be that of a linear map of the
    tilt: sigma^2 - (fit sigma)^2 grows as the tilt variance (replay run with the IMU covariance
    alone, then with the extra), the fit sigma from a run without any attitude uncertainty.
    """
    imgs = frames(pitch=12.0, roll=-7.0)
    var_rad2, extra = 4e-4, 1.5
    var_deg2 = math.degrees(math.sqrt(var_rad2)) ** 2
    node = node_statuses(
        ctx, '+x-y', 'tilt_aware', imgs=imgs, var_rad2=var_rad2, attitude_sigma_deg=extra
    )
    rows = replay_rows(
        '+x-y', 'tilt_aware', imgs=imgs, var_deg2=var_deg2, attitude_sigma_deg=extra
    )
    imu_only = replay_rows('+x-y', 'tilt_aware', imgs=imgs, var_deg2=var_deg2)
    bare = replay_rows('+x-y', 'tilt_aware', imgs=imgs)  # no covariance, no extra: the fit's
    assert [r.status for r in rows] == [n['status'] for n in node]
    assert [n['status'] for n in node] == ['ok', 'prior_disagrees', 'ok']
    for k in (0, 2):
        n, r, b, i = node[k], rows[k], bare[k], imu_only[k]
        assert r.sigma_deg == pytest.approx(n['sigma_deg'], rel=1e-9)
        assert n['attitude_covariance'] == 'imu'
        assert n['attitude_sigma_deg'] == pytest.approx(math.sqrt(var_deg2 + extra**2), rel=1e-12)
        assert r.sigma_deg > 1.05 * b.sigma_deg  # the share is not negligible here
        # sigma^2 = fit^2 + |J|^2 s_tilt^2: the added variance scales with the tilt variance
        ratio = (r.sigma_deg**2 - b.sigma_deg**2) / (i.sigma_deg**2 - b.sigma_deg**2)
        assert ratio == pytest.approx((var_deg2 + extra**2) / var_deg2, rel=1e-6)


@pytest.mark.parametrize('flip', ['x', 'xy'])
def test_replay_reads_a_mirrored_readout_back_as_the_node(ctx, flip):
    """
    A camera mirroring its readout: node (``readout_flip``) and replay (mapping key) agree.

    The sensor's own camera has its principal point off centre (so that K must be mirrored too);
    the delivered images are mirrored and the camera_info is the delivered image's. With the
    flip set, both give the rendered bearings (40 and 200 deg) ``ok``; without it, replay gives no
    ``ok`` at the rendered heading.
    """
    from polarization_compass.camera import unflipped_camera

    sensor = CameraModel(
        'pinhole', 96, 80, 0.12, 3.45, 3.45, principal_x_px=44.0, principal_y_px=43.0
    )
    delivered = unflipped_camera(sensor, flip)  # a mirror is its own inverse
    assert (delivered.cx_px, delivered.cy_px) != (sensor.cx_px, sensor.cy_px)
    imgs = frames(cam=sensor, flip=flip)
    node = node_statuses(ctx, '+x-y', cam=delivered, imgs=imgs, readout_flip=flip)
    rows = replay_rows('+x-y', cam=delivered, imgs=imgs, flip=flip)
    assert [r.status for r in rows] == [n['status'] for n in node]
    assert [n['status'] for n in node] == ['ok', 'prior_disagrees', 'ok']
    for k, truth in ((0, 40.0), (2, 200.0)):
        assert rows[k].raw_bearing_deg == pytest.approx(node[k]['bearing_deg'], abs=1e-9)
        assert abs((rows[k].raw_bearing_deg - truth + 180.0) % 360.0 - 180.0) < 2.0
    unflipped = replay_rows('+x-y', cam=delivered, imgs=imgs)
    assert not any(
        r.status == 'ok' and abs((r.raw_bearing_deg - t + 180.0) % 360.0 - 180.0) < 5.0
        for r, t in zip(unflipped, (40.0, 130.0, 200.0))
    )
