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
The sky models by name: what a scene's ``sky`` mapping (``{"model": "rayleigh", ...}``) builds.

Imports each model's module (:mod:`~polarization_compass.sky` for ``rayleigh``,
:mod:`~polarization_compass.sky_bdl` for ``berry_dennis_lee``), so that neither of those imports
the other upwards: a model module only defines its class; this module names it.
"""

from __future__ import annotations

from typing import Callable

from .sky import RayleighSky, SkyModelError
from .sky_bdl import BerryDennisLeeSky

__all__ = ['make_sky_model', 'register_sky_model', 'sky_model_names']

_REGISTRY: dict[str, Callable[..., object]] = {
    'rayleigh': RayleighSky,
    'berry_dennis_lee': BerryDennisLeeSky,
}


def register_sky_model(name: str):
    """
    Register ``factory(**params)`` as the sky model called ``name`` (class decorator).

    For a model defined in a test or a plugin; a later registration under the same name replaces
    the earlier one.

    Parameters
    ----------
    name : str
        Model name, as a scene's ``sky`` mapping writes it under ``model``.

    Returns
    -------
    callable
        Decorator that registers its argument (a class or factory) and returns it unchanged.

    """

    def deco(factory):
        _REGISTRY[name] = factory
        return factory

    return deco


def sky_model_names() -> list[str]:
    """
    Return the names of the registered sky models.

    Returns
    -------
    list of str
        Names, sorted.

    """
    return sorted(_REGISTRY)


def make_sky_model(config: dict | None):
    """
    Build a sky model from a mapping like ``{"model": "rayleigh", "dop_max": 0.75}``.

    Parameters
    ----------
    config : dict or None
        ``model`` (default ``rayleigh``) and the model's keyword parameters; None means Rayleigh
        with its defaults. Not modified.

    Returns
    -------
    object
        The model, e.g. :class:`~polarization_compass.sky.RayleighSky` or
        :class:`~polarization_compass.sky_bdl.BerryDennisLeeSky`.

    Raises
    ------
    SkyModelError
        Unknown model name, unknown parameter names (one line), or an out-of-range parameter
        (raised by the model itself).

    """
    cfg = dict(config or {'model': 'rayleigh'})
    name = cfg.pop('model', 'rayleigh')
    if name not in _REGISTRY:
        raise SkyModelError(f'unknown sky model {name!r}; known: {", ".join(sky_model_names())}')
    try:
        return _REGISTRY[name](**cfg)
    except TypeError as exc:
        raise SkyModelError(f'bad parameters for sky model {name!r}: {exc}') from None
