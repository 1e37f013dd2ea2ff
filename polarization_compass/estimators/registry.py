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
The public registry of heading methods: which estimator classes exist, in a stable order.

Every fact about a method lives on its class (see
:class:`~polarization_compass.estimators.base.Estimator`: ``name``, ``label``, ``style``,
``needs_tilt``, ``paper_method``, ``sweep_knobs``, ``relative_cost``, ``knob_specs()``);
applications (node parameters, graphs, the CLI, error-map sweeps, figures, the replay) read them
from here and never key behaviour on a method's name string.

Adding a method: write one module with an :class:`~.base.Estimator` subclass that sets its facts,
and add one line to :data:`_BUILTIN` below (or call :func:`register` from a plug-in). This module
imports the method modules; the method modules import :mod:`.base` only, so there is no import
cycle.
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib import import_module

from .base import Estimator, EstimatorError

__all__ = [
    'register',
    'unregister',
    'names',
    'get',
    'make',
    'paper_methods',
    'tilt_methods',
    'knob_names',
    'label',
    'style',
    'relative_cost',
    'sweep_knobs',
    'MethodNames',
]

# (module, class) of the built-in methods, in the paper's order, then the others: one line per
# method.
_BUILTIN = (
    ('.zenith', 'ZenithEstimator'),
    ('.sm_asm', 'SmAsmEstimator'),
    ('.symmetry', 'SymmetryEstimator'),
    ('.least_squares', 'LeastSquaresEstimator'),
    ('.least_squares', 'TiltAwareEstimator'),
)

_CLASSES: dict[str, type[Estimator]] = {}  # insertion order = the stable order of names()
_loaded = False


def _load() -> dict[str, type[Estimator]]:
    global _loaded
    if not _loaded:
        _loaded = True
        for mod, cls in _BUILTIN:
            register(getattr(import_module(mod, __package__), cls))
    return _CLASSES


def register(cls: type[Estimator]) -> type[Estimator]:
    """
    Add an estimator class under its ``name`` (usable as a class decorator).

    The built-in methods are loaded first, so they keep their places and names.

    Parameters
    ----------
    cls : type
        An :class:`~.base.Estimator` subclass that sets its own class attribute ``name`` (an
        identifier).

    Returns
    -------
    type
        ``cls`` itself.

    Raises
    ------
    EstimatorError
        ``cls`` is not an Estimator subclass, has no name of its own, or the name is taken by
        another class.

    """
    _load()  # the built-ins first: they keep their places and names
    if not (isinstance(cls, type) and issubclass(cls, Estimator)):
        raise EstimatorError(f'register: {cls!r} is not an Estimator subclass')
    name = cls.__dict__.get('name')
    if not isinstance(name, str) or not name or not name.isidentifier():
        raise EstimatorError(
            f'register: {cls.__name__} must set a class attribute name (an identifier)'
        )
    if _CLASSES.get(name, cls) is not cls:
        raise EstimatorError(
            f'register: method {name!r} is already registered ({_CLASSES[name].__name__})'
        )
    _CLASSES[name] = cls
    return cls


def unregister(name: str) -> None:
    """
    Remove a registered method (plug-ins and tests).

    Parameters
    ----------
    name : str
        Name of the method.

    Raises
    ------
    EstimatorError
        No method of that name is registered.

    """
    get(name)
    del _CLASSES[name]


def names(
    paper: bool | None = None,
    needs_tilt: bool | None = None,
    accepts_units: bool | None = None,
) -> tuple[str, ...]:
    """
    List the registered method names in their stable order, optionally filtered.

    Built-ins come in the paper's order, then the others in registration order.

    Parameters
    ----------
    paper : bool, optional
        Keep only methods whose ``paper_method`` equals this; None keeps all.
    needs_tilt : bool, optional
        Keep only methods whose ``needs_tilt`` equals this; None keeps all.
    accepts_units : bool, optional
        Keep only methods whose ``accepts_units`` (runs on a photodiode array) equals this; None
        keeps all.

    Returns
    -------
    tuple of str
        The method names.

    """
    return tuple(
        n
        for n, c in _load().items()
        if (paper is None or bool(c.paper_method) == paper)
        and (needs_tilt is None or bool(c.needs_tilt) == needs_tilt)
        and (accepts_units is None or bool(c.accepts_units) == accepts_units)
    )


def paper_methods() -> tuple[str, ...]:
    """
    List the paper's four approaches (``paper_method`` True), in order.

    Returns
    -------
    tuple of str
        The method names.

    """
    return names(paper=True)


