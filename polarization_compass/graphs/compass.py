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

"""The ``compass`` graph: a real camera and IMU, one estimator and its corrector."""

from __future__ import annotations

from .node_specs import _corrector, _estimator
from .spec import Graph, NodeSpec
from ..estimators import registry
from ..specs import topics as T


def compass_graph(
    method='least_squares',
    correction='error_map',
    image_topic=T.IMAGE,
    camera_info_topic=T.CAMERA_INFO,
    imu_topic=T.IMU,
    fix_topic=T.FIX,
    site_source='navsatfix',
    frame_id='base_link',
    namespace='',
    use_sim_time=False,
    error_map='',
    sky_check=True,
) -> Graph:
    """
    Return the ``compass`` graph: a real camera and IMU, one estimator and its corrector.

    Parameters
    ----------
    method : str
        Heading method (a method that reads the tilt gets no corrector).
    correction : {"error_map", "none"}
        Tilt correction of the heading.
    image_topic, camera_info_topic, imu_topic, fix_topic : str
        Input topics (remappings of the nodes' default names).
    site_source : {"parameters", "navsatfix"}
        Where the site comes from.
    frame_id : str
        frame_id of the published heading (z up, e.g. base_link).
    namespace : str
        Namespace of the compass nodes.
    use_sim_time : bool
        Use ``/clock``.
    error_map : str
        Tilt error map (.npz) ("" = the map shipped with the package).
    sky_check : bool, default True
        The estimator checks every heading against the whole sky (its ``sky_check`` parameter): on
        real skies a heading is ``ok`` only when the whole sky agrees (docs/real-cameras.md).

    Returns
    -------
    Graph
        The graph, its camera, IMU and fix topics as external inputs.

    """
    remaps = tuple(
        (a, b)
        for a, b in (
            (T.IMAGE, image_topic),
            (T.CAMERA_INFO, camera_info_topic),
            (T.IMU, imu_topic),
            (T.FIX, fix_topic),
        )
        if a != b
    )
    common = {'use_sim_time': bool(use_sim_time)}
    nodes = [
        _estimator(
            method,
            {
                **common,
                'site_source': site_source,
                'frame_id': frame_id,
                'sky_check': bool(sky_check),
            },
            remaps,
            namespace,
        )
    ]
    if not registry.get(method).needs_tilt:  # a method that reads the tilt needs no corrector
        nodes.append(
            _corrector(
                method,
                {
                    **common,
                    'site_source': site_source,
                    'correction': correction,
                    'error_map': error_map,
                },
                remaps,
                namespace,
            )
        )
    probe = NodeSpec('x', 'x', namespace, remappings=remaps)
    external = tuple(probe.resolved(t) for t in (T.IMAGE, T.CAMERA_INFO, T.IMU, T.FIX))
    return Graph(
        'compass',
        'a real polarization camera and IMU: heading for robot_localization',
        tuple(nodes),
        external_inputs=external,
    )
