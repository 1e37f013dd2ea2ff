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
The knobs of a photodiode array's heading estimator (:data:`ARRAY_KNOBS`).

One table for every array method (:class:`.heading.ArrayHeadingEstimator`), validated like the
camera methods' knobs; the ``array_heading_estimator`` node declares them as its ``knob.*``
parameters.
"""

from __future__ import annotations

from ..estimators._common import Knob

__all__ = ['ARRAY_KNOBS']


ARRAY_KNOBS = {
    'min_units': Knob(
        3, 'int', 2, 64, doc='usable units needed (2 fix the sun exactly, with no misfit check)'
    ),
    'min_dop': Knob(0.02, 'float', 0.0, 1.0, doc='units seeing a lower DoP are not used'),
    'weighting': Knob(
        'dop2',
        'choice',
        choices=('dop2', 'uniform'),
        doc='unit weights: DoP^2 (AoP noise ~ 1/DoP) or equal',
    ),
    'max_misfit_deg': Knob(
        30.0, 'float', 0.1, 90.0, doc='rms angle residual above this: status poor_fit'
    ),
    'max_sun_elevation_diff_deg': Knob(
        35.0,
        'float',
        0.1,
        180.0,
        doc='fitted vs ephemeris sun elevation above this: status poor_fit',
    ),
    'aop_noise_prior_deg': Knob(
        10.0, 'float', 0.0, 90.0, doc='prior AoP noise (model misfit) per unit, pooled into sigma'
    ),
    'prior_dof': Knob(
        4.0, 'float', 0.0, 1e6, doc='degrees of freedom the prior AoP noise is worth'
    ),
    'sigma_floor_deg': Knob(0.0, 'float', 0.0, 90.0, doc='added in quadrature to sigma'),
    'max_sun_altitude_deg': Knob(
        85.0, 'float', 1.0, 90.0, doc='ephemeris sun above this: sun_near_zenith'
    ),
    'min_sun_altitude_deg': Knob(
        0.0, 'float', -10.0, 10.0, doc='ephemeris sun below this: sun_below_horizon'
    ),
    'min_eigen_gap': Knob(
        1e-9, 'float', 0.0, 1.0, doc='(lambda2 - lambda1) / lambda3 below this: degenerate'
    ),
    'min_axes_spread_deg': Knob(
        10.0,
        'float',
        0.0,
        60.0,
        doc="spread of the used units' view axes below this: degenerate (they look one way)",
    ),
    'sign_margin_sigma': Knob(
        3.0, 'float', 0.0, 100.0, doc="elevation margin, in sigmas, for the sun's side"
    ),
    'side_elevation_sigma_deg': Knob(
        3.0,
        'float',
        0.0,
        45.0,
        doc="1-sigma of the levelled frame's elevation (tilt, mount, time) for the sun's side",
    ),
    'max_tilt_deg': Knob(
        30.0, 'float', 0.0, 89.0, doc='least_squares: assumed tilt bound for the sign rule'
    ),
    'brightness_min_t': Knob(
        4.0,
        'float',
        1.0,
        1e6,
        doc="normal-equivalent |t| (n - 2 dof) of the units' brightness gradient fixing the side",
    ),
    'prior_max_diff_deg': Knob(
        60.0, 'float', 1.0, 90.0, doc='a prior bearing within this picks the side'
    ),
}
