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

"""The paper's figure 14: one method's error over pitch x roll at four yaws."""

from __future__ import annotations

import numpy as np

from .axes import _default_alt, _label, _need, _node, _plt, _yaw_node, SIGN_NOTE
from ..conventions import wrap_180_deg
from ..estimators import registry

__all__ = ['fig14']


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
