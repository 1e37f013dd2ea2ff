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

"""The camera intrinsics in use from a camera_info stream."""

from __future__ import annotations

from collections import OrderedDict

from .errors import PipelineError

__all__ = [
    'CameraInfoState',
]


class CameraInfoState:
    """
    The intrinsics in use from a camera_info stream, and why none are.

    ROS-free: the node and the replay hold one each.

    :meth:`accept` a decoded, validated camera; :meth:`reject` a message that failed decoding or
    :func:`~polarization_compass.camera.check_intrinsics`. A rejection also withdraws the camera
    accepted before it: the stream now says something else about the camera (a recalibration,
    another resolution or binning), and using the old intrinsics could be worse than none -- frames
    get a ``bad_input`` status naming the rejection until a valid camera_info arrives.
    :meth:`camera` is the camera to use, None when no camera_info arrived yet (the caller's
    fallback applies), or raises :class:`PipelineError`.
    """

    #: camera_info messages remembered by stamp, to pair an image with its own (issue 24).
    STAMPS_KEPT = 64

    def __init__(self):
        self._by_stamp: OrderedDict = OrderedDict()  # stamp ns -> (camera, rejection reason)
        self._camera = None
        self.rejected_reason: str | None = None
        self.accepted = 0
        self.rejected = 0

    def accept(self, camera, stamp_ns: int | None = None) -> None:
        """
        Use a camera from now on.

        Parameters
        ----------
        camera : CameraModel
            Decoded and validated (:func:`~polarization_compass.camera.check_intrinsics`).
        stamp_ns : int, optional
            The message's header stamp [ns]: the image of this stamp gets this camera.

        """
        self._camera = camera
        self.rejected_reason = None
        self.accepted += 1
        self._remember(stamp_ns, camera, None)

    def reject(self, reason: str, stamp_ns: int | None = None) -> None:
        """
        Record a rejected camera_info; the camera in use is withdrawn.

        Parameters
        ----------
        reason : str
            Why it was rejected (one line).
        stamp_ns : int, optional
            The message's header stamp [ns]: the image of this stamp gets no camera.

        """
        self.rejected_reason = str(reason)
        self.rejected += 1
        self._remember(stamp_ns, None, self.rejected_reason)

    def _remember(self, stamp_ns, camera, reason) -> None:
        if stamp_ns is None:
            return
        self._by_stamp[int(stamp_ns)] = (camera, reason)
        self._by_stamp.move_to_end(int(stamp_ns))
        while len(self._by_stamp) > self.STAMPS_KEPT:
            self._by_stamp.popitem(last=False)

    @property
    def received_any(self) -> bool:
        """Whether any camera_info arrived (accepted or rejected)."""
        return self.accepted + self.rejected > 0

    def camera(self, stamp_ns: int | None = None):
        """
        Return the camera to use for an image: its own camera_info's, else the latest.

        An image is paired with the camera_info of its stamp when one of the last
        :attr:`STAMPS_KEPT` had it, so a hostile camera_info arriving between a good one and its
        image does not spoil that image; otherwise the latest camera_info decides.

        Parameters
        ----------
        stamp_ns : int, optional
            The image's header stamp [ns]; None: the latest camera_info.

        Returns
        -------
        CameraModel or None
            The accepted camera; None before any camera_info (the caller's fallback applies).

        Raises
        ------
        PipelineError
            The image's own camera_info, or without one the latest, was rejected (its reason).

        """
        if stamp_ns is not None and int(stamp_ns) in self._by_stamp:
            camera, reason = self._by_stamp[int(stamp_ns)]
            if reason is not None:
                raise PipelineError(f"this image's camera_info was rejected ({reason})")
            return camera
        if self.rejected_reason is not None:
            raise PipelineError(
                f'the latest camera_info was rejected ({self.rejected_reason}); no intrinsics '
                'in use until a valid one arrives'
            )
        return self._camera
