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
Which methods run, with which knobs: the method selection, the estimators and each result's row.

:func:`method_list` reads a method selection, :func:`make_estimators` makes one estimator per
method with the knobs it declares (names and ranges checked by the knobs' own declarations,
:func:`check_stride` for ``--stride``), and :func:`result_row` gives a result as the JSON-ready
dict ``estimate`` prints.
"""

from __future__ import annotations

from ..errors import CompassError

__all__ = [
    'REAL_SKY_KNOBS',
    'REAL_SKY_OUTLIER_DEG',
    'check_stride',
    'make_estimators',
    'method_list',
    'result_row',
]

#: real images: the robust refit's outlier threshold for the methods that have the knob
#: (``outlier_deg``)
REAL_SKY_OUTLIER_DEG = 15.0

#: real images: knob defaults for the methods with the robust refit (``outlier_deg``), unless the
#: user sets ``outlier_deg``: consensus over candidate suns, outliers beyond 15 deg dropped
REAL_SKY_KNOBS = {'outlier_deg': REAL_SKY_OUTLIER_DEG, 'max_aop_noise_deg': 90.0}


def method_list(text: str) -> list[str]:
    """
    Read a method selection: ``all`` or a comma-separated list of registered methods.

    Parameters
    ----------
    text : str
        ``all`` or e.g. ``zenith,sm_asm``.

    Returns
    -------
    list of str
        The method names, in the registry's order for ``all``, else as given.

    Raises
    ------
    CompassError
        An unknown method or an empty list.

    """
    from ..estimators import estimator_names

    names = estimator_names()
    if text == 'all':
        return names
    wanted = [t.strip() for t in text.split(',') if t.strip()]
    bad = [w for w in wanted if w not in names]
    if bad or not wanted:
        raise CompassError(
            f'--method: unknown {", ".join(bad) or repr(text)}; known: {", ".join(names)} or all'
        )
    return wanted


def make_estimators(methods, knobs: dict, stride: int | None = None, defaults=None) -> list:
    """
    Make one estimator per method, each with the knobs it declares.

    Names and ranges are checked by the knobs' own declarations (``knob_specs``, through
    :func:`polarization_compass.estimators.make_estimator`).

    Parameters
    ----------
    methods : sequence of str
        Registered method names.
    knobs : dict
        Knob name to value, applied to every method that has the knob; each must be some
        selected method's.
    stride : int, optional
        Every N-th sensor pixel, for the methods with a ``stride`` knob (checked against the
        declared range even when none of the selected methods has one).
    defaults : dict, optional
        Knob defaults for the methods with the robust refit (``outlier_deg``) unless ``knobs``
        sets ``outlier_deg`` (:data:`REAL_SKY_KNOBS` on real images).

    Returns
    -------
    list of tuple
        (name, estimator, the knobs it was given) per method.

    Raises
    ------
    CompassError
        A knob no selected method has; a bad knob value (an
        :class:`~polarization_compass.estimators.EstimatorError`).

    """
    from ..estimators import make_estimator, registry

    if stride is not None:
        check_stride(stride, methods)
    estimators, used = [], set()
    for name in methods:
        specs = registry.get(name).knob_specs()
        kn = {k: v for k, v in knobs.items() if k in specs}
        if defaults and 'outlier_deg' in specs and 'outlier_deg' not in knobs:
            for k, v in defaults.items():
                if k in specs and k not in knobs:
                    kn[k] = v
        used.update(kn)
        if stride is not None and 'stride' in specs:
            kn['stride'] = stride
        estimators.append((name, make_estimator(name, **kn), kn))
    unused = sorted(set(knobs) - used)
    if unused:
        raise CompassError(f'--knob {", ".join(unused)}: no selected method has that knob')
    return estimators


def check_stride(stride, methods) -> None:
    """
    Check a stride against the ``stride`` knob as the methods declare it.

    The declarations of the selected methods that have the knob, else that of any registered
    method (so a bad value is refused even when no selected method reads it).

    Parameters
    ----------
    stride : int
        Every N-th sensor pixel.
    methods : sequence of str
        The selected methods.

    Raises
    ------
    EstimatorError
        The value is outside the declared range or not an integer.

    """
    from ..estimators import registry

    def holders(names):
        specs = (registry.get(n).knob_specs() for n in names)
        return [s['stride'] for s in specs if 'stride' in s]

    for spec in holders(methods) or holders(registry.names())[:1]:
        spec.check('stride', stride)


def result_row(res, time_ms: float, knobs: dict, source: dict, truth_psi_deg=None) -> dict:
    """
    Give one method's result as the JSON-ready dict ``estimate`` prints.

    Parameters
    ----------
    res : HeadingResult
        The result.
    time_ms : float
        Time it took [ms] (rounded to microseconds here).
    knobs : dict
        The knobs the method was given.
    source : dict
        Where the sun and the input came from.
    truth_psi_deg : float, optional
        The true psi [deg] of a simulated frame: adds ``truth_psi_deg`` and ``error_deg``
        (axially folded for an axial result) when the result has a psi.

    Returns
    -------
    dict
        ``res.to_json_dict()`` plus ``time_ms``, ``knobs``, the truth and error, and ``source``.

    """
    from ..conventions import fold_axial_deg, wrap_180_deg

    d = res.to_json_dict()
    d['time_ms'] = round(time_ms, 3)
    d['knobs'] = knobs
    if res.psi_deg is not None and truth_psi_deg is not None:
        err = res.psi_deg - truth_psi_deg
        d['truth_psi_deg'] = truth_psi_deg
        d['error_deg'] = float(fold_axial_deg(err) if res.axial else wrap_180_deg(err))
    d['source'] = source
    return d
