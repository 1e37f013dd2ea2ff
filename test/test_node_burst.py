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
Good frames survive a hostile burst between them (issue 24, "good frames lost").

The ``heading_estimator`` node (in-process, its reception and worker code called directly, the
worker held back as a busy one is) receives three good frames, each followed by a burst of images
it cannot use: malformed ones (rejected by the decoder) and well-formed ones of another size than
the camera_info. The well-formed ones used to be queued and, more than ``MAX_PENDING_IMAGES`` of
them, pushed the waiting good frames out (``image_queue_full``) before failing one by one in the
worker. Now they get their ``bad_input`` status on reception, never queued, and every good frame
is estimated.
"""

import math

import numpy as np
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import body_quat_from_camera_attitude, CameraAttitude
from polarization_compass.nodes import msgs as M
from polarization_compass.nodes.heading_estimator import MAX_PENDING_IMAGES
from polarization_compass.pipeline import SunSource
import pytest
from rclpy.parameter import Parameter
from test_replay_rules import imu_msg, mosaic, SITE, T0

CAM = CameraModel('pinhole', 96, 80, 0.12, 3.45, 3.45)
BEARINGS = (40.0, 130.0, 250.0)
BURST = MAX_PENDING_IMAGES + 4  # well-formed wrong-size images after each good frame


def _burst(t_ns):
    """Malformed and wrong-size images stamped around ``t_ns``."""
    out = []
    for k in range(BURST):
        out.append(M.image_msg(np.full((78, 96), 0.5, np.float32), t_ns + 1000 * (k + 1), 'c'))
    bad = np.full((80, 96), 0.5, np.float32)
    bad[3, 3] = np.nan
    out.append(M.image_msg(bad, t_ns + 999_000, 'c'))
    m = M.image_msg(np.full((80, 96), 0.5, np.float32), t_ns + 998_000, 'c')
    m.encoding = 'rgb8'
    out.append(m)
    return out


@pytest.fixture
def node(ctx):
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode

    n = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='least_squares'),
            Parameter('site_source', value='navsatfix'),
        ],
    )
    n.statuses = []
    n._publish_status = n.statuses.append
    yield n
    n.destroy_node()


def test_a_burst_between_good_frames_loses_none_of_them(node):
    truth, queued = {}, []
    for k, bearing in enumerate(BEARINGS):
        t = T0 + k * 10**9
        az, alt = SunSource(*SITE).at_ns(t)
        q = body_quat_from_camera_attitude(CameraAttitude(bearing, 0.0, 0.0))
        node._on_camera_info(M.camera_info_msg(CAM, t, 'camera_optical_frame'))
        node._on_fix(M.navsatfix_msg(*SITE, t, 'gps'))
        node._on_imu(imu_msg(t - 10_000_000, q))
        node._on_imu(imu_msg(t + 10_000_000, q))
        assert node._receive_image(M.image_msg(mosaic(bearing, az, alt), t, 'camera_optical'))
        truth[t] = bearing
        # the worker is busy: nothing is processed yet
        queued += [node._receive_image(m) for m in _burst(t)]
    node._drain()
    st = {s['stamp_ns']: s for s in node.statuses if s['status'] == 'ok'}
    assert set(st) == set(truth), 'a good frame was lost'
    assert not any(queued)
    for t, bearing in truth.items():
        assert st[t]['status'] == 'ok', st[t]
        assert abs(math.remainder(st[t]['bearing_deg'] - bearing, 360.0)) < 2.0
    refused = [s for s in node.statuses if s['status'] == 'bad_input']
    assert len(refused) == BURST * len(BEARINGS)
    assert all('camera_info says 96x80' in s['reason'] for s in refused)
    rej = node.diag.rejected
    assert rej['non_finite'] == len(BEARINGS) and rej['bad_encoding'] == len(BEARINGS)
    assert rej['image_queue_full'] == 0


def test_an_image_of_the_camera_info_size_is_still_queued_after_a_resize(node):
    """The check pairs by stamp: an image whose own camera_info has its size is never refused."""
    t = T0
    node._on_camera_info(M.camera_info_msg(CAM, t, 'camera_optical_frame'))
    small = CameraModel('pinhole', 48, 40, 0.06, 3.45, 3.45)
    node._on_camera_info(M.camera_info_msg(small, t + 10**8, 'camera_optical_frame'))
    img = np.full((80, 96), 0.5, np.float32)
    assert node._receive_image(M.image_msg(img, t, 'c'))  # its own camera_info: 96 x 80
    assert not node._receive_image(M.image_msg(img, t + 2 * 10**8, 'c'))  # the latest: 48 x 40
    assert node.statuses[-1]['status'] == 'bad_input'
    assert node.statuses[-1]['stamp_ns'] == t + 2 * 10**8
