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

"""The paper's error curves over yaw: figures 8 and 12 (every sun altitude), 9 and 13 (zoomed)."""

from __future__ import annotations

import numpy as np

from .axes import (
    _closed_yaw,
    _default_alt,
    _default_tilt,
    _label,
    _masked,
    _methods,
    _need,
    _node,
    _plt,
    _style,
    _yaw_ticks,
    _zero,
    SIGN_NOTE,
)
from ..conventions import wrap_180_deg
from ..errormap import ErrorMap

__all__ = ['fig8', 'fig9', 'fig12', 'fig13']


def _curve(m, name, ia, tilt, it):
    """Return the error over the closed yaw axis (see :func:`_closed_yaw`)."""
    i = m.method_index(name)
    _, order = _closed_yaw(m)
    if tilt == 'pitch':
        return _masked(m, i, (ia, slice(None), it, _zero(m.roll_deg, 'roll')))[order]
    return _masked(m, i, (ia, slice(None), _zero(m.pitch_deg, 'pitch'), it))[order]


def _all_altitude_curves(m: ErrorMap, tilt: str, opts):
    plt = _plt()
    methods = _methods(m, opts.get('methods'))
    axis = m.pitch_deg if tilt == 'pitch' else m.roll_deg
    it = _node(axis, opts.get(tilt), tilt, _default_tilt)
    _need(m.yaw_deg, 'yaw', 3)
    fig, ax = plt.subplots(figsize=(10, 6.4), dpi=110, layout='constrained')
    cmap = plt.get_cmap('viridis')
    alts = m.sun_altitude_deg
    for ia, h in enumerate(alts):
        colour = cmap(ia / max(1, alts.size - 1))
        for k, name in enumerate(methods):
            ls = _style(name, k)[1]
            ax.plot(_closed_yaw(m)[0], _curve(m, name, ia, tilt, it), color=colour, ls=ls, lw=1.3)
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], color='k', ls=_style(n, k)[1], label=_label(n))
        for k, n in enumerate(methods)
    ]
    ax.legend(
        handles=handles,
        loc='upper center',
        bbox_to_anchor=(0.5, -0.1),
        ncol=len(handles),
        fontsize=9,
        title='method (line style)',
        frameon=False,
    )
    sm = plt.cm.ScalarMappable(
        cmap=cmap, norm=plt.Normalize(alts.min(), alts.max() if alts.size > 1 else alts.min() + 1)
    )
    fig.colorbar(sm, ax=ax, label='sun altitude (deg)')
    ax.axhline(0, color='0.6', lw=0.6)
    ax.set_xlim(_closed_yaw(m)[0][0], _closed_yaw(m)[0][-1])
    _yaw_ticks(ax)
    ax.set_xlabel('yaw psi (deg)')
    ax.set_ylabel('heading error (deg)')
    ax.grid(alpha=0.3)
    ax.set_title(
        f"{tilt.capitalize()} only, {tilt} = {axis[it]:g} deg: the methods' error curves for "
        'every sun '
        f'altitude\n{SIGN_NOTE}',
        fontsize=11,
    )
    return fig


def fig8(m, opts):
    """
    Draw the paper's Fig 8: the methods' error curves over yaw for every sun altitude.

    Pitch only (roll 0), at one pitch; colour by sun altitude, line style by method.

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods`` and ``pitch`` (deg, a node of the map; default -20 if a node, else the largest
        |pitch|).

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
       Polarized Skylight Orientation Determination" (the seed paper), section 3.1, Fig 8.

    """
    return _all_altitude_curves(m, 'pitch', opts)


def fig12(m, opts):
    """
    Draw the paper's Fig 12: the methods' error curves over yaw for every sun altitude.

    Roll only (pitch 0), at one roll; colour by sun altitude, line style by method.

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods`` and ``roll`` (deg, a node of the map; default -20 if a node, else the largest
        |roll|).

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
       Polarized Skylight Orientation Determination" (the seed paper), section 3.2, Fig 12.

    """
    return _all_altitude_curves(m, 'roll', opts)


