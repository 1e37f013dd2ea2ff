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
The parameter type of every node and the checks its values go through (ROS-free).

One :class:`Param` per ROS parameter: name, default, description, range or choices, and whether it
may change while the node runs; :func:`validate_value` checks a value against it, the helpers the
checks of the node tables use (downstream lists, optical frame ids, ISO times, polarizer layouts).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable


@dataclass(frozen=True)
class Param:
    """
    Describe one node parameter.

    Parameters
    ----------
    name : str
        ROS parameter name, units in the name (e.g. ``latitude_deg``).
    default : bool, int, float, str or list
        Default value; its type decides the parameter's type (:attr:`kind`).
    description : str
        One-line meaning, shown by ``ros2 param describe`` and in docs/ros.md.
    lo, hi : float, optional
        Inclusive bounds of a number, in ``unit``.
    choices : tuple of str, default ()
        Allowed strings (for a string array: allowed items).
    read_only : bool, default False
        Fixed once the node runs (topics and graph wiring depend on it); otherwise a method knob
        that changes at run time.
    check : callable, optional
        Extra rule ``check(value) -> str | None`` returning an error message or None.
    unit : str, default ""
        Unit of a number for messages and docs (e.g. ``"deg"``).

    """

    name: str
    default: object
    description: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    read_only: bool = False
    check: Callable | None = field(default=None, compare=False)
    unit: str = ''

    @property
    def kind(self) -> str:
        """ROS type from the default: bool, int, float, str, str_list or float_list."""
        d = self.default
        if isinstance(d, bool):
            return 'bool'
        if isinstance(d, int):
            return 'int'
        if isinstance(d, float):
            return 'float'
        if isinstance(d, str):
            return 'str'
        if isinstance(d, (list, tuple)):
            return 'str_list' if all(isinstance(x, str) for x in d) else 'float_list'
        raise TypeError(f'parameter {self.name}: unsupported default {d!r}')


def validate_value(p: Param, value) -> str | None:
    """
    Return why ``value`` is not acceptable for ``p``, or None when it is.

    Parameters
    ----------
    p : Param
        The parameter's specification.
    value : object
        The proposed value (a ROS parameter value: bool, int, float, str or list).

    Returns
    -------
    str or None
        A one-line reason naming the parameter (type, finiteness, range with unit, choice, or the
        extra ``check``), or None when the value is acceptable.

    """
    k = p.kind
    if k == 'bool':
        if not isinstance(value, bool):
            return f'{p.name} must be true or false, got {value!r}'
        return p.check(value) if p.check else None
    if k in ('int', 'float'):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f'{p.name} must be a number, got {value!r}'
        if k == 'int' and not float(value).is_integer():
            return f'{p.name} must be an integer, got {value!r}'
        if not math.isfinite(float(value)):
            return f'{p.name} must be finite, got {value!r}'
        if p.lo is not None and value < p.lo or p.hi is not None and value > p.hi:
            return (
                f'{p.name} must be in [{p.lo}, {p.hi}]{" " + p.unit if p.unit else ""}, got '
                f'{value!r}'
            )
    elif k == 'str':
        if not isinstance(value, str):
            return f'{p.name} must be a string, got {value!r}'
        if p.choices and value not in p.choices:
            return f'{p.name} must be one of {", ".join(p.choices)}; got {value!r}'
    elif k == 'str_list':
        if not isinstance(value, (list, tuple)) or not all(isinstance(x, str) for x in value):
            return f'{p.name} must be a list of strings, got {value!r}'
        if p.choices:
            bad = [
                x for x in value if x and x not in p.choices
            ]  # "" = ROS's empty-array placeholder
            if bad:
                return f'{p.name}: unknown item(s) {bad}; allowed: {", ".join(p.choices)}'
    elif k == 'float_list':
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in value
        ):
            return f'{p.name} must be a list of finite numbers, got {value!r}'
    return p.check(value) if p.check else None


def parse_downstream(items) -> list[tuple[str, frozenset]]:
    """
    Parse ``wait_for_downstream`` entries into topics and the nodes to wait for.

    Parameters
    ----------
    items : iterable of str
        Entries ``"topic=node_a,node_b"``; empty strings are ignored.

    Returns
    -------
    list of tuple
        ``[(topic, frozenset of node names)]`` in the order given.

    Raises
    ------
    ValueError
        An entry without ``=``, a topic or at least one node name (the message quotes it).

    """
    out = []
    for item in items:
        if not item:
            continue
        topic, sep, names = item.rpartition('=')
        nodes = frozenset(x.strip() for x in names.split(',') if x.strip())
        if not sep or not topic or not nodes:
            raise ValueError(
                f"wait_for_downstream entries are 'topic=node[,node...]', got {item!r}"
            )
        out.append((topic, nodes))
    return out


def _downstream_problem(v):
    try:
        parse_downstream(v)
    except ValueError as exc:
        return str(exc)
    return None


def _not_optical(frame_id: str):
    if frame_id.endswith('_optical_frame') or frame_id.endswith('_optical'):
        return (
            f'frame_id {frame_id!r} is an optical frame (z forward): robot_localization needs a '
            'z-up '
            'frame with a TF to base_link, e.g. base_link'
        )
    if not frame_id:
        return 'frame_id must not be empty'
    return None


def _iso_or_empty(text: str):
    if text == '':
        return None
    from ...scene import parse_time_utc, SceneError

    try:
        parse_time_utc(text)
    except SceneError as exc:
        return str(exc)
    return None


def _layout_problem(text: str):
    try:
        vals = [int(x) for x in text.split(',')]
    except ValueError:
        return (
            'polarizer_layout must be four comma-separated angles such as 90,45,135,0, got '
            f'{text!r}'
        )
    if sorted(vals) != [0, 45, 90, 135]:
        return f'polarizer_layout must hold 0, 45, 90 and 135 once each, got {text!r}'
    return None


def layout_from_text(text: str):
    """
    Parse a ``polarizer_layout`` parameter into a 2 x 2 layout.

    Parameters
    ----------
    text : str
        Four comma-separated polarizer angles [deg], row by row, e.g. ``"90,45,135,0"``
        (validated beforehand by the parameter's check).

    Returns
    -------
    tuple of tuple of int
        ``((90, 45), (135, 0))`` for the example.

    """
    v = [int(x) for x in text.split(',')]
    return ((v[0], v[1]), (v[2], v[3]))
