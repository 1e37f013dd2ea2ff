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
What the paper's figures share: their methods, labels and styles, and the map nodes they show.

The helpers of :mod:`polarization_compass.figures`: the matplotlib import (Agg backend), the
estimator classes' labels and styles, and picking the nodes of an error map's axes (a sun
altitude, a tilt, zero, a yaw node modulo 360, a full-turn yaw axis closed for plotting).
"""

from __future__ import annotations

import numpy as np

from ..errormap import ErrorMap, ErrorMapError
from ..estimators import registry

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
