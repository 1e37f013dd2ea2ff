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
A division-of-focal-plane mosaic: its 2 x 2 polarizer layout and the checks of a raw image.

:class:`MosaicLayout` (from :func:`parse_layout` or a ``mosaic:`` mapping,
:func:`layout_from_mapping`) holds the polarizer angles of the mosaic's top-left 2 x 2 block and
the image direction of the 45 deg polarizer, and gives the Stokes weights of each pixel; the
conventions are in :mod:`.demosaic`'s docstring. :class:`SensorError` is the error of a bad sensor
configuration or an unusable raw image.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .errors import CompassError

#: Sony IMX250MZR, top-left 2 x 2 block, row by row.
IMX250MZR_LAYOUT = ((90, 45), (135, 0))


_POL45 = ('+x+y', '+x-y')
#: The image direction of the IMX250MZR's 45 deg polarizer as real cameras deliver the image (no
#: ReverseX/ReverseY): towards +x-y, up and to the right on the displayed image (Sony's drawing,
#: whose angles run counter-clockwise with the image's y axis up). Measured on real sky frames (two
#: independent sources, ``test/data/real-sky``; ``polarization-compass check-polarizer``). A
#: readout flipped in one axis (ReverseX or ReverseY) mirrors the image and turns this into +x+y
#: (and moves the 2 x 2 phase); flipped in both it stays +x-y (a 180 deg rotation keeps polarizer
#: angles).
IMX250MZR_POL45 = '+x-y'


class SensorError(CompassError):
    """Bad sensor configuration or unusable raw image (the message says which value and why)."""


@dataclass(frozen=True)
class MosaicLayout:
    """
    Hold a validated 2 x 2 polarizer layout of a DoFP mosaic.

    Parameters
    ----------
    angles_deg : tuple of tuple of int, default ((90, 45), (135, 0))
        ``angles_deg[r][c]`` is the polarizer angle [deg] at row r, column c of the mosaic's
        top-left 2 x 2 block (0, 45, 90 and 135 once each; IMX250MZR by default).
    pol45_toward : {"+x-y", "+x+y"}, default "+x-y"
        Image direction of the 45 deg polarizer from +x_cam (columns): towards +y_cam (down the
        rows) or -y_cam (up); see the module docstring.

    """

    angles_deg: tuple = IMX250MZR_LAYOUT
    pol45_toward: str = IMX250MZR_POL45

    @property
    def camera_angles_deg(self) -> np.ndarray:
        """
        Return the (2, 2) polarizer angles from +x_cam towards +y_cam (deg).

        Each is the physical angle, or minus it, as ``pol45_toward`` says.
        """
        a = np.asarray(self.angles_deg, dtype=float)
        return a if self.pol45_toward == '+x+y' else -a

    def shifted(self, dy: int, dx: int) -> 'MosaicLayout':
        """
        Return the layout seen by a block whose top-left pixel is (dy, dx) into this pattern.

        Parameters
        ----------
        dy, dx : int
            Offset [px] of the block's top-left pixel from the pattern's, along rows and columns
            (only the parities matter).

        Returns
        -------
        MosaicLayout
            The same polarizers, rolled by (dy, dx), with the same ``pol45_toward``.

        """
        a = self.angles_deg
        return MosaicLayout(
            tuple(tuple(a[(r + dy) % 2][(c + dx) % 2] for c in range(2)) for r in range(2)),
            self.pol45_toward,
        )

    def stokes_weights(self) -> np.ndarray:
        """
        Return the Stokes weights of the four polarizers of one block.

        ``S1 = sum(w[..., 0] * I)`` and ``S2 = sum(w[..., 1] * I)`` over one block of four.

        Returns
        -------
        numpy.ndarray
            float32 (2, 2, 2): ``w[r, c] = (cos 2phi, sin 2phi)`` of the polarizer at (r, c), phi
            its camera-frame angle (from +x_cam towards +y_cam); exactly 0 or +-1.

        """
        phi = np.radians(self.camera_angles_deg)
        w = np.stack([np.cos(2 * phi), np.sin(2 * phi)], axis=-1)
        return np.rint(w).astype(np.float32)  # exactly 0 or +-1 for 0/45/90/135

    def describe(self) -> dict:
        """
        Return the layout as plain data for logs, JSON and diagnostics.

        Returns
        -------
        dict
            ``{"layout": [[deg, deg], [deg, deg]], "pol45_toward": "+x-y" | "+x+y"}``.

        """
        return {'layout': [list(r) for r in self.angles_deg], 'pol45_toward': self.pol45_toward}


