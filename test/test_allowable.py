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
Allowable tilt against closed forms.

On a synthetic map whose worst error is exactly c * h * radius, the envelope is ME / (c h); eq 33's
radius is ME^2 / h in any angle unit.
"""

import json
import math
import subprocess
import sys

import numpy as np
from polarization_compass.allowable import allowable_envelope, eq33_radius_deg, format_envelopes
from polarization_compass.errormap import ErrorMap, ErrorMapError, tilt_domain_mask
import pytest

C = 0.02  # deg of error per (deg of sun altitude x deg of tilt)
ALT = np.array([0.0, 10.0, 20.0, 30.0, 40.0, 50.0])
YAW = np.arange(-180.0, 180.0, 5.0)
TILT = np.arange(-30.0, 30.1, 2.5)


def synthetic(scale=(1.0,), names=('a',), limit=30.0, full=False):
    """
    Return a synthetic map whose worst error over yaw is s * C * h * radius.

    error = s * C * h * hypot(p, r) * cos(yaw): worst over yaw (yaw 0 is a node) = s * C * h *
    radius.
    """
    h, y, p, r = np.meshgrid(ALT, YAW, TILT, TILT, indexing='ij')
    base = C * h * np.hypot(p, r) * np.cos(np.radians(y))
    e = np.stack([np.clip(s * base, -89.0, 89.0) for s in scale])
    st = np.zeros(e.shape, np.int8)
    if not full:
        st[..., ~tilt_domain_mask(TILT, TILT, limit, 2)] = -1
    e = np.where(st == 0, e, 0.0)
    return ErrorMap(
        e,
        st,
        tuple(names),
        ALT,
        YAW,
        TILT,
        TILT,
        {'domain': {'tilt_limit_deg': limit, 'full_domain': full}},
    )


def test_eq33_radius_is_unit_free():
    for me, h in ((1.0, 30.0), (5.0, 10.0), (20.0, 50.0)):
        deg = eq33_radius_deg(me, h)
        rad = math.radians(me) ** 2 / math.radians(h)  # the same rule with every angle in radians
        assert deg == pytest.approx(math.degrees(rad), rel=1e-12)
        assert deg == pytest.approx(me * me / h)
    assert math.isinf(eq33_radius_deg(1.0, 0.0))


@pytest.mark.parametrize('me,h', [(2.0, 10.0), (2.0, 30.0), (5.0, 40.0), (1.0, 50.0), (8.0, 50.0)])
def test_envelope_matches_the_closed_form_limit(me, h):
    env = allowable_envelope(synthetic(), me, h)
    exact = me / (C * h)
    assert env.coverage_deg == pytest.approx(30 / math.sqrt(2))
    assert exact < env.coverage_deg
    assert env.radius_estimate_deg == pytest.approx(
        exact, rel=1e-9
    )  # worst is linear in the radius
    assert env.radius_ok_deg <= exact < env.radius_fail_deg
    assert env.pitch_only_deg == (pytest.approx(exact, rel=1e-9), True)
    assert env.roll_only_deg == (pytest.approx(exact, rel=1e-9), True)
    assert env.eq33_radius_deg == pytest.approx(me * me / h)


def test_verdicts_say_which_way_eq33_errs():
    m = synthetic()
    small = allowable_envelope(m, 1.0, 30.0)  # eq 33: 1/30 deg; map: 1/(0.02*30) = 1.67 deg
    assert small.verdict.startswith('DISAGREE, eq 33 is conservative')
    assert '50 x smaller' in small.verdict
    big = allowable_envelope(m, 10.0, 40.0)  # eq 33: 2.5 deg... map 12.5 deg
    assert 'conservative' in big.verdict
    opt = allowable_envelope(
        synthetic(scale=(6.0,)), 6.0, 50.0
    )  # eq33 0.72 deg; map 6/(0.12*50) = 1 deg
    assert opt.verdict.startswith('agree')
    worse = allowable_envelope(synthetic(scale=(20.0,)), 6.0, 50.0)  # map 0.3 deg < eq 33's 0.72
    assert worse.verdict.startswith('DISAGREE, eq 33 is optimistic')
    assert worse.radius_estimate_deg == pytest.approx(
        0.3
    ) and worse.eq33_radius_deg == pytest.approx(0.72)
    coarse = allowable_envelope(
        synthetic(scale=(3.0,)), 10.0, 50.0
    )  # eq 33: 2 deg; map 10/(0.06*50) = 3.3
    assert coarse.verdict.startswith('agree')
    far = allowable_envelope(synthetic(scale=(40.0,)), 20.0, 50.0)  # eq 33: 8 deg; map 0.5 deg
    assert far.verdict.startswith('DISAGREE, eq 33 is optimistic') and far.worst_at_eq33_deg > 20.0
    zero = allowable_envelope(m, 1.0, 0.0)
    assert 'no limit' in zero.verdict and zero.radius_fail_deg is None


def test_every_method_counts_and_the_first_to_fail_is_named():
    m = synthetic(scale=(1.0, 2.0), names=('gentle', 'steep'))
    env = allowable_envelope(m, 4.0, 20.0)
    assert env.radius_estimate_deg == pytest.approx(4.0 / (2 * C * 20.0))
    assert env.worst_method == 'steep'
    only = allowable_envelope(m, 4.0, 20.0, methods=['gentle'])
    assert only.radius_estimate_deg == pytest.approx(4.0 / (C * 20.0))


def test_between_altitude_nodes_the_higher_node_governs():
    m = synthetic()
    env = allowable_envelope(m, 3.0, 25.0)
    assert env.radius_estimate_deg == pytest.approx(3.0 / (C * 30.0))
    assert env.eq33_radius_deg == pytest.approx(9.0 / 25.0)


def test_limits_beyond_the_covered_domain_are_lower_bounds():
    m = synthetic()
    env = allowable_envelope(m, 5.0, 10.0)  # exact 25 deg > coverage 21.2 deg
    assert env.radius_fail_deg is None
    assert env.radius_ok_deg <= env.coverage_deg + 1e-9
    assert env.pitch_only_deg == (
        pytest.approx(25.0),
        True,
    )  # along a single axis the map reaches 30
    full = synthetic(full=True)
    env = allowable_envelope(full, 5.0, 10.0)
    assert env.radius_estimate_deg == pytest.approx(25.0)


def test_bad_requests_are_errors():
    m = synthetic()
    for me, h in ((0.0, 10.0), (-1.0, 10.0), (math.nan, 10.0)):
        with pytest.raises(ErrorMapError):
            allowable_envelope(m, me, h)
    with pytest.raises(ErrorMapError, match='outside the map'):
        allowable_envelope(m, 1.0, 60.0)
    with pytest.raises(ErrorMapError, match='not in this map'):
        allowable_envelope(m, 1.0, 10.0, methods=['zenith'])


def test_table_and_cli(tmp_path):
    m = synthetic(scale=(1.0, 1.5), names=('zenith', 'least_squares'))
    text = format_envelopes([allowable_envelope(m, 2.0, h) for h in (10.0, 50.0)])
    assert 'eq33' in text and 'h = 50 deg' in text and 'deg' in text
    path = m.save(tmp_path / 'm.npz')
    run = [sys.executable, '-m', 'polarization_compass.cli', 'allowable-tilt', '--map', str(path)]
    r = subprocess.run(run + ['--max-error', '2'], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert len([ln for ln in r.stdout.splitlines() if ln.startswith('h = ')]) == ALT.size
    r = subprocess.run(
        run + ['--max-error', '2', '--sun-altitude', '40', '--json'],
        capture_output=True,
        text=True,
        timeout=120,
    )
    out = json.loads(r.stdout)
    assert len(out) == 1 and out[0]['radius_estimate_deg'] == pytest.approx(2.0 / (1.5 * C * 40.0))
    assert out[0]['worst_method'] == 'least_squares'
    for bad in (
        ['--max-error', '-1'],
        ['--max-error', '2', '--sun-altitude', '70'],
        ['--max-error', '2', '--methods', 'nope'],
    ):
        r = subprocess.run(run + bad, capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, (bad, r.stderr)
