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

"""What a tilt correction returns: :class:`CorrectionStatus`, :class:`Correction`, bearings."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import numpy as np


class CorrectionStatus(str, Enum):
    """
    Outcome of one tilt correction (values are strings).

    ``ok``; ``out_of_domain`` (outside the map's axes or tilt limit, or an invalid node is needed);
    ``multiple_solutions`` (several yaws predict the measurement); ``no_solution`` (none does).
    """

    OK = 'ok'
    OUT_OF_DOMAIN = 'out_of_domain'
    MULTIPLE_SOLUTIONS = 'multiple_solutions'
    NO_SOLUTION = 'no_solution'


#: int8 codes of :meth:`TiltCorrector.correct_many`.
STATUS_INT = {
    CorrectionStatus.OK: 0,
    CorrectionStatus.OUT_OF_DOMAIN: 1,
    CorrectionStatus.MULTIPLE_SOLUTIONS: 2,
    CorrectionStatus.NO_SOLUTION: 3,
}
_FROM_INT = {v: k for k, v in STATUS_INT.items()}


class BearingCorrections(NamedTuple):
    """
    Hold the corrected bearings of :meth:`TiltCorrector.correct_bearings`, all finite.

    Parameters
    ----------
    bearing_deg : numpy.ndarray
        Corrected bearings of camera +y [deg] in [0, 360), clockwise from North, shape (N,);
        0.0 where ``ok`` is False (no heading there: read ``status``, never this value).
    ok : numpy.ndarray
        bool (N,): True where the correction succeeded (status ``ok``).
    status : list of str
        :class:`CorrectionStatus` value per heading, the reason there is no heading when not ok.

    """

    bearing_deg: np.ndarray
    ok: np.ndarray
    status: list


@dataclass(frozen=True)
class Correction:
    """
    Hold one corrected heading; ``psi_deg`` is None when there is none (status says why).

    Parameters
    ----------
    status : CorrectionStatus
        Outcome.
    psi_deg : float or None
        Corrected yaw psi [deg] (eq 21), (-180, 180].
    error_deg : float or None
        The map's error at the corrected yaw, ``psi_meas - psi`` [deg].
    candidates_deg : tuple of float
        Every root of the inversion [deg].
    mode : str
        ``invert`` or ``subtract``.
    reason : str
        Why the status is not ``ok`` (or how a root was chosen).

    """

    status: CorrectionStatus
    psi_deg: float | None = None
    error_deg: float | None = None
    candidates_deg: tuple = ()
    mode: str = 'invert'
    reason: str = ''

    @property
    def ok(self) -> bool:
        """Whether a corrected heading exists (status ``ok``)."""
        return self.status == CorrectionStatus.OK
