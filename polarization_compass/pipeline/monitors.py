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

"""Watches on the live stream: images lost before the node, and the polarizer convention."""

from __future__ import annotations

import numpy as np

from .sampling import decimated_blocks
from ..camera import CameraModel

__all__ = [
    'ImageLossWatch',
    'PolarizerMonitor',
]


class ImageLossWatch:
    """
    Count images lost before they reached the node, from the camera_info stream.

    Lost means the middleware's keep-last queue overflowed or the transport dropped them. A camera
    driver publishes one camera_info per image with the image's stamp, so a camera_info stamp
    without any image of that stamp ``after_ns`` (stamp time) behind the newest camera_info is one
    image lost. Never counts a frame twice; undercounts when camera_info messages are lost too (or
    when no camera_info is published: then nothing is counted). Counts only once an image and a
    camera_info of the same stamp were seen (a driver stamping them differently is never reported
    as losing every image). Thread-safe (images and camera_info arrive on different executor
    threads).
    """

    def __init__(self, after_ns: int = 1_000_000_000, keep: int = 512):
        from collections import OrderedDict
        import threading

        self.after_ns = int(after_ns)
        self.keep = int(keep)
        self._lock = threading.Lock()
        self._info: OrderedDict = OrderedDict()  # camera_info stamps waiting for their image
        self._images: OrderedDict = OrderedDict()  # image stamps seen (good or bad)
        self.lost = 0
        self.paired = False  # an image and a camera_info of one stamp were seen

    def image(self, t_ns: int) -> None:
        """
        Record an image that arrived (good or bad).

        Parameters
        ----------
        t_ns : int
            Its header stamp [ns].

        """
        with self._lock:
            t = int(t_ns)
            if self._info.pop(t, 0) is None:
                self.paired = True
            self._images[t] = None
            while len(self._images) > self.keep:
                self._images.popitem(last=False)

    def camera_info(self, t_ns: int) -> int:
        """
        Record a camera_info stamp and count the images found lost now.

        Parameters
        ----------
        t_ns : int
            The camera_info's header stamp [ns].

        Returns
        -------
        int
            Images newly found lost (their camera_info is ``after_ns`` behind the newest).

        """
        with self._lock:
            t = int(t_ns)
            if t not in self._images:
                self._info[t] = None
            else:
                self.paired = True
            newest = max(self._info, default=t)
            lost = [s for s in self._info if s < newest - self.after_ns] if self.paired else []
            for s in lost:
                del self._info[s]
            while len(self._info) > self.keep:  # a stream of camera_info without images at all
                self._info.popitem(last=False)
            self.lost += len(lost)
            return len(lost)


# ------------------------------------------------------------------------------------------------
# Polarizer convention watched on live frames
# ------------------------------------------------------------------------------------------------
class PolarizerMonitor:
    """
    Watch the polarizer convention on live frames.

    Runs :func:`polarization_compass.polarizer_check.check_polarizer` on every ``every_n``-th
    mosaic (0 = never; the first check is on frame ``every_n``), on a decimated superpixel grid (at
    most ``max_blocks`` 2 x 2 blocks, block-aligned so the layout's phase is kept), and remembers
    the last decisive verdict.

    :attr:`error` is the text a node publishes as a diagnostics ERROR while the last decisive check
    contradicts the configured layout (it names the fix); ``cannot_tell`` keeps the previous
    verdict.
    """

    def __init__(self, every_n: int = 100, max_blocks: int = 10000):
        self.every_n = int(every_n)
        self.max_blocks = int(max_blocks)
        self.count = 0
        self.last: dict | None = None
        self.error: str | None = None

    def feed(
        self,
        mosaic,
        camera: CameraModel,
        layout,
        sun_altitude_deg=None,
        pitch_deg=None,
        roll_deg=None,
    ) -> dict | None:
        """
        Count a frame and, on every ``every_n``-th, check the polarizer convention.

        Parameters
        ----------
        mosaic : numpy.ndarray
            Raw full-sensor DoFP image.
        camera : CameraModel
            The camera (rays of the decimated superpixels, cached).
        layout : MosaicLayout
            The configured :class:`~polarization_compass.demosaic.MosaicLayout`.
        sun_altitude_deg : float, optional
            Sun altitude [deg]; None: fitted.
        pitch_deg, roll_deg : float, optional
            Known tilt [deg] (eq 21); None: level.

        Returns
        -------
        dict or None
            The :func:`~polarization_compass.polarizer_check.check_polarizer` report on a checked
            frame, else None.

        """
        if self.every_n <= 0:
            return None
        self.count += 1
        if self.count % self.every_n:  # the every_n-th frame, not the first: start-up stays fast
            return None
        from ..estimators.mosaic_input import _grid_rays
        from ..polarizer_check import check_polarizer

        m = np.asarray(mosaic)
        small, k, nx, ny = decimated_blocks(m, self.max_blocks)

        def rays_for_shape(shape):
            _, _, rays, ok = _grid_rays(camera, (1.5, 2.0 * k, nx), (1.5, 2.0 * k, ny))
            return rays, ok

        sat = float(np.iinfo(m.dtype).max) if np.issubdtype(m.dtype, np.integer) else None
        rep = check_polarizer(
            [('mosaic', small, sat)],
            camera,
            layout.angles_deg,
            layout.pol45_toward,
            rays_for_shape,
            sun_altitude_deg,
            pitch_deg or 0.0,
            roll_deg or 0.0,
        )
        self.last = rep
        if rep['verdict'] == 'contradicted':
            self.error = (
                f'polarizer convention contradicted by the sky (margin {rep["margin"]:.2f}): '
                f'{rep.get("fix", "")}'
            )
        elif rep['verdict'] == 'supported':
            self.error = None
        return rep
