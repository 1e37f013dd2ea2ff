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
The heading node's debug image and marker (issue 25), in-process on the test's ROS domain.

A probe built on :class:`polarization_compass.nodes.heading_node.HeadingNodeBase` counts its
renders: without a subscriber to ``~/debug_image`` nothing is rendered or sent; with one, one
``rgb8`` picture arrives and the rate limit holds the next back. The marker's arrow carries the
result's REP-103 yaw (read back from its quaternion).
"""

import math
import time
from types import SimpleNamespace

import numpy as np
from polarization_compass.estimators import HeadingResult, Status
import pytest
import rclpy


def _probe(ctx, rate_hz):
    from polarization_compass.nodes.heading_node import HeadingNodeBase
    from rclpy.node import Node

    class Probe(HeadingNodeBase):
        """A heading node's debug outputs, its picture counted."""

        def __init__(self):
            Node.__init__(self, 'debug_probe', context=ctx)
            values = {'publish_marker': True, 'debug_rate_hz': rate_hz, 'frame_id': 'base_link'}
            self.params = _Params(values)
            self.diag = SimpleNamespace(reject=lambda *a: pytest.fail(f'rejected {a}'))
            self.renders = 0
            self._start_debug(self.params)

        def _debug_rgb(self, prepared, data, result, sun, inp):
            self.renders += 1
            return np.full((6, 8, 3), 200, np.uint8)

    return Probe()


class _Params(dict):
    """Parameter values as a node's ParameterSet gives them."""

    @property
    def values(self):
        return self


def _spin_until(ctx, nodes, cond, timeout_s=10.0):
    from rclpy.executors import SingleThreadedExecutor

    ex = SingleThreadedExecutor(context=ctx)
    for n in nodes:
        ex.add_node(n)
    t_end = time.monotonic() + timeout_s
    while not cond() and time.monotonic() < t_end:
        ex.spin_once(timeout_sec=0.05)
    for n in nodes:
        ex.remove_node(n)
    return cond()


def _result(yaw_enu_deg=30.0):
    return HeadingResult(
        'least_squares',
        Status.OK,
        'test',
        psi_deg=10.0,
        bearing_deg=90.0 - yaw_enu_deg,
        yaw_enu_deg=yaw_enu_deg,
        sigma_deg=2.0,
        pixels=100,
        quality=1.0,
    )


def test_debug_image_only_while_subscribed(ctx):
    from sensor_msgs.msg import Image
    from visualization_msgs.msg import Marker

    probe = _probe(ctx, rate_hz=2.0)
    for _ in range(3):
        probe._publish_debug(1, _result(), None, None, (0.0, 40.0), None, None)
    assert probe.renders == 0, 'rendered without a subscriber'
    listener = rclpy.create_node('debug_listener', context=ctx)
    images, markers = [], []
    listener.create_subscription(Image, '/debug_probe/debug_image', images.append, 1)
    listener.create_subscription(Marker, '/debug_probe/heading_marker', markers.append, 10)
    assert _spin_until(
        ctx, [probe, listener], lambda: probe.pub_debug.get_subscription_count() > 0
    )
    probe._publish_debug(2, _result(), None, None, (0.0, 40.0), None, None)
    probe._publish_debug(3, _result(), None, None, (0.0, 40.0), None, None)  # within 0.5 s
    assert probe.renders == 1, 'the rate limit did not hold'
    assert _spin_until(ctx, [probe, listener], lambda: images and len(markers) >= 4)
    m = images[0]
    assert (m.encoding, m.height, m.width, m.step) == ('rgb8', 6, 8, 24)
    assert bytes(m.data) == bytes([200]) * (6 * 8 * 3)
    arrow = next(k for k in markers if k.type == Marker.ARROW)
    q = arrow.pose.orientation
    assert math.degrees(2 * math.atan2(q.z, q.w)) == pytest.approx(30.0, abs=1e-9)
    assert arrow.header.frame_id == 'base_link'
    listener.destroy_node()
    probe.destroy_node()


class _Sink:
    """A publisher stand-in with one subscriber that keeps what is published."""

    def __init__(self):
        self.msgs = []

    def get_subscription_count(self):
        return 1

    def publish(self, msg):
        self.msgs.append(msg)


def test_heading_estimator_sends_its_picture_and_marker(ctx):
    """The real node on a good frame: one rgb8 picture, debug_width_px wide; the yaw's arrow."""
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode
    from rclpy.parameter import Parameter
    import test_hard_cases_nodes as H
    from visualization_msgs.msg import Marker

    node = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value='tilt_aware'),
            Parameter('site_source', value='navsatfix'),
            Parameter('debug_width_px', value=320),
        ],
    )
    try:
        node.statuses = []
        node._publish_status = node.statuses.append
        node.pub_debug, node.pub_marker = _Sink(), _Sink()
        st = H.feed_good_frame(node, H.T0)
        assert st['ok'], st
        (img,) = node.pub_debug.msgs
        assert (img.encoding, img.width, img.step) == ('rgb8', 320, 960)
        pix = np.frombuffer(bytes(img.data), np.uint8).reshape(img.height, img.width, 3)
        assert pix.std() > 20  # a picture, not a blank
        arrow = next(m for m in node.pub_marker.msgs if m.type == Marker.ARROW)
        q = arrow.pose.orientation
        yaw = math.degrees(2 * math.atan2(q.z, q.w))
        assert abs(math.remainder(yaw - (90.0 - 40.0), 360.0)) < 0.5  # REP-103 of bearing 40
    finally:
        node.destroy_node()
