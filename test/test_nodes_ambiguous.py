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
An ``ambiguous`` heading never reaches robot_localization unless ``publish_ambiguous`` says so.

The publish rule (docs/ros.md, "Fusing it into robot_localization"): a heading known only modulo
180 deg (status ``ambiguous``) is not published on ``compass/<method>/heading_raw`` (nor its
bearing) unless ``publish_ambiguous`` is true, and its JSON status says what happened. The
``tilt_corrector`` cannot tell an ambiguous heading from a resolved one (an Imu carries no status),
so what the estimator withholds is what keeps ``compass/<method>/heading``, the topic
robot_localization fuses, free of it.

The real chain runs in-process on a private rclpy context: ``heading_estimator`` (method
``sm_asm``, ``prior_source: none``: without intensity the method's symmetry axis never says which
end of the solar meridian holds the sun, so an ideal level frame gives a genuine ``ambiguous``
result from the estimator itself; ``zenith`` would resolve it from the whole sky) fed through its
own callbacks, its ``heading_raw`` publisher forwarded to a ``tilt_corrector``'s heading callback
(``correction: none``, a pass-through: the corrector adds nothing that could hide a leak), whose
``heading`` publisher is recorded. A control frame resolved by the IMU prior goes all the way
through, so an empty topic is the rule at work, not a broken chain.
"""

import math

from polarization_compass.nodes import msgs as M
import pytest
from rclpy.parameter import Parameter
from test_hard_cases_nodes import body_quat, feed_good_frame, imu_msg, T0

BEARING = 40.0  # true bearing of the level camera's +y [deg]
METHOD = 'sm_asm'  # axial without a prior or intensity (test_estimators.AXIAL_METHODS)


class _Recorder:
    """Stand-in publisher: keeps what is published and hands it on."""

    def __init__(self, then=None):
        self.msgs = []
        self.then = then

    def publish(self, msg):
        self.msgs.append(msg)
        if self.then is not None:
            self.then(msg)


@pytest.fixture(scope='module')
def chain(ctx):
    """Build heading_estimator (sm_asm) -> tilt_corrector (pass-through) with recorded outputs."""
    from polarization_compass.nodes.heading_estimator import HeadingEstimatorNode
    from polarization_compass.nodes.tilt_corrector import TiltCorrectorNode

    corr = TiltCorrectorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value=METHOD),
            Parameter('correction', value='none'),
            Parameter('imu_max_wait_s', value=0.0),
        ],
    )
    corr.statuses = []
    corr._status = corr.statuses.append
    corr.pub_heading = _Recorder()  # compass/sm_asm/heading: what robot_localization fuses
    corr.pub_bearing = _Recorder()
    est = HeadingEstimatorNode(
        context=ctx,
        parameter_overrides=[
            Parameter('method', value=METHOD),
            Parameter('site_source', value='navsatfix'),
            Parameter('prior_source', value='none'),
        ],
    )
    est.statuses = []
    est._publish_status = est.statuses.append
    est.pub_heading = _Recorder(then=corr._on_heading)  # compass/sm_asm/heading_raw
    est.pub_bearing = _Recorder()
    yield est, corr
    est.destroy_node()
    corr.destroy_node()


def _frame(est, corr, t_ns):
    """Feed one level frame at ``t_ns`` (the corrector: its IMU); return the estimator status."""
    corr._on_imu(imu_msg(t_ns, body_quat(BEARING, 0.0, 0.0)))
    st = feed_good_frame(est, t_ns, bearing=BEARING, pitch=0.0, roll=0.0)
    corr._drain()
    assert st['stamp_ns'] == t_ns
    return st


def _counts(est, corr):
    return len(est.pub_heading.msgs), len(est.pub_bearing.msgs), len(corr.pub_heading.msgs)


def _set(node, name, value):
    (res,) = node.set_parameters([Parameter(name, value=value)])
    assert res.successful, res.reason


def _yaw_deg(msg):
    q = [getattr(msg.orientation, k) for k in 'xyzw']
    return math.degrees(M.yaw_enu_from_quat(q))


def _is_axial_truth(yaw_deg):
    """Return whether a yaw [deg] is the true one modulo 180 deg (0.5 deg)."""
    return abs(math.remainder(yaw_deg - (90.0 - BEARING), 180.0)) < 0.5


def test_an_ambiguous_heading_is_not_published_by_default(chain):
    est, corr = chain
    assert est.params['publish_ambiguous'] is False  # the default is the rule under test
    before = _counts(est, corr)
    st = _frame(est, corr, T0)
    assert st['status'] == 'ambiguous' and st['axial'] is True, st
    assert st['ok'] is True  # a usable axial heading, withheld by the publish rule alone
    assert _is_axial_truth(st['yaw_enu_deg']), st
    assert st['published'] is False, st
    # nothing on heading_raw / bearing_raw, so nothing on the fused heading either
    assert _counts(est, corr) == before


def test_a_resolved_heading_goes_through_the_same_chain(chain):
    """Control: with the IMU prior the same frame is resolved and reaches the fused topic."""
    est, corr = chain
    _set(est, 'prior_source', 'imu')
    try:
        before = _counts(est, corr)
        t = T0 + 1_000_000_000
        st = _frame(est, corr, t)
        assert st['status'] == 'ok' and st['axial'] is False and st['published'] is True, st
        assert _counts(est, corr) == tuple(n + 1 for n in before)
        fused = corr.pub_heading.msgs[-1]
        assert fused.header.stamp.sec * 1_000_000_000 + fused.header.stamp.nanosec == t
        assert abs(math.remainder(_yaw_deg(fused) - (90.0 - BEARING), 360.0)) < 0.5
        assert corr.statuses[-1]['published'] is True
    finally:
        _set(est, 'prior_source', 'none')


def test_publish_ambiguous_publishes_it_with_its_own_sigma_and_says_so(chain):
    """
    ``publish_ambiguous: true`` publishes the axial heading as is; only the status says so.

    The message is an ordinary heading (yaw variance from the estimator's sigma, not inflated),
    and the pass-through corrector hands it on: the side is a coin toss, which is why the
    parameter's description says never to fuse those into robot_localization (the 180 deg flip
    is then left to ``imu0_pose_rejection_threshold``).
    """
    est, corr = chain
    _set(est, 'publish_ambiguous', True)
    try:
        before = _counts(est, corr)
        t = T0 + 2_000_000_000
        st = _frame(est, corr, t)
        assert st['status'] == 'ambiguous' and st['axial'] is True, st
        assert st['published'] is True, st
        assert _counts(est, corr) == tuple(n + 1 for n in before)
        raw = est.pub_heading.msgs[-1]
        assert _is_axial_truth(_yaw_deg(raw))
        assert _yaw_deg(raw) == pytest.approx(
            math.degrees(math.remainder(math.radians(st['yaw_enu_deg']), 2 * math.pi)), abs=1e-9
        )
        sigma = max(st['sigma_deg'], est.params['sigma_floor_deg'])
        assert raw.orientation_covariance[8] == pytest.approx(math.radians(sigma) ** 2, rel=1e-12)
        assert est.pub_bearing.msgs[-1].data == pytest.approx(st['bearing_deg'])
        assert _is_axial_truth(_yaw_deg(corr.pub_heading.msgs[-1]))
    finally:
        _set(est, 'publish_ambiguous', False)
    # and back to the default: withheld again
    before = _counts(est, corr)
    st = _frame(est, corr, T0 + 3_000_000_000)
    assert st['status'] == 'ambiguous' and st['published'] is False, st
    assert _counts(est, corr) == before