def _zoom_curves(m: ErrorMap, tilt: str, opts, with_pitch_shift=False):
    plt = _plt()
    methods = _methods(m, opts.get('methods'))
    axis = m.pitch_deg if tilt == 'pitch' else m.roll_deg
    it = _node(axis, opts.get(tilt), tilt, _default_tilt)
    ia = _node(m.sun_altitude_deg, opts.get('sun_altitude'), 'sun altitude', _default_alt)
    fig, (ax, ax2) = plt.subplots(
        2, 1, figsize=(10, 7.5), dpi=110, sharex=True, gridspec_kw={'height_ratios': [2.2, 1]}
    )
    curves = []
    for k, name in enumerate(methods):
        c = _curve(m, name, ia, tilt, it)
        curves.append(c)
        colour, ls = _style(name, k)
        ax.plot(_closed_yaw(m)[0], c, color=colour, ls=ls, lw=1.8, label=_label(name))
    if with_pitch_shift:
        ipitch = ErrorMap.axis_index(m.pitch_deg, float(axis[it]), 'pitch')
        name = methods[-1]
        c = _curve(m, name, ia, 'pitch', ipitch)
        shifted = np.asarray(wrap_180_deg(_closed_yaw(m)[0] + 90.0))
        order = np.argsort(shifted, kind='stable')
        ax.plot(
            shifted[order],
            c[order],
            color='k',
            lw=1.0,
            marker='o',
            ms=2.5,
            ls='none',
            label=f'Only pitch (pitch = {axis[it]:g}, {_label(name)}), yaw + 90',
        )
    stack = np.ma.stack(curves)
    mean = stack.mean(axis=0)
    for k, (name, c) in enumerate(zip(methods, curves)):
        colour, ls = _style(name, k)
        ax2.plot(_closed_yaw(m)[0], c - mean, color=colour, ls=ls, lw=1.5, label=_label(name))
    spread = float((stack.max(axis=0) - stack.min(axis=0)).max()) if stack.count() else 0.0
    ax.axhline(0, color='0.6', lw=0.6)
    ax2.axhline(0, color='0.6', lw=0.6)
    ax.set_ylabel('heading error (deg)')
    ax2.set_ylabel('method - mean (deg)')
    ax2.set_xlabel('yaw psi (deg)')
    ax2.set_xlim(_closed_yaw(m)[0][0], _closed_yaw(m)[0][-1])
    _yaw_ticks(ax2)
    ax.grid(alpha=0.3)
    ax2.grid(alpha=0.3)
    ax.legend(fontsize=9, loc='best')
    ax2.set_title(
        f'largest difference between methods on this curve: {spread:.2g} deg', fontsize=10
    )
    other = 'roll' if tilt == 'pitch' else 'pitch'
    ax.set_title(
        f'{tilt.capitalize()} only ({other} = 0), {tilt} = {axis[it]:g} deg, sun altitude '
        f'{m.sun_altitude_deg[ia]:g} deg\n{SIGN_NOTE}',
        fontsize=11,
    )
    fig.tight_layout()
    return fig


def fig9(m, opts):
    """
    Draw the paper's Fig 9: the methods' curves at one sun altitude and pitch, enlarged.

    Below: each method minus the methods' mean (how far apart they are).

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods``, ``pitch`` (deg; default -20 if a node, else the largest |pitch|) and
        ``sun_altitude`` (deg; default the highest node <= 50 deg).

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
       Polarized Skylight Orientation Determination" (the seed paper), section 3.1, Fig 9.

    """
    return _zoom_curves(m, 'pitch', opts)


def fig13(m, opts):
    """
    Draw the paper's Fig 13: the roll-only curves with the pitch-only curve shifted.

    At one sun altitude and roll; the pitch-only curve (pitch = roll) is shifted by +90 deg of
    yaw (eq 32). Below: each method minus the methods' mean.

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``methods``, ``roll`` (deg; default -20 if a node, else the largest |roll|) and
        ``sun_altitude`` (deg; default the highest node <= 50 deg).

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
       Polarized Skylight Orientation Determination" (the seed paper), section 3.2, eq 32 and
       Fig 13.

    """
    return _zoom_curves(m, 'roll', opts, with_pitch_shift=True)
