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
    Watch the polarizer convention on live frames, and refuse headings the sky contradicts.

    Runs :func:`polarization_compass.polarizer_check.check_frame` (at most ``max_blocks`` 2 x 2
    blocks, block-aligned so the layout's phase is kept) on **every** frame until the sky supports
    the configured convention, and while it contradicts it; once supported, on every
    ``every_n``-th frame (the convention is the camera's, not the frame's). ``every_n`` 0 turns
    the check off.

    :meth:`gate` turns a heading into ``poor_fit`` naming the fix while the last check
    contradicts (or clearly disfavours) the configuration
    (:func:`~polarization_compass.polarizer_check.gate_result`); :attr:`error` is the same text,
    which a node publishes as a diagnostics ERROR. ``cannot_tell`` keeps the previous verdict.
    Measured (10 000 blocks, eight hypotheses, one loaded core): 60-170 ms per check at the known
    sun altitude, 0.5-2 s when it disfavours the configuration (then refitted with the altitude
    free).
    """

    def __init__(self, every_n: int = 100, max_blocks: int = 10000):
        self.every_n = int(every_n)
        self.max_blocks = int(max_blocks)
        self.count = 0
        self.last: dict | None = None
        self.error: str | None = None
        self.supported = False  # the last decisive check supported the configuration
        self._against: dict | None = None  # the last report that disfavours the configuration

    def reset(self) -> None:
        """
        Forget the verdicts (a new polarizer configuration): check from the next frame on.

        :attr:`error` stays until the next decisive check, so a node can clear the diagnostics
        ERROR it raised.
        """
        self.count = 0
        self.supported = False
        self._against = None

    def due(self) -> bool:
        """
        Count a frame and say whether it is checked.

        Returns
        -------
        bool
            True for every frame until the sky supports the configuration (and while it
            contradicts it), then for every ``every_n``-th; never with ``every_n`` 0.

        """
        if self.every_n <= 0:
            return False
        self.count += 1
        return not self.supported or self.count % self.every_n == 0

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
        Count a frame and, when :meth:`due`, check the polarizer convention on it.

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
        if not self.due():
            return None
        from ..polarizer_check import check_frame, contradiction_text, disfavoured

        m = np.asarray(mosaic)
        sat = float(np.iinfo(m.dtype).max) if np.issubdtype(m.dtype, np.integer) else None
        rep = check_frame(
            'mosaic',
            m,
            sat,
            camera,
            layout.angles_deg,
            layout.pol45_toward,
            sun_altitude_deg,
            pitch_deg,
            roll_deg,
            max_samples=self.max_blocks,
        )
        self.last = rep
        if disfavoured(rep):
            self._against, self.supported = rep, False
            self.error = contradiction_text(rep)
        elif rep['verdict'] == 'supported':
            self._against, self.supported, self.error = None, True, None
        return rep

    def gate(self, result):
        """
        Refuse a heading while the last check disfavours the configuration.

        Parameters
        ----------
        result : HeadingResult
            A method's result on the frame.

        Returns
        -------
        HeadingResult
            ``result``, or ``poor_fit`` naming the fix
            (:func:`~polarization_compass.polarizer_check.gate_result`).

        """
        from ..polarizer_check import gate_result

        return gate_result(result, self._against)
