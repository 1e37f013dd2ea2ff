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
Heading estimators: the paper's four approaches plus an exact tilt-aware least-squares solve.

The methods are listed by :mod:`.registry`;
``make_estimator``/``estimator_names``/``estimator_knob_names`` are its
``make``/``names``/``knob_names``.
"""

from . import registry  # noqa: F401
from ._knobs import Knob  # noqa: F401  (a plug-in method describes its knobs with it)
from .base import EstimatorError, HeadingResult, Observation, Status  # noqa: F401
from .registry import knob_names as estimator_knob_names  # noqa: F401
from .registry import make as make_estimator  # noqa: F401


def estimator_names() -> list[str]:
    """
    List the registered methods in the registry's stable order (the paper's first).

    Returns
    -------
    list of str
        The method names (:func:`.registry.names`).

    """
    return list(registry.names())
