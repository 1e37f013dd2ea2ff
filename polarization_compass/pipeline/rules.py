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
replay's statuses and sigmas are the node's: the IMU tilt's share of a tilt-reading method's sigma
(:func:`~polarization_compass.pipeline.attitude_sigma.with_attitude_sigma`), the polarizer gate
(:meth:`~polarization_compass.pipeline.monitors.PolarizerMonitor.gate`), then the IMU-prior check
(:meth:`~polarization_compass.pipeline.prior.TiltAndPrior.checked`), whose limit grows with that
sigma. :class:`SensorReadout` reads the images and intrinsics of a mirrored readout back as the
sensor sees them (the node's ``readout_flip`` parameter, replay's topic-mapping key).
"""

from __future__ import annotations

import numpy as np

from .attitude_sigma import with_attitude_sigma
from .monitors import PolarizerMonitor
from .prior import FrameInputs, TiltAndPrior
from ..camera_file import READOUT_FLIPS, unflip, unflipped_camera

__all__ = ['apply_rules', 'SensorReadout']


def apply_rules(
    result,
    inputs: FrameInputs,
    tilt_prior: TiltAndPrior,
    polarizer: PolarizerMonitor | None,
    tilt_sigma: tuple | None = None,
    notes: dict | None = None,
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
    tilt_sigma : tuple of (float, bool), optional
        The IMU tilt's 1-sigma [deg] and whether the IMU stated its covariance
        (:func:`~polarization_compass.pipeline.attitude_sigma.tilt_sigma_deg`); None: no
        attitude share (methods that do not read the tilt ignore it anyway).
    notes : dict, optional
        Receives the attitude share's numbers
        (:func:`~polarization_compass.pipeline.attitude_sigma.with_attitude_sigma`).

    Returns
    -------
    HeadingResult
        ``result``, its sigma grown by the attitude share; ``poor_fit`` while the sky disfavours
        the polarizer configuration; ``prior_disagrees`` when the heading contradicts the IMU
        prior.

    """
    if tilt_sigma is not None and tilt_prior.needs_tilt:
        result = with_attitude_sigma(
            result, tilt_prior.method, inputs.pitch_deg, inputs.roll_deg, tilt_sigma, notes
        )
    if polarizer is not None:
        result = polarizer.gate(result)
    return tilt_prior.checked(result, inputs)


class SensorReadout:
    """
    A camera's mirrored readout undone: images and intrinsics as the sensor itself sees them.

    The node's ``readout_flip`` parameter and replay's topic-mapping key ``readout_flip``: each
    image is read back (:func:`~polarization_compass.camera_file.unflip`) and the camera_info's K
    mirrored with it (:func:`~polarization_compass.camera_file.unflipped_camera`, kept per K), so
    that the polarizer layout describes the sensor.

    Parameters
    ----------
    readout_flip : {"none", "", "x", "y", "xy"}
        The axes the readout mirrors ("none" = "").

    """

    def __init__(self, readout_flip: str = ''):
        flip = '' if readout_flip in (None, 'none') else str(readout_flip)
        if flip not in READOUT_FLIPS:
            raise ValueError(f'readout_flip must be one of none, x, y, xy, got {readout_flip!r}')
        self.flip = flip
        self._cameras = None  # (delivered camera, the sensor's)

    def image(self, mosaic):
        """
        Return a delivered image as the sensor sees it (itself without a flip).

        Parameters
        ----------
        mosaic : numpy.ndarray
            The delivered image, rows x columns.

        Returns
        -------
        numpy.ndarray
            The image with the mirrored axes reversed back, C-contiguous.

        """
        if not self.flip:
            return mosaic
        return np.ascontiguousarray(unflip(mosaic, self.flip))

    def camera(self, cam):
        """
        Return the intrinsics of the sensor's own image from the delivered image's.

        Parameters
        ----------
        cam : CameraModel
            The camera_info's (delivered image's) intrinsics.

        Returns
        -------
        CameraModel
            The mirrored intrinsics (``cam`` itself without a flip).

        """
        if not self.flip:
            return cam
        if self._cameras is None or self._cameras[0] != cam:
            self._cameras = (cam, unflipped_camera(cam, self.flip))
        return self._cameras[1]