def tilt_methods() -> tuple[str, ...]:
    """
    List the methods that read the known pitch and roll (``needs_tilt``).

    They run without a tilt corrector.

    Returns
    -------
    tuple of str
        The method names.

    """
    return names(needs_tilt=True)


def get(name: str) -> type[Estimator]:
    """
    Look up the estimator class of a method.

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    type
        The :class:`~.base.Estimator` subclass.

    Raises
    ------
    EstimatorError
        ``name`` is not registered; the message names the known methods.

    """
    classes = _load()
    try:
        return classes[name]
    except (KeyError, TypeError):
        raise EstimatorError(f'unknown method {name!r}; known: {", ".join(classes)}') from None


def find(name: str) -> type[Estimator] | None:
    """
    Look up the estimator class of a method, or None when it is not registered.

    For names read from old files, where an unknown method is not an error.

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    type or None
        The :class:`~.base.Estimator` subclass, or None.

    """
    return _load().get(name)


def make(name: str, **knobs) -> Estimator:
    """
    Create a new estimator of a method with the given knobs.

    Parameters
    ----------
    name : str
        Name of the method.
    **knobs
        Knob values, validated by the class (:meth:`~.base.Estimator.knob_specs`).

    Returns
    -------
    Estimator
        The new estimator.

    Raises
    ------
    EstimatorError
        ``name`` is not registered, or a knob is unknown or out of range.

    """
    return get(name)(**knobs)


def knob_names(name: str) -> frozenset:
    """
    List the names of the knobs a method accepts.

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    frozenset of str
        The knob names; empty for a method without knobs.

    Raises
    ------
    EstimatorError
        ``name`` is not registered.

    """
    return frozenset(get(name).knob_specs())


def label(name: str) -> str:
    """
    Give the human-readable label of a method (figures, tables).

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    str
        The class's ``label``; the name itself when unknown or unset.

    """
    c = find(name)
    return (c.label or name) if c is not None else name


def style(name: str) -> tuple | None:
    """
    Give the (matplotlib colour, line style) of a method in figures.

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    tuple or None
        ``(colour, line style)``; None when unknown or unset (the next colour of the cycle).

    """
    c = find(name)
    return c.style if c is not None else None


def relative_cost(name: str) -> float:
    """
    Give the relative CPU time per frame of a method (the replay balances its threads on it).

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    float
        The class's ``relative_cost`` (dimensionless); the base class's default for unknown
        methods.

    """
    c = find(name)
    return float((c or Estimator).relative_cost)


def sweep_knobs(name: str) -> dict:
    """
    Give a copy of the default sampling knobs of a method in error-map sweeps.

    Parameters
    ----------
    name : str
        Name of the method.

    Returns
    -------
    dict
        ``{knob: value}``; {} when the method is unknown or uses its defaults.

    """
    c = find(name)
    return dict(c.sweep_knobs) if c is not None else {}


class MethodNames(Sequence):
    """
    Provide a live, read-only sequence of the registered method names.

    Filtered like :func:`names`: parameter and launch-argument choices built at import time still
    see methods registered later.

    Parameters
    ----------
    paper : bool, optional
        Keep only methods whose ``paper_method`` equals this; None keeps all.
    needs_tilt : bool, optional
        Keep only methods whose ``needs_tilt`` equals this; None keeps all.
    accepts_units : bool, optional
        Keep only methods that run on a photodiode array's units (or not); None keeps all.

    """

    def __init__(
        self,
        paper: bool | None = None,
        needs_tilt: bool | None = None,
        accepts_units: bool | None = None,
    ):
        self._filter = {'paper': paper, 'needs_tilt': needs_tilt, 'accepts_units': accepts_units}

    def _names(self) -> tuple[str, ...]:
        return names(**self._filter)

    def __getitem__(self, i):
        return self._names()[i]

    def __len__(self) -> int:
        return len(self._names())

    def __contains__(self, x) -> bool:
        return x in self._names()

    def __iter__(self):
        return iter(self._names())

    def __add__(self, other):
        return self._names() + tuple(other)

    def __radd__(self, other):
        return tuple(other) + self._names()

    def __eq__(self, other):
        return (
            tuple(self) == tuple(other)
            if isinstance(other, (tuple, list, MethodNames))
            else NotImplemented
        )

    def __hash__(self):
        return hash(tuple(self))

    def __repr__(self) -> str:
        return f'MethodNames{self._names()!r}'
