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

"""The ``replay`` graph: the sim graph's estimators and evaluator on a recorded bag."""

from __future__ import annotations

from .node_specs import _corrector, _estimator, _evaluator, _split_direct
from .spec import Graph
from ..specs import topics as T
from ..specs.params import PAPER_METHODS


def replay_graph(
    methods=PAPER_METHODS,
    tilt_aware=True,
    site_source='navsatfix',
    error_map='',
    report_dir='out/replay',
) -> Graph:
    """
    Return the ``replay`` graph: the sim graph without the simulator, for a played bag.

    For ``ros2 bag play --clock`` of a recorded run; ``use_sim_time`` on.

    Parameters
    ----------
    methods : iterable of str
        Paper methods to run on the bag.
    tilt_aware : bool
        Also run every registered method that reads the IMU tilt.
    site_source : {"parameters", "navsatfix"}
        Site from the bag's NavSatFix or from parameters.
    error_map : str
        Tilt error map (.npz) ("" = the map shipped with the package).
    report_dir : str
        Where the error_evaluator writes its report.

    Returns
    -------
    Graph
        The graph; the bag's image, camera_info, IMU, fix, truth and ``/clock`` are external
        inputs.

    """
    methods, direct = _split_direct(methods, tilt_aware)
    all_methods = methods + direct
    common = {'use_sim_time': True}
    # the player publishes reliably: images queue behind an estimator slower than the player
    # instead of being dropped (every frame of the bag scored, as offline)
    nodes = [
        _estimator(m, {**common, 'site_source': site_source, 'image_qos': 'replay'})
        for m in all_methods
    ]
    nodes += [
        _corrector(m, {**common, 'site_source': site_source, 'error_map': error_map})
        for m in methods
    ]
    nodes.append(
        _evaluator(
            all_methods, direct, {**common, 'report_dir': report_dir, 'latency_source': 'clock'}
        )
    )
    external = tuple('/' + t for t in (T.IMAGE, T.CAMERA_INFO, T.IMU, T.FIX, T.TRUTH)) + (T.CLOCK,)
    return Graph(
        'replay',
        "a recorded run played with 'ros2 bag play --clock'",
        tuple(nodes),
        external_inputs=external,
    )
