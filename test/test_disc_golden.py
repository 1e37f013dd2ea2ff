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
sm_asm and symmetry give the answers they gave before their passes were made faster.

A golden test, on purpose: the speed-up (shared bilinear lookups, one influence pass for both
block sizes, fused residual passes, ...) must not change behaviour. The stored answers
(``test/data/disc_golden.npz``) were written by ``test/disc_golden.py`` on main at 9edd6dd, before
the speed-up; the frames (ideal, tilted, noisy, broken clouds, overcast, occluded, a pixel list, a
region, a noisy mosaic, three real frames) are rebuilt here from the same script.
"""

import math

import disc_golden as G
import numpy as np
import pytest

#: psi and sigma must agree to this (deg): the same fits up to the rounding of reordered sums
TOL_DEG = 1e-9


@pytest.fixture(scope='module')
def stored():
    d = np.load(G.OUT)
    return {
        str(k): (float(p), float(s), str(st), str(r))
        for k, p, s, st, r in zip(d['keys'], d['psi'], d['sigma'], d['status'], d['reason'])
    }


@pytest.fixture(scope='module')
def now():
    return G.run_all()


def test_every_stored_case_is_rebuilt(stored, now):
    assert set(now) == set(stored)
    assert len(stored) > 200
    # the set exercises refusals too, not only headings
    assert {v[2] for v in stored.values()} >= {'ok', 'ambiguous', 'insufficient_coverage'}


def test_answers_are_unchanged(stored, now):
    bad = []
    for key, (psi0, sig0, st0, why0) in stored.items():
        psi, sig, st, why = now[key]
        same = st == st0 and why == why0
        for a, b in ((psi, psi0), (sig, sig0)):
            if math.isnan(a) or math.isnan(b):
                same &= math.isnan(a) and math.isnan(b)
            else:
                same &= abs(a - b) <= TOL_DEG
        if not same:
            bad.append((key, (psi, sig, st, why), (psi0, sig0, st0, why0)))
    assert not bad, bad[:5]
