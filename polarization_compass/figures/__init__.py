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
The paper's figures 7-14, drawn from an error map (matplotlib, Agg backend).

==========  ==================================================================================
``fig7``    pitch only (roll 0): error surface over yaw x pitch, one panel per method
``fig8``    pitch only: the methods' error curves over yaw on one plot, for every sun altitude
``fig9``    pitch only, one sun altitude and pitch (enlarged): the curves, and each method minus
            the methods' mean (how far apart they are)
``fig10``   roll only (pitch 0): error surface over yaw x roll, yaw in [-180, 180]
``fig11``   as fig10 with yaw shown over [-90, 270] (the paper's shift for comparison with fig7)
``fig12``   roll only: the methods' curves for every sun altitude
``fig13``   roll only, one sun altitude and roll, with the pitch-only curve (pitch = roll) shifted
            by +90 deg of yaw (eq 32)
``fig14``   pitch and roll: one method's error over pitch x roll at four yaws (|pitch|+|roll| <=
            30)
==========  ==================================================================================

Errors are ``fold(estimated psi - true psi)`` in degrees, with this project's eq 21 sign (README).
Cells without a valid estimate are left blank, never drawn as zero.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..conventions import wrap_180_deg
from ..errormap import ErrorMap, ErrorMapError
from ..estimators import registry

__all__ = ['FIGURES', 'draw_figure', 'save_figure', 'save_all']

SIGN_NOTE = 'error = estimated psi - true psi, folded to (-90, 90]'


def _plt():
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def _label(m):
    """Return the estimator class's ``label`` (the name for a method this build does not have)."""
    return registry.label(m)


def _style(m, k):
    """Return the estimator class's ``style``, else the ``k``-th colour of matplotlib's cycle."""
    return registry.style(m) or (f'C{k % 10}', '-')


def _methods(m: ErrorMap, wanted=None) -> list[str]:
    if wanted:
        for w in wanted:
            m.method_index(w)
        return list(wanted)
    paper = [x for x in registry.paper_methods() if x in m.methods]
    return paper if paper else list(m.methods)


def _node(axis, value, name, default=None):
    """
    Return the index of the node nearest ``value`` (or the ``default`` picker's).

    The value must be within 1e-6 of a node.
    """
    if value is None:
        value = default(axis) if default else axis[-1]
    return ErrorMap.axis_index(axis, float(value), name)


def _zero(axis, name):
    if not np.any(np.abs(axis) < 1e-9):
        raise ErrorMapError(f"this figure needs {name} = 0 on the map's {name} axis")
    return int(np.argmin(np.abs(axis)))


def _need(axis, name, n=2):
    if axis.size < n:
        raise ErrorMapError(f"this figure needs at least {n} nodes on the map's {name} axis")


def _default_alt(axis):
    """Return the highest sun altitude <= 50 deg (the paper's range), else the highest."""
    sel = axis[axis <= 50 + 1e-9]
    return float(sel[-1] if sel.size else axis[-1])


def _default_tilt(axis):
    """-20 deg if on the axis (the paper's field experiment), else the largest |value|."""
    if np.any(np.abs(axis + 20) < 1e-9):
        return -20.0
    return float(axis[np.argmax(np.abs(axis))])


def _masked(m: ErrorMap, i, sl):
    e = m.error_deg[i][sl]
    v = m.valid[i][sl]
    return np.ma.masked_array(e, ~v)


def _closed_yaw(m: ErrorMap):
    """
    Return yaw values and node indices that close a full-turn axis for plotting.

    A full-turn axis without its end node gets it back (-180 repeated at +180), so curves and
    surfaces close.
    """
    y = m.yaw_deg
    idx = np.arange(y.size)
    if y.size > 2:
        step = y[1] - y[0]
        if np.allclose(np.diff(y), step) and abs(y[-1] + step - (y[0] + 360.0)) < 1e-6:
            return np.append(y, y[0] + 360.0), np.append(idx, 0)
    return y.copy(), idx


def _yaw_node(axis, y):
    """Index of the yaw node equal to y modulo 360."""
    for cand in (y, y - 360.0, y + 360.0):
        j = int(np.argmin(np.abs(axis - cand)))
        if abs(axis[j] - cand) <= 1e-6:
            return j
    raise ErrorMapError(f"yaw {y:g} is not a node of the map's yaw axis")


def _yaw_ticks(ax, lo=-180, hi=180, step=45):
    ax.set_xticks(np.arange(lo, hi + 1, step))


# --------------------------------------------------------------------------------------------
# Surfaces (figs 7, 10, 11)
# --------------------------------------------------------------------------------------------
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


# --------------------------------------------------------------------------------------------
# Curves (figs 8, 9, 12, 13)
# --------------------------------------------------------------------------------------------
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