def parse_layout(layout=IMX250MZR_LAYOUT, pol45_toward: str = IMX250MZR_POL45) -> MosaicLayout:
    """
    Validate a 2 x 2 layout holding 0, 45, 90, 135 once each, and the 45 deg direction.

    Parameters
    ----------
    layout : array_like of shape (2, 2) or MosaicLayout, default ((90, 45), (135, 0))
        Polarizer angles [deg] of the mosaic's top-left block, row by row; a
        :class:`MosaicLayout` is returned as it is.
    pol45_toward : {"+x-y", "+x+y"}, default "+x-y"
        Image direction of the 45 deg polarizer (see the module docstring).

    Returns
    -------
    MosaicLayout
        The validated layout, angles as int.

    Raises
    ------
    SensorError
        ``pol45_toward`` is neither value, the layout is not 2 x 2, holds an angle other than
        0/45/90/135 (or a bool), or does not hold each of them once.

    """
    if isinstance(layout, MosaicLayout):
        return layout
    if pol45_toward not in _POL45:
        raise SensorError(f"pol45_toward must be '+x+y' or '+x-y', got {pol45_toward!r}")
    try:
        rows = [list(r) for r in layout]
        ok_shape = len(rows) == 2 and all(len(r) == 2 for r in rows)
    except TypeError:
        ok_shape = False
    if not ok_shape:
        raise SensorError(
            f'mosaic layout must be 2 x 2, e.g. [[90, 45], [135, 0]], got {layout!r}'
        )
    vals = []
    for v in (x for r in rows for x in r):
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float, np.integer, np.floating))
            or v not in (0, 45, 90, 135)
        ):
            raise SensorError(f'mosaic layout angles must be 0, 45, 90 or 135 deg, got {v!r}')
        vals.append(int(v))
    if sorted(vals) != [0, 45, 90, 135]:
        raise SensorError(f'mosaic layout must hold 0, 45, 90 and 135 once each, got {rows}')
    return MosaicLayout(((vals[0], vals[1]), (vals[2], vals[3])), pol45_toward)


def layout_from_mapping(mosaic) -> MosaicLayout:
    """
    Return the layout of a ``mosaic`` mapping such as a scene's ``sensor.mosaic``.

    Also the form of a topic map's ``mosaic:`` entry.

    Parameters
    ----------
    mosaic : mapping or None
        ``layout`` (2 x 2 angles [deg]) and ``pol45_toward``, each defaulting to the IMX250MZR's
        when missing (None means both defaults).

    Returns
    -------
    MosaicLayout
        The validated layout (see :func:`parse_layout`, whose :class:`SensorError` propagates).

    """
    mos = mosaic or {}
    return parse_layout(
        mos.get('layout', IMX250MZR_LAYOUT), mos.get('pol45_toward', IMX250MZR_POL45)
    )


def _bilinear_weights(layout: MosaicLayout) -> np.ndarray:
    """
    Return the (2, 2, 8) float32 bilinear S1, S2 weights per pixel parity.

    For a pixel of parity (r, c), the S1 then S2 weights of the channel at the centre (r, c), the
    horizontal neighbours (r, 1-c), the vertical (1-r, c) and the diagonal (1-r, 1-c).
    """
    w = layout.stokes_weights()
    out = np.zeros((2, 2, 8), np.float32)
    for r in range(2):
        for c in range(2):
            roles = [(r, c), (r, 1 - c), (1 - r, c), (1 - r, 1 - c)]
            out[r, c, :4] = [w[y, x, 0] for y, x in roles]
            out[r, c, 4:] = [w[y, x, 1] for y, x in roles]
    return out


def _prepare(mosaic, saturation_level, read_once: bool = False):
    """
    Validate the raw image; float32 copy for the kernels and the float32 saturation threshold.

    ``read_once``: the kernel reads each sample once (superpixels), so an 8- or 16-bit unsigned
    image is passed as it is (the kernel converts each sample to float32 exactly as ``astype``
    would; the copy of a full 2448 x 2048 frame cost 2 ms, a third of the demosaic).
    """
    m = np.asarray(mosaic)
    if m.ndim != 2:
        raise SensorError(f'a mosaic must be a 2-D image, got shape {m.shape}')
    if m.dtype.kind not in 'uif' or m.dtype == np.float16:
        raise SensorError(
            f'mosaic dtype must be unsigned/signed integer, float32 or float64, got {m.dtype}'
        )
    if saturation_level is None:
        sat = float(np.iinfo(m.dtype).max) if m.dtype.kind in 'ui' else math.inf
    else:
        sat = float(saturation_level)
        if math.isnan(sat):
            raise SensorError('saturation_level must be a number, got NaN')
    if read_once and m.dtype in (np.uint8, np.uint16):
        return np.ascontiguousarray(m), np.float32(sat)
    if m.dtype != np.float32:
        # float32 holds every uint16 exactly; converting once is cheaper than converting 9x per
        # pixel. A float64 sample beyond float32's range becomes +-inf, which the kernels treat as
        # invalid.
        with np.errstate(over='ignore'):
            m = m.astype(np.float32)
    return np.ascontiguousarray(m), np.float32(sat)
