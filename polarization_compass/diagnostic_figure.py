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
The diagnostic figure of one image: what the compass saw and what it concluded (issue 25).

Draws a :class:`polarization_compass.sky_view.SkyView` with matplotlib's Agg canvas (no pyplot,
no display, safe in a node's thread): the AoP on a cyclic colour map with the fitted sun, anti-sun
and solar meridian and each method's sun azimuth (+- sigma); the DoP; the pixels used and each
mask by reason (own colour, legend with counts); the residual against the fitted sky; a compass
with each method's bearing and sigma; the status and reason of every method. :func:`save_figure`
writes a PNG (``estimate --plot``), :func:`figure_rgb` returns the picture as an RGB array. The
node's debug image and ``replay --plots-every`` use the fast renderer of the same layers,
:func:`polarization_compass.diagnostic_rgb.quick_rgb`.
"""

from __future__ import annotations

import math

import numpy as np

from .sky_view import CLASSES

__all__ = ['CLASS_COLOURS', 'figure_rgb', 'make_figure', 'save_figure']

#: colour (RGB, 0-1) of each class of :data:`polarization_compass.sky_view.CLASSES`
CLASS_COLOURS = (
    (0.55, 0.85, 0.45),  # used: green
    (0.80, 0.80, 0.80),  # not read: light grey
    (0.95, 0.55, 0.10),  # off the fitted sky: orange
    (0.35, 0.55, 0.95),  # low DoP: blue
    (0.35, 0.35, 0.35),  # no measurement: dark grey
    (0.85, 0.10, 0.75),  # IFOV: magenta
    (1.00, 0.90, 0.00),  # saturated sun + glare: yellow
    (0.85, 0.10, 0.10),  # user mask: red
    (0.00, 0.00, 0.00),  # outside: black
)
_METHOD_COLOURS = ('tab:red', 'tab:blue', 'tab:green', 'tab:purple', 'tab:brown', 'tab:cyan')


def make_figure(view, size_in=(13.0, 8.5), dpi=100):
    """
    Draw a view on a new Agg figure.

    Parameters
    ----------
    view : SkyView
        The layers (:mod:`polarization_compass.sky_view`).
    size_in : tuple of float, default (13, 8.5)
        Figure size [inch].
    dpi : float, default 100
        Dots per inch.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (with an Agg canvas).

    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size_in, dpi=dpi)
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(
        2, 3, left=0.04, right=0.98, top=0.88, bottom=0.04, wspace=0.3, hspace=0.3
    )
    _aop_panel(fig.add_subplot(gs[0, 0]), view)
    _dop_panel(fig.add_subplot(gs[0, 1]), view)
    _class_panel(fig.add_subplot(gs[0, 2]), view)
    _residual_panel(fig.add_subplot(gs[1, 0]), view)
    _compass_panel(fig.add_subplot(gs[1, 1], projection='polar'), view)
    _text_panel(fig.add_subplot(gs[1, 2]), view)
    fig.suptitle(_title(view), fontsize=11)
    return fig


def save_figure(view, path, dpi=100) -> None:
    """
    Write the figure of a view as a PNG.

    Parameters
    ----------
    view : SkyView
        The layers.
    path : str or os.PathLike
        Output file (.png).
    dpi : float, default 100
        Dots per inch (1300 x 850 pixels at 100).

    """
    make_figure(view, dpi=dpi).savefig(path, format='png')


def figure_rgb(view, width_px: int = 640) -> np.ndarray:
    """
    Render the figure of a view into an RGB array.

    Parameters
    ----------
    view : SkyView
        The layers.
    width_px : int, default 640
        Width of the picture [px] (the height follows the figure's 13 : 8.5).

    Returns
    -------
    numpy.ndarray
        uint8, shape (height, width, 3), C-contiguous.

    """
    fig = make_figure(view, dpi=width_px / 13.0)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    return np.ascontiguousarray(rgba[..., :3])


