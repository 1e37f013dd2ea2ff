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
The rules a method's result passes before it is published: one implementation, node and replay.

The ``heading_estimator`` node and ``replay`` both call :func:`apply_rules` on every result, so
replay's statuses are the node's: the polarizer gate
(:meth:`~polarization_compass.pipeline.monitors.PolarizerMonitor.gate`), then the IMU-prior check
(:meth:`~polarization_compass.pipeline.prior.TiltAndPrior.checked`).
"""

from __future__ import annotations

from .monitors import PolarizerMonitor
from .prior import FrameInputs, TiltAndPrior

__all__ = ['apply_rules']


def apply_rules(
    result, inputs: FrameInputs, tilt_prior: TiltAndPrior, polarizer: PolarizerMonitor | None
):
    """
    Apply the node's rules to one method's result, in order.

    Parameters
    ----------
    result : HeadingResult
        The method's result (after the whole-sky check when it is on).
    inputs : FrameInputs
        The frame's tilt and prior for this method.
    tilt_prior : TiltAndPrior
        The method's prior rules (its ``prior_source`` and ``prior_sigma_deg``).
    polarizer : PolarizerMonitor or None
        The frame stream's polarizer check (already fed with this frame); None: no gate.

    Returns
    -------
    HeadingResult
        ``result``; ``poor_fit`` while the sky disfavours the polarizer configuration;
        ``prior_disagrees`` when the heading contradicts the IMU prior.

    """
    if polarizer is not None:
        result = polarizer.gate(result)
    return tilt_prior.checked(result, inputs)
