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

from pathlib import Path

from . import curves, surfaces, tilts
from .axes import _plt
from ..errormap import ErrorMap, ErrorMapError

__all__ = ['FIGURES', 'draw_figure', 'save_figure', 'save_all']


FIGURES = {
    'fig7': surfaces.fig7,
    'fig8': curves.fig8,
    'fig9': curves.fig9,
    'fig10': surfaces.fig10,
    'fig11': surfaces.fig11,
    'fig12': curves.fig12,
    'fig13': curves.fig13,
    'fig14': tilts.fig14,
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
