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
The check-polarizer command on simulated skies with known truth.

Whatever 2 x 2 phase and 45 deg direction the simulated sensor has, the check names it (and calls
the configured one supported or contradicted), and a sun on an image axis -- where the mirrored
pattern is itself a valid sky -- is never mis-decided.
"""

from conftest import FisheyeSky
from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
from polarization_compass.camera_pixels import PixelSelection, select_pixels
from polarization_compass.estimators.mosaic_input import _grid_rays
from polarization_compass.mosaic import IMX250MZR_LAYOUT, IMX250MZR_POL45, parse_layout
from polarization_compass.polarizer_check import check_polarizer, polarizer_hypotheses

N = 128
CAM = FisheyeSky.camera(N)


def rays_for_shape(shape):
    if tuple(shape) == (N, N):
        sp = select_pixels(CAM, PixelSelection.full())
        return sp.rays_cam, sp.has_ray
    _, _, rays, ok = _grid_rays(CAM, (1.5, 2.0, N // 2), (1.5, 2.0, N // 2))
    return rays, ok


def simulate(layout, pol45, psi_deg, sun_alt_deg):
    return FisheyeSky.mosaic(CAM, layout, pol45, psi_deg + 40.0, 40.0, sun_alt_deg, 1)


def test_there_are_eight_distinct_hypotheses_for_a_mosaic_and_two_for_stokes():
    h = polarizer_hypotheses(IMX250MZR_LAYOUT, IMX250MZR_POL45, raw=True)
    assert len({(x.layout, x.pol45_toward) for x in h}) == 8
    assert (h[0].layout, h[0].pol45_toward) == (IMX250MZR_LAYOUT, IMX250MZR_POL45)
    assert len(polarizer_hypotheses(IMX250MZR_LAYOUT, IMX250MZR_POL45, raw=False)) == 2


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.sampled_from([(0, 0), (0, 1), (1, 0), (1, 1)]),
    st.sampled_from(['+x+y', '+x-y']),
    st.floats(15.0, 75.0),
    st.integers(0, 3),
    st.floats(20.0, 60.0),
)
def test_any_layout_phase_and_direction_is_detected(phase, pol45, psi_off, quadrant, sun_alt):
    """
    Any layout phase and 45 deg direction is detected.

    The sun's image direction is kept 15 deg or more from the image axes (psi = 0 puts it on +y).
    """
    truth = parse_layout(IMX250MZR_LAYOUT, pol45).shifted(*phase)
    mosaic = simulate(truth.angles_deg, pol45, psi_off + 90.0 * quadrant, sun_alt)
    rep = check_polarizer(
        [('mosaic', mosaic, None)], CAM, IMX250MZR_LAYOUT, IMX250MZR_POL45, rays_for_shape
    )
    assert rep['best'] == {'layout': [list(r) for r in truth.angles_deg], 'pol45_toward': pol45}, (
        rep['margin']
    )
    configured = phase == (0, 0) and pol45 == IMX250MZR_POL45
    assert rep['verdict'] == ('supported' if configured else 'contradicted'), rep['reason']
    if not configured:
        assert "pol45_toward: '%s'" % pol45 in rep['fix']


def test_stokes_input_direction_is_detected_and_an_axis_sun_is_not_misjudged():
    for pol45 in ('+x+y', '+x-y'):
        mosaic = simulate(parse_layout(IMX250MZR_LAYOUT, pol45).angles_deg, pol45, 35.0, 40.0)
        from polarization_compass.demosaic import stokes_from_mosaic

        s0, s1, s2 = stokes_from_mosaic(mosaic, IMX250MZR_LAYOUT, pol45, 'superpixel')
        sdk = (s0, s1, -s2 if pol45 == '+x-y' else s2)  # what an SDK writes: the sensor's labels
        rep = check_polarizer(
            [('stokes', sdk, None)], CAM, IMX250MZR_LAYOUT, '+x-y', rays_for_shape
        )
        assert rep['best']['pol45_toward'] == pol45
        assert rep['verdict'] == ('supported' if pol45 == '+x-y' else 'contradicted')
    # sun on the image's y axis: the mirrored field is the same sky, so no verdict may be wrong
    mosaic = simulate(parse_layout(IMX250MZR_LAYOUT, '+x+y').angles_deg, '+x+y', 0.0, 40.0)
    rep = check_polarizer(
        [('mosaic', mosaic, None)], CAM, IMX250MZR_LAYOUT, IMX250MZR_POL45, rays_for_shape
    )
    assert rep['verdict'] == 'cannot_tell' or rep['best']['pol45_toward'] == '+x+y'
