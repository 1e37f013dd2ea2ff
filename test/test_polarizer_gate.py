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
The polarizer hypotheses run where the heading is decided (issue 24, item 3).

A ``+x+y`` sensor read with the default ``+x-y`` configuration mirrors every AoP; with the sun at
2-35 deg every method used to report ``ok`` 90-180 deg off. ``estimate`` (the core road
:func:`polarization_compass.headings.estimate_file`) must now refuse those headings and name the
fix, while the right configuration keeps ``ok`` and the true heading.
"""

from conftest import FisheyeSky
import numpy as np
from polarization_compass.conventions import wrap_180_deg
from polarization_compass.headings import estimate_file, EstimateOptions
from polarization_compass.mosaic import IMX250MZR_LAYOUT, parse_layout
import pytest

N = 160
CAM = FisheyeSky.camera(N)
METHODS = ['zenith', 'sm_asm', 'symmetry', 'least_squares']


def camera_yaml(path, pol45=None):
    """Write the CAMERA.yaml of ``CAM``; without ``pol45`` the package default (+x-y)."""
    extra = ''
    if pol45:
        extra = f"polarizer: {{layout: [[90, 45], [135, 0]], pol45_toward: '{pol45}'}}\n"
    path.write_text(FisheyeSky.camera_yaml(N, CAM.K_matrix(), extra))
    return str(path)


def mosaic_file(path, pol45, psi_deg, sun_alt_deg):
    """Render a raw mosaic of a sensor whose +45 deg polarizer points towards ``pol45``."""
    lay = parse_layout(IMX250MZR_LAYOUT, pol45)
    np.save(path, FisheyeSky.mosaic(CAM, lay.angles_deg, pol45, psi_deg, 0.0, sun_alt_deg, 3))
    return str(path)


def run(path, cam, sun_alt):
    opts = EstimateOptions(
        methods=METHODS, camera_yaml=cam, sun_azimuth_deg=0.0, sun_altitude_deg=float(sun_alt)
    )
    return estimate_file(path, opts)


@pytest.mark.parametrize('sun_alt,psi', [(2.0, 30.0), (12.0, 100.0), (35.0, -60.0)])
def test_a_mirrored_convention_is_never_ok_and_names_the_fix(tmp_path, sun_alt, psi):
    mos = mosaic_file(tmp_path / 'm.npy', '+x+y', psi, sun_alt)
    rows = run(mos, camera_yaml(tmp_path / 'default.yaml'), sun_alt)
    assert [d['status'] for d in rows if d['status'] in ('ok', 'ambiguous')] == [], rows
    gated = [d for d in rows if d['psi_deg'] is not None]
    assert gated, 'no method produced a heading to refuse'
    for d in gated:
        assert d['status'] == 'poor_fit'
        assert 'polarizer convention' in d['reason'] and "pol45_toward: '+x+y'" in d['reason']
    assert rows[0]['source']['polarizer_check']['best']['pol45_toward'] == '+x+y'


@pytest.mark.parametrize('sun_alt,psi', [(2.0, 30.0), (35.0, -60.0)])
def test_the_right_convention_stays_ok_with_the_true_heading(tmp_path, sun_alt, psi):
    mos = mosaic_file(tmp_path / 'm.npy', '+x+y', psi, sun_alt)
    rows = run(mos, camera_yaml(tmp_path / 'right.yaml', '+x+y'), sun_alt)
    oks = [d for d in rows if d['status'] == 'ok']
    assert len(oks) >= 3, rows
    for d in oks:
        assert abs(float(wrap_180_deg(d['psi_deg'] - psi))) < 1.0, d
    assert rows[0]['source']['polarizer_check']['verdict'] in ('supported', 'cannot_tell')