# --------------------------------------------------------------------------------------------
# Pitch and roll (fig 14)
# --------------------------------------------------------------------------------------------
def fig14(m, opts):
    """
    Draw the paper's Fig 14: one method's error over pitch x roll at four yaws.

    Cells outside |pitch| + |roll| <= the map's tilt limit (30 deg) are blank; the diamond
    marks the limit.

    Parameters
    ----------
    m : ErrorMap
        The error map (errors [deg], ``fold(estimated psi - true psi)``; invalid cells blank).
    opts : dict
        ``method`` (default the first paper method in the map: zenith, as in the paper),
        ``sun_altitude`` (deg; default the highest node <= 50 deg) and ``yaws`` (four yaw nodes
        [deg]; default the nodes nearest -135, -45, 45 and 135 deg).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (Agg backend); the caller saves and closes it.

    Raises
    ------
    ErrorMapError
        Through its helpers: the map has fewer than 2 pitch or roll nodes, or a yaw in ``yaws``
        is not a node.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), section 3.3, Fig 14.

    """
    plt = _plt()
    # the paper's fig 14 shows its first approach (zenith)
    method = opts.get('method') or next(
        (x for x in registry.paper_methods() if x in m.methods), m.methods[0]
    )
    i = m.method_index(method)
    ia = _node(m.sun_altitude_deg, opts.get('sun_altitude'), 'sun altitude', _default_alt)
    _need(m.pitch_deg, 'pitch', 2)
    _need(m.roll_deg, 'roll', 2)
    if opts.get('yaws'):
        iy = [_yaw_node(m.yaw_deg, float(y)) for y in opts['yaws']]
    else:  # the nodes nearest -135, -45, 45, 135 deg
        iy = [
            int(np.argmin(np.abs(wrap_180_deg(m.yaw_deg - y))))
            for y in (-135.0, -45.0, 45.0, 135.0)
        ]
    yaws = [float(m.yaw_deg[k]) for k in iy]
    limit = (
        float(m.meta.get('domain', {}).get('tilt_limit_deg', 30.0))
        if isinstance(m.meta, dict)
        else 30.0
    )
    P, R = np.meshgrid(m.pitch_deg, m.roll_deg, indexing='ij')
    domain = (np.abs(P) + np.abs(R)) <= limit + 1e-9
    panels = [np.ma.masked_array(m.error_deg[i, ia, k], ~(m.valid[i, ia, k] & domain)) for k in iy]
    lim = max(float(np.abs(p).max()) if p.count() else 0.0 for p in panels) or 1.0
    fig, axes = plt.subplots(2, 2, figsize=(10.5, 9.2), dpi=110, layout='constrained')
    dp = np.diff(m.pitch_deg).min() if m.pitch_deg.size > 1 else 1.0
    dr = np.diff(m.roll_deg).min() if m.roll_deg.size > 1 else 1.0
    extent = (
        m.roll_deg[0] - dr / 2,
        m.roll_deg[-1] + dr / 2,
        m.pitch_deg[0] - dp / 2,
        m.pitch_deg[-1] + dp / 2,
    )
    cm = plt.get_cmap('coolwarm').with_extremes(bad='0.92')
    for ax, k, data, y in zip(axes.flat, iy, panels, yaws):
        im = ax.imshow(
            data,
            origin='lower',
            extent=extent,
            cmap=cm,
            vmin=-lim,
            vmax=lim,
            aspect='equal',
            interpolation='nearest',
        )
        ax.plot([0, limit, 0, -limit, 0], [limit, 0, -limit, 0, limit], color='k', lw=0.8)
        if data.count() and (m.pitch_deg.size * m.roll_deg.size) <= 400:
            for a in range(m.pitch_deg.size):
                for b in range(m.roll_deg.size):
                    if not np.ma.is_masked(data[a, b]):
                        ax.text(
                            m.roll_deg[b],
                            m.pitch_deg[a],
                            f'{data[a, b]:.0f}',
                            ha='center',
                            va='center',
                            fontsize=6,
                        )
        ax.set_title(f'yaw psi = {m.yaw_deg[k]:g} deg', fontsize=10)
        ax.set_xlabel('roll (deg)')
        ax.set_ylabel('pitch (deg)')
    fig.colorbar(im, ax=axes, shrink=0.85, label='heading error (deg)')
    fig.suptitle(
        f'{_label(method)} approach under pitch and roll (|pitch| + |roll| <= {limit:g} deg), sun '
        'altitude '
        f'{m.sun_altitude_deg[ia]:g} deg\n{SIGN_NOTE}; numbers: error at each node',
        fontsize=11,
    )
    return fig


FIGURES = {
    'fig7': fig7,
    'fig8': fig8,
    'fig9': fig9,
    'fig10': fig10,
    'fig11': fig11,
    'fig12': fig12,
    'fig13': fig13,
    'fig14': fig14,
}


def draw_figure(m: ErrorMap, name: str, **opts):
    """
    Draw one of the paper's figures from an error map.

    Parameters
    ----------
    m : ErrorMap
        The error map.
    name : str
        A key of :data:`FIGURES` (``"fig7"`` ... ``"fig14"``).
    **opts
        The figure's options (see each ``figN``).

    Returns
    -------
    matplotlib.figure.Figure
        The figure; the caller saves and closes it.

    Raises
    ------
    ErrorMapError
        Unknown figure name (or, from the figure, a map without the nodes it needs).

    """
    if name not in FIGURES:
        raise ErrorMapError(f'unknown figure {name!r}; known: {", ".join(FIGURES)} (or all)')
    return FIGURES[name](m, opts)


def save_figure(m: ErrorMap, name: str, out, **opts) -> Path:
    """
    Draw one figure and save it.

    Parameters
    ----------
    m : ErrorMap
        The error map.
    name : str
        A key of :data:`FIGURES`.
    out : str or os.PathLike
        Output image (format from the suffix); its directory is created.
    **opts
        The figure's options.

    Returns
    -------
    pathlib.Path
        The file written.

    """
    plt = _plt()
    fig = draw_figure(m, name, **opts)
    p = Path(out)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p)
    plt.close(fig)
    return p


def save_all(m: ErrorMap, out_dir, **opts) -> list[Path]:
    """
    Save every figure into ``out_dir/figN.png``.

    Parameters
    ----------
    m : ErrorMap
        The error map.
    out_dir : str or os.PathLike
        Output directory (created).
    **opts
        Options passed to every figure.

    Returns
    -------
    list of pathlib.Path
        The files written, in :data:`FIGURES` order.

    """
    return [save_figure(m, name, Path(out_dir) / f'{name}.png', **opts) for name in FIGURES]
