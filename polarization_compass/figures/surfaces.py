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

"""The paper's error surfaces over yaw x tilt: figures 7 (pitch), 10 and 11 (roll)."""

from __future__ import annotations

import math

import numpy as np

from .axes import (
    _closed_yaw,
    _default_alt,
    _label,
    _masked,
    _methods,
    _need,
    _node,
    _plt,
    _yaw_ticks,
    _zero,
    SIGN_NOTE,
)
from ..errormap import ErrorMap

__all__ = ['fig7', 'fig10', 'fig11']


def _surfaces(m: ErrorMap, tilt: str, opts, shift=False):
    plt = _plt()
    methods = _methods(m, opts.get('methods'))
    ia = _node(m.sun_altitude_deg, opts.get('sun_altitude'), 'sun altitude', _default_alt)
    _need(m.yaw_deg, 'yaw', 3)
    if tilt == 'pitch':
        ir = _zero(m.roll_deg, 'roll')
        _need(m.pitch_deg, 'pitch', 2)
        tilt_axis = m.pitch_deg
        index = (ia, slice(None), slice(None), ir)  # (yaw, pitch)
    else:
        ip = _zero(m.pitch_deg, 'pitch')
        _need(m.roll_deg, 'roll', 2)
        tilt_axis = m.roll_deg
        index = (ia, slice(None), ip, slice(None))  # (yaw, roll)
    yaw, order = _closed_yaw(m)
    if shift:  # show yaw over [-90, 270]: nodes <= -90 move up a turn
        up = np.nonzero(yaw <= -90 + 1e-9)[0]
        keep_lo = np.nonzero(yaw >= -90 - 1e-9)[0]
        order = np.concatenate([order[keep_lo], order[up]])
        yaw = np.concatenate([yaw[keep_lo], yaw[up] + 360.0])
        keep = np.concatenate([[True], np.diff(yaw) > 1e-9])
        order, yaw = order[keep], yaw[keep]
    n = len(methods)
    cols = 2 if n > 1 else 1
    rows = int(math.ceil(n / cols))
    fig = plt.figure(figsize=(max(8.0, 6.2 * cols), 5.3 * rows + 0.6), dpi=110)
    data = [_masked(m, m.method_index(x), index)[order] for x in methods]
    lim = max(float(np.abs(d).max()) if d.count() else 0.0 for d in data) or 1.0
    Y, T = np.meshgrid(yaw, tilt_axis, indexing='ij')
    for k, (name, d) in enumerate(zip(methods, data)):
        ax = fig.add_subplot(rows, cols, k + 1, projection='3d')
        surf = ax.plot_surface(
            Y,
            T,
            d.filled(np.nan),
            cmap='coolwarm',
            vmin=-lim,
            vmax=lim,
            rstride=1,
            cstride=1,
            linewidth=0.1,
            edgecolor='0.4',
            antialiased=True,
        )
        ax.set_xlabel('yaw psi (deg)', labelpad=6)
        ax.set_ylabel(f'{tilt} (deg)', labelpad=6)
        ax.set_zlabel('heading error (deg)', labelpad=6)
        ax.set_zlim(-lim, lim)
        _yaw_ticks(ax, -90 if shift else -180, 270 if shift else 180, step=90)
        ax.set_title(f'({chr(97 + k)}) {_label(name)}', fontsize=11)
        ax.view_init(elev=28, azim=-58)
        fig.colorbar(surf, ax=ax, shrink=0.55, pad=0.12)
    other = 'roll' if tilt == 'pitch' else 'pitch'
    fig.suptitle(
        f'Heading error under {tilt} only ({other} = 0), sun altitude {m.sun_altitude_deg[ia]:g} '
        'deg'
        + ('\nyaw shown over [-90, 270] (compare with fig 7)' if shift else '')
        + f'\n{SIGN_NOTE}',
        fontsize=11,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.93), h_pad=2.5)
    return fig


def fig7(m, opts):
    """
    Draw the paper's Fig 7: error surfaces over yaw x pitch (roll 0), one per method.

    Pitch only: one 3-D panel per method at one sun altitude.

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods`` (list of str, default the paper's methods in the map) and ``sun_altitude``
        (deg, a node of the map; default the highest node <= 50 deg).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (Agg backend); the caller saves and closes it.

    Raises
    ------
    ErrorMapError
        Through its helpers: the map lacks the nodes the figure needs (e.g. pitch 0 or roll 0, or
        fewer than 2-3 nodes on an axis).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3.1, Fig 7.

    """
    return _surfaces(m, 'pitch', opts)


def fig10(m, opts):
    """
    Draw the paper's Fig 10: error surfaces over yaw x roll (pitch 0), one per method.

    Roll only, yaw over [-180, 180].

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods`` (list of str, default the paper's methods in the map) and ``sun_altitude``
        (deg, a node of the map; default the highest node <= 50 deg).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (Agg backend); the caller saves and closes it.

    Raises
    ------
    ErrorMapError
        Through its helpers: the map lacks the nodes the figure needs (e.g. pitch 0 or roll 0, or
        fewer than 2-3 nodes on an axis).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3.2, Fig 10.

    """
    return _surfaces(m, 'roll', opts)


def fig11(m, opts):
    """
    Draw the paper's Fig 11: Fig 10 with yaw shown over [-90, 270].

    The paper's shift for comparison with Fig 7.

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods`` (list of str, default the paper's methods in the map) and ``sun_altitude``
        (deg, a node of the map; default the highest node <= 50 deg).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (Agg backend); the caller saves and closes it.

    Raises
    ------
    ErrorMapError
        Through its helpers: the map lacks the nodes the figure needs (e.g. pitch 0 or roll 0, or
        fewer than 2-3 nodes on an axis).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3.2, Fig 11.

    """
    return _surfaces(m, 'roll', opts, shift=True)