def _title(view) -> str:
    fit = view.fit
    head = view.label or 'image'
    if fit is None:
        worst = view.results[0] if view.results else None
        why = f'{worst.status.value}: {worst.reason}' if worst else 'no result'
        return f'{head}\nno heading: {_short(why, 110)}'
    sig = f' +- {fit.sigma_deg:.2g}' if fit.sigma_deg is not None else ''
    bearing = f'bearing {fit.bearing_deg:.1f}{sig} deg' if fit.bearing_deg is not None else ''
    return f'{head}\n{fit.method}: {fit.status.value} {bearing} -- {_short(fit.reason, 90)}'


def _short(text: str, n: int) -> str:
    text = str(text or '')
    return text if len(text) <= n else text[: n - 3] + '...'


def _image(ax, view, data, **kw):
    im = ax.imshow(data, extent=view.extent, interpolation='nearest', **kw)
    ax.set_xlim(view.extent[0], view.extent[1])
    ax.set_ylim(view.extent[2], view.extent[3])
    ax.tick_params(labelsize=7)
    return im


def _colourbar(ax, im, label):
    cb = ax.figure.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
    cb.ax.tick_params(labelsize=7)
    cb.set_label(label, fontsize=8)


def _aop_panel(ax, view) -> None:
    im = _image(ax, view, view.aop_deg, cmap='twilight', vmin=-90, vmax=90)
    _colourbar(ax, im, 'AoP [deg] (eq 28)')
    ax.set_title('AoP, fitted sun and solar meridian', fontsize=9)
    _geometry(ax, view, arrows=True)


def _dop_panel(ax, view) -> None:
    im = _image(ax, view, view.dop, cmap='viridis', vmin=0, vmax=max(0.1, _p99(view.dop)))
    _colourbar(ax, im, 'DoP')
    ax.set_title('DoP', fontsize=9)
    _geometry(ax, view, arrows=False)


def _p99(a) -> float:
    v = a[np.isfinite(a)]
    return float(np.percentile(v, 99)) if v.size else 1.0


def _class_panel(ax, view) -> None:
    rgb = np.asarray(CLASS_COLOURS)[view.classes]
    _image(ax, view, rgb)
    ax.set_title(f'pixels used and masked (1 cell = {view.step} x {view.step})', fontsize=9)
    _geometry(ax, view, arrows=False)


def _class_legend(ax, view) -> int:
    """Put the classes' legend (full-resolution counts) at the top of ``ax``; return its rows."""
    from matplotlib.patches import Patch

    handles = [
        Patch(color=CLASS_COLOURS[i], label=f'{CLASSES[i]}: {n}')
        for i, n in enumerate(view.counts)
        if n or i == 0
    ]
    ax.legend(
        handles=handles,
        fontsize=7,
        loc='upper left',
        bbox_to_anchor=(0.0, 1.02),
        frameon=False,
        title='pixels (full resolution)',
        title_fontsize=7,
    )
    return len(handles) + 1


def _residual_panel(ax, view) -> None:
    who = '' if view.fit is None else f' (sun of {view.fit.method})'
    ax.set_title(f'AoP minus fitted sky{who} [deg]', fontsize=9)
    if view.residual_deg is None:
        _image(ax, view, np.full(view.classes.shape, np.nan))
        ax.text(
            0.5,
            0.5,
            'no fit (no result with a heading)',
            transform=ax.transAxes,
            ha='center',
            va='center',
            fontsize=9,
        )
        return
    res = view.residual_deg[: view.classes.shape[0], : view.classes.shape[1]]
    im = _image(ax, view, res, cmap='coolwarm', vmin=-30, vmax=30)
    _colourbar(ax, im, 'residual [deg], |r| > 15: off the sky')
    _geometry(ax, view, arrows=False)


def _geometry(ax, view, arrows: bool) -> None:
    """Draw the solar meridian, the fitted sun and anti-sun, and (``arrows``) each method's sun."""
    if view.meridian_px is not None:
        x, y = view.meridian_px
        half = x.size // 2
        ax.plot(x[: half + 1], y[: half + 1], '-', color='gold', lw=1.5)
        ax.plot(x[half:], y[half:], '--', color='white', lw=1.2)
    kw = {'ms': 13, 'mec': 'black', 'mew': 1.2, 'ls': 'none'}
    if view.sun_px is not None:
        ax.plot(*view.sun_px, marker='*', mfc='gold', label='fitted sun', **kw)
    if view.antisun_px is not None:
        ax.plot(*view.antisun_px, marker='X', mfc='white', label='anti-sun', **kw)
    if arrows:
        _sun_arrows(ax, view)


