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

"""The ``fusion`` graph: the sim graph plus robot_localization's ``ekf_node``."""

from __future__ import annotations

import dataclasses

import yaml

from .node_specs import _downstream
from .paths import share_dir
from .sim import sim_graph
from .spec import Graph, GraphError, NodeSpec
from ..specs import topics as T

#: robot_localization's parameter file the fusion graph runs ekf_node with: the example users copy
EKF_CONFIG = 'config/ekf_heading_example.yaml'
#: ekf_node's name in EKF_CONFIG (the node the file's parameters are for)
EKF_NODE = 'ekf_filter_node'


def fusion_graph(
    methods=('least_squares',),
    tilt_aware=True,
    fuse=('least_squares',),
    turns=1.0,
    turn_rate_deg_s=10.0,
    pitch_deg=-20.0,
    roll_deg=0.0,
    odom_yaw_rate_bias_deg_s=0.5,
    odom_yaw_rate_noise_deg_s=0.2,
    exit_when_done=True,
    error_map='',
    report_dir='out/fusion',
) -> Graph:
    """
    Return the ``fusion`` graph: the sim graph plus robot_localization's ``ekf_node``.

    Each fused heading gets an ``ekf_node`` with :data:`EKF_CONFIG`'s parameters, ``imu0`` pointed
    at that method's corrected heading (a method that reads the tilt: its own), the simulator's
    ``odometry/wheel`` as ``odom0`` and sim time. The first is :data:`EKF_NODE` (the file's node,
    its own topic ``/odometry/filtered`` and TF); the others are ``ekf_filter_node_<method>`` on
    ``/odometry/filtered_<method>`` without TF, and ``none`` fuses the odometry alone (the drift
    the compass bounds). The evaluator scores each as stream ``<method>/fused`` (``none``:
    ``odometry/fused``).

    Parameters
    ----------
    methods : iterable of str
        Paper methods: an estimator and a corrector each.
    tilt_aware : bool
        Also run every registered method that reads the IMU tilt (no corrector).
    fuse : iterable of str
        Methods whose heading is fused (each must run), or ``"none"``.
    turns, turn_rate_deg_s, pitch_deg, roll_deg : float
        The simulated motion (:func:`sim_graph`).
    odom_yaw_rate_bias_deg_s, odom_yaw_rate_noise_deg_s : float
        The simulated wheel odometry's yaw-rate bias and noise [deg/s].
    exit_when_done : bool
        Stop the whole graph after the last frame.
    error_map : str
        Tilt error map of the correctors ("" = the map shipped with the package).
    report_dir : str
        Where the error_evaluator writes its report.

    Returns
    -------
    Graph
        The graph.

    Raises
    ------
    GraphError
        Nothing to fuse, a fused method that does not run, or an unreadable :data:`EKF_CONFIG`.

    """
    sim = sim_graph(
        methods=methods,
        tilt_aware=tilt_aware,
        turns=turns,
        turn_rate_deg_s=turn_rate_deg_s,
        pitch_deg=pitch_deg,
        roll_deg=roll_deg,
        exit_when_done=exit_when_done,
        error_map=error_map,
        report_dir=report_dir,
    )
    fuse, correctors = _fused_methods(sim, fuse)
    base = _ekf_base_parameters()
    ekfs, scored = _ekf_nodes(fuse, correctors, base)
    nodes = _fusion_sim_nodes(sim, scored, odom_yaw_rate_bias_deg_s, odom_yaw_rate_noise_deg_s)
    nodes += ekfs
    nodes[0] = dataclasses.replace(
        nodes[0], parameters={**nodes[0].parameters, 'wait_for_downstream': _downstream(nodes)}
    )
    return Graph(
        'fusion',
        "the sim graph plus robot_localization's ekf_node fusing wheel odometry and the heading",
        tuple(nodes),
        shutdown_with=sim.shutdown_with,
    )


