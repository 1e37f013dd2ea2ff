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
ROS 2 (rclpy) glue for :mod:`polarization_compass.specs.params`: declared and validated parameters.

Every parameter is declared with a descriptor (description, range, read-only flag) and every
change is validated with a reason.

Bad values are rejected twice over: rclpy enforces ``FloatingPointRange``/``IntegerRange`` and
``read_only`` itself, and the on-set-parameters callback checks choices, types and the extra rules
of :class:`~polarization_compass.specs.params.Param` (the reason comes back to ``ros2 param set``
as the failure message).
Any exception of the node's ``on_change`` (a file the new value names that cannot be read, ...)
refuses the change with its reason and keeps the old value: a parameter set never ends a node. A
bad value in a parameter file stops the node at start with a one-line :class:`ParameterError`.
"""

from __future__ import annotations

from typing import Callable

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterException,
)
from rclpy.parameter import Parameter

from ..errors import CompassError
from ..specs.params import Param, spec_by_name, validate_value

__all__ = ['ParameterError', 'ParameterSet']

_TYPES = {
    'bool': Parameter.Type.BOOL,
    'int': Parameter.Type.INTEGER,
    'float': Parameter.Type.DOUBLE,
    'str': Parameter.Type.STRING,
    'str_list': Parameter.Type.STRING_ARRAY,
    'float_list': Parameter.Type.DOUBLE_ARRAY,
}


class ParameterError(CompassError):
    """A parameter value the node cannot start with."""


def _descriptor(p: Param) -> ParameterDescriptor:
    d = ParameterDescriptor(
        name=p.name, type=int(_TYPES[p.kind]), description=p.description, read_only=p.read_only
    )
    notes = []
    if p.kind == 'float' and p.lo is not None and p.hi is not None:
        d.floating_point_range = [
            FloatingPointRange(from_value=float(p.lo), to_value=float(p.hi), step=0.0)
        ]
    if p.kind == 'int' and p.lo is not None and p.hi is not None:
        d.integer_range = [IntegerRange(from_value=int(p.lo), to_value=int(p.hi), step=1)]
    if p.choices:
        notes.append('one of: ' + ', '.join(p.choices))
    if p.unit:
        notes.append('unit: ' + p.unit)
    if not p.read_only:
        notes.append('changeable at run time')
    d.additional_constraints = '; '.join(notes)
    return d


class ParameterSet:
    """
    Declares ``specs`` on ``node`` and keeps a plain dict of current values in :attr:`values`.

    ``on_change(changed: dict) -> str | None`` is called with accepted run-time changes before they
    apply; it may veto them by returning a reason (e.g. a knob the estimator rejects).
    """

    def __init__(self, node, specs, on_change: Callable | None = None):
        self.node = node
        self.specs = spec_by_name(specs)
        self.on_change = on_change
        self.values: dict = {}
        self._declared = False
        node.add_on_set_parameters_callback(self._callback)
        try:
            for p in specs:
                default = list(p.default) if isinstance(p.default, (list, tuple)) else p.default
                param = node.declare_parameter(p.name, default, _descriptor(p))
                self.values[p.name] = self._py(param.value)
        except (
            InvalidParameterValueException,
            InvalidParameterTypeException,
            ParameterException,
        ) as exc:
            raise ParameterError(f'{node.get_name()}: bad parameter: {exc}') from None
        self._declared = True

    @staticmethod
    def _py(v):
        if isinstance(v, (list, tuple)) or type(v).__name__ == 'array':
            return list(v)
        return v

    def _callback(self, params) -> SetParametersResult:
        changed = {}
        for prm in params:
            p = self.specs.get(prm.name)
            if p is None:
                continue  # use_sim_time and other ROS-defined parameters
            v = self._py(prm.value)
            if p.kind == 'float' and isinstance(v, int) and not isinstance(v, bool):
                v = float(v)
            reason = validate_value(p, v)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
            changed[p.name] = v
        if self._declared and changed and self.on_change is not None:
            try:
                reason = self.on_change(changed)
            except Exception as exc:  # noqa: BLE001 - a parameter set must never end the node
                # (e.g. a RecursionError or MemoryError from a file the new value names): refuse,
                # keep the old
                reason = (
                    f'{", ".join(sorted(changed))}: refused ({type(exc).__name__}: '
                    f'{" ".join(str(exc).split())[:200]})'
                )
                self.node.get_logger().error(f'parameter change refused: {reason}')
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        self.values.update(changed)
        return SetParametersResult(successful=True)

    def __getitem__(self, name):
        return self.values[name]

    def strings(self, name) -> list[str]:
        """
        Return a string-array parameter without the empty placeholder entries.

        The placeholders are there because ROS has no typed empty array.
        """
        return [s for s in self.values[name] if s]