def _sun_arrows(ax, view) -> None:
    """Arrow per method from the principal point to its sun's azimuth, with a +-sigma wedge."""
    from matplotlib.patches import Wedge

    x0, x1, y1, y0 = view.extent
    length = 0.42 * min(abs(x1 - x0), abs(y1 - y0))
    cx, cy = view.centre_px
    for i, r in enumerate(view.results):
        d = view.sun_dir_img.get(r.method)
        if d is None:
            continue
        c = _METHOD_COLOURS[i % len(_METHOD_COLOURS)]
        ang = math.degrees(math.atan2(d[1], d[0]))
        sig = min(float(r.sigma_deg or 0.0), 90.0)
        if sig > 0:
            ax.add_patch(Wedge((cx, cy), length, ang - sig, ang + sig, color=c, alpha=0.25, lw=0))
        ls = '-' if r.ok else ':'
        ax.annotate(
            '',
            xy=(cx + length * d[0], cy + length * d[1]),
            xytext=(cx, cy),
            arrowprops={'arrowstyle': '->', 'color': c, 'lw': 1.8, 'ls': ls},
        )
        ax.plot([], [], color=c, ls=ls, label=f'{r.method} sun azimuth')
    if view.sun_dir_img:
        ax.legend(fontsize=6, loc='lower left', framealpha=0.7)


def _compass_panel(ax, view) -> None:
    """Each method's bearing of camera +y (clockwise from North) with its +-sigma sector."""
    ax.set_theta_zero_location('N')
    ax.set_theta_direction(-1)
    ax.set_yticks([])
    ax.set_ylim(0, 1.05)
    ax.tick_params(labelsize=7)
    ax.set_title('bearing of camera +y (from North) +- sigma', fontsize=9, pad=14)
    for i, r in enumerate(view.results):
        if r.bearing_deg is None or not math.isfinite(r.bearing_deg):
            continue
        c = _METHOD_COLOURS[i % len(_METHOD_COLOURS)]
        b = math.radians(r.bearing_deg)
        ls = '-' if r.ok else ':'
        ends = (b, b + math.pi) if r.axial else (b,)
        for e in ends:
            ax.plot([e, e], [0, 1], color=c, lw=2, ls=ls)
            sig = math.radians(min(float(r.sigma_deg or 0.0), 90.0))
            if sig > 0:
                t = np.linspace(e - sig, e + sig, 30)
                ax.fill_between(t, 0, 1, color=c, alpha=0.2, lw=0)
        ax.plot([], [], color=c, ls=ls, lw=2, label=r.method)
    if ax.lines:
        ax.legend(fontsize=6, loc='upper left', bbox_to_anchor=(1.0, 1.1), frameon=False)


def _text_panel(ax, view) -> None:
    """Each method's status, bearing, sigma and reason; what the geometry shows and omits."""
    import textwrap

    ax.axis('off')
    rows = _class_legend(ax, view)
    lines = []
    reason_lines = 2 if len(view.results) <= 3 else 1
    for r in view.results:
        b = '--' if r.bearing_deg is None else f'{r.bearing_deg:.1f}'
        s = '' if r.sigma_deg is None else f' +- {r.sigma_deg:.2g}'
        lines.append(f'{r.method}: {r.status.value}, bearing {b}{s} deg, {r.pixels} px')
        lines += textwrap.wrap(
            str(r.reason or ''),
            56,
            initial_indent='   ',
            subsequent_indent='   ',
            max_lines=reason_lines,
        )
    lines.append('')
    lines.append('white in the maps: no measurement or masked')
    if view.fit is not None and view.sun_px is None:
        lines.append('the fitted sun is outside the image')
    ax.text(
        0.0,
        1.0 - 0.068 * rows,
        '\n'.join(lines),
        transform=ax.transAxes,
        va='top',
        ha='left',
        fontsize=6.5,
        family='monospace',
    )
