"""Heading estimators: the paper's four approaches plus an exact tilt-aware least-squares solve.

The methods are listed by :mod:`.registry`; ``make_estimator``/``estimator_names``/``estimator_knob_names``
are its ``make``/``names``/``knob_names``."""
from . import registry  # noqa: F401
from ._common import Knob  # noqa: F401  (a plug-in method describes its knobs with it)
from .base import EstimatorError, HeadingResult, Observation, Status  # noqa: F401
from .registry import knob_names as estimator_knob_names  # noqa: F401
from .registry import make as make_estimator  # noqa: F401


def estimator_names() -> list[str]:
    """List the registered methods in the registry's stable order (the paper's first).

    Returns
    -------
    list of str
        The method names (:func:`.registry.names`).
    """
    return list(registry.names())
