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
Viewable images of frames (matplotlib, Agg backend).

The module is imported only when a picture is asked for.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def save_frame_pngs(frame, out_dir) -> list[Path]:
    """
    Write ``aop.png`` and ``dop.png`` of a rendered frame, with colour bars.

    AoP in degrees on a cyclic colour map (eq 28: from +y_cam towards +x_cam, [-90, 90]), DoP in
    [0, 1]; pixels without sky (``valid`` False) are grey. The title gives the sun and attitude.

    Parameters
    ----------
    frame : Frame
        A rendered frame on a 2-D pixel grid: ``aop_rad``, ``dop``, ``valid``, ``x_px``,
        ``y_px`` and ``meta`` (sun azimuth/altitude, bearing, pitch, roll [deg]).
    out_dir : str or os.PathLike
        Output directory (created).

    Returns
    -------
    list of pathlib.Path
        The two files, AoP first.

    Raises
    ------
    ValueError
        The frame's pixels are not a 2-D grid (a ring or list selection).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28 and Fig 5.

    """
    plt = _plt()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    aop = np.degrees(frame.aop_rad.astype(float))
    dop = frame.dop.astype(float)
    if aop.ndim != 2:
        raise ValueError(
            'PNG output needs a 2-D pixel grid (full, stride, grid or region selection)'
        )
    m = frame.meta
    title = (
        f'sun az {m["sun_azimuth_deg"]:.1f} deg, alt {m["sun_altitude_deg"]:.1f} deg; '
        f'bearing {m["bearing_deg"]:.1f}, pitch {m["pitch_deg"]:.1f}, roll {m["roll_deg"]:.1f} deg'
    )
    paths = []
    for name, img, cmap, lo, hi, label in (
        ('aop', aop, 'twilight', -90, 90, 'AoP (eq 28: from +y_cam toward +x_cam), deg'),
        ('dop', dop, 'viridis', 0, 1, 'DoP'),
    ):
        fig, ax = plt.subplots(figsize=(7.2, 5.6), dpi=110)
        shown = np.ma.masked_where(~frame.valid, img)
        cm = plt.get_cmap(cmap).with_extremes(bad='0.6')  # set_bad on a copy is deprecated
        x0, x1 = float(frame.x_px.min()), float(frame.x_px.max())
        y0, y1 = float(frame.y_px.min()), float(frame.y_px.max())
        im = ax.imshow(
            shown,
            cmap=cm,
            vmin=lo,
            vmax=hi,
            extent=(x0 - 0.5, x1 + 0.5, y1 + 0.5, y0 - 0.5),
            interpolation='nearest',
        )
        ax.set_xlabel('column x_px (camera +x)')
        ax.set_ylabel('row y_px (camera +y)')
        ax.set_title(title, fontsize=8)
        fig.colorbar(im, ax=ax, label=label)
        fig.tight_layout()
        p = out / f'{name}.png'
        fig.savefig(p)
        plt.close(fig)
        paths.append(p)
    return paths