def _fused_methods(sim: Graph, fuse) -> tuple[tuple, set]:
    """
    Check the fused methods against the sim graph: (fuse without repeats, corrected methods).

    Raises GraphError when there is nothing to fuse or a fused method does not run.
    """
    fuse = tuple(dict.fromkeys(fuse))
    if not fuse:
        raise GraphError('the fusion graph needs at least one heading to fuse (or none)')
    running = {n.parameters['method']: n for n in sim.nodes if n.executable == 'heading_estimator'}
    correctors = {n.parameters['method'] for n in sim.nodes if n.executable == 'tilt_corrector'}
    missing = [m for m in fuse if m != 'none' and m not in running]
    if missing:
        raise GraphError(
            f'fuse names {missing}, which the graph does not run (methods, tilt_aware)'
        )
    return fuse, correctors


def _ekf_base_parameters() -> dict:
    """Read :data:`EKF_NODE`'s parameters from :data:`EKF_CONFIG` (GraphError when unreadable)."""
    path = share_dir() / EKF_CONFIG
    try:
        base = yaml.safe_load(path.read_text())[EKF_NODE]['ros__parameters']
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise GraphError(f'cannot read {EKF_NODE} parameters from {path}: {exc}') from None
    return base


def _ekf_nodes(fuse: tuple, correctors: set, base: dict) -> tuple[list, list]:
    """
    Build one ``ekf_node`` per fused method and the evaluator's fused streams (``<name>=<topic>``).

    The first (unless ``none``) is :data:`EKF_NODE` with :data:`EKF_CONFIG` and TF; the others
    carry the file's parameters (not its ``imu0``) and publish no TF.
    """
    ekfs, scored = [], []
    for i, m in enumerate(fuse):
        topic = (
            None
            if m == 'none'
            else '/' + T.method_topics(m)['heading' if m in correctors else 'heading_raw']
        )
        first = i == 0 and m != 'none'
        name = EKF_NODE if first else f'{EKF_NODE}_{m}'
        out = '/' + T.FILTERED if first else f'/{T.FILTERED}_{m}'
        params = {} if first else {k: v for k, v in base.items() if not k.startswith('imu0')}
        params.update(use_sim_time=True, odom0='/' + T.ODOM)
        if topic is not None:
            params.update(
                {k: v for k, v in base.items() if k.startswith('imu0') and not first}, imu0=topic
            )
        if not first:
            params['publish_tf'] = False
        subs = [('/' + T.ODOM, T.T_ODOMETRY)] + ([] if topic is None else [(topic, T.T_IMU)])
        ekfs.append(
            NodeSpec(
                'ekf_node',
                name,
                '',
                (EKF_CONFIG,) if first else (),
                params,
                () if first else ((T.FILTERED, out),),
                ((T.FILTERED, T.T_ODOMETRY),),
                tuple(subs),
                package='robot_localization',
            )
        )
        scored.append(f'{"odometry" if m == "none" else m}={out}')
    return ekfs, scored


def _fusion_sim_nodes(
    sim: Graph, scored: list, odom_yaw_rate_bias_deg_s, odom_yaw_rate_noise_deg_s
) -> list:
    """
    Return the sim graph's nodes as the fusion graph runs them.

    The simulator with the odometry's bias and noise and a long wait for its readers; the evaluator
    scoring the fused streams too.
    """
    nodes = []
    for n in sim.nodes:
        if n.executable == 'sky_simulator':
            n = dataclasses.replace(
                n,
                parameters={
                    **n.parameters,
                    'odom_yaw_rate_bias_deg_s': float(odom_yaw_rate_bias_deg_s),
                    'odom_yaw_rate_noise_deg_s': float(odom_yaw_rate_noise_deg_s),
                },
            )
        if n.executable == 'error_evaluator':
            pubs, subs = T.evaluator_topics(
                T.evaluator_streams(
                    n.parameters['methods'], direct_methods=n.parameters['direct_methods']
                ),
                fused=T.fused_streams(scored),
            )
            n = dataclasses.replace(
                n, parameters={**n.parameters, 'fused_streams': scored}, subscribes=tuple(subs)
            )
        nodes.append(n)
    return nodes
