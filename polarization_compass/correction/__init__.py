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
Tilt correction from an error map (paper, section 3.4, done properly).

A tilted camera makes a classical method report ``psi_meas = psi + e(psi, h, pitch, roll)``, where
the error ``e`` (an :class:`~polarization_compass.errormap.ErrorMap`) is a function of the *true*
yaw psi, which the corrector does not know. Two corrections are offered:

``invert`` (default)  solve ``psi + e(psi, h, pitch, roll) = psi_meas`` for psi: a 1-D search over
                      a +-90 deg window of yaw around the measurement (the map's errors are folded
                      to (-90, 90]), bracketing sign changes on a sub-grid of the yaw axis, then
                      bisection to 1e-9 deg. Several roots: status ``multiple_solutions`` (the
                      heading returned is the root nearest the ``subtract`` estimate; all roots are
                      listed); none: ``no_solution``.
``subtract``          the paper's reading: ``psi = psi_meas - e(psi_meas, ...)``, i.e. the error
                      looked up at the measured yaw. Wrong by about ``e * de/dpsi``: several
                      degrees at large tilt and high sun (docs/error-maps.md gives the numbers).

Interpolation: tensor-product cubic convolution (Keys, a = -1/2; periodic along yaw, Keys' cubic
boundary rule at the ends of the other axes) on uniform axes, multilinear on non-uniform or short
(< 4 nodes) axes; where a cubic stencil touches a node without a valid estimate the point falls
back to multilinear in its grid cell. ``order=1`` forces multilinear everywhere.

Domain (status ``out_of_domain``, never silent extrapolation): sun altitude, pitch and roll inside
the map's axes; |pitch| + |roll| <= the map's tilt limit unless the map was computed on the full
domain; and every node the interpolation reads holds a valid estimate. The map's yaw axis must
cover a full turn with a uniform step (it is periodic).

Angles in degrees; psi is the paper's yaw (bearing minus sun azimuth), (-180, 180].

Modules: :mod:`.corrector` (:class:`TiltCorrector`, the shipped map), :mod:`.sensitivity` (its
derivatives with respect to the attitude), :mod:`.results` (what a correction returns),
:mod:`.weights` (interpolation weights) and :mod:`.kernels` (the compiled curve and inversion); the
names below are the package's documented surface.
"""

from .corrector import (
    DEFAULT_MAP_NAME,
    default_map_path,
    REGENERATE_DEFAULT_MAP,
    TiltCorrector,
)
from .results import BearingCorrections, Correction, CorrectionStatus, STATUS_INT

__all__ = [
    'TiltCorrector',
    'Correction',
    'CorrectionStatus',
    'STATUS_INT',
    'default_map_path',
    'DEFAULT_MAP_NAME',
    'REGENERATE_DEFAULT_MAP',
    'BearingCorrections',
]
