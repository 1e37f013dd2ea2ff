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

"""The ``sim`` graph: the sky simulator, the estimators, their correctors and the evaluator."""

from __future__ import annotations

import dataclasses

from .node_specs import (
    _array_estimator,
    _corrector,
    _downstream,
    _estimator,
    _evaluator,
    _split_direct,
)
from .spec import Graph, GraphError, NodeSpec, SIM_ATTITUDE_SOURCES
from ..estimators import registry
from ..specs import topics as T
from ..specs.params import PAPER_METHODS

#: How long the simulator waits for all its readers before the first frame [s]: with a cold numba
#: cache (a fresh install, or the first `make sim` after a change) five estimators compiling at
#: once took 60-130 s to start on 2 cores, and 60 s lost the first frame of the slowest
READERS_WAIT_TIMEOUT_S = 600.0


def _tf_attitude_params(attitude_source: str, turns: float, turn_rate_deg_s: float) -> dict:
    """
    Return the simulator parameters of the sim graph's ``attitude_source``.

    ``tf``: the simulator looks the attitude up in TF and broadcasts its built-in motion there
    (``motion_tf``): one source of attitude, exercised through the real tf2 path. Its run length
    (``duration_s``) is then set from the turns, which a TF-driven simulator does not count. No
    wheel odometry then, so no ``odom`` parent of ``base_link`` besides ``map``.

    Parameters
    ----------
    attitude_source : {"motion", "tf"}
        The launch argument.
    turns, turn_rate_deg_s : float
        The simulated motion (:func:`sim_graph`).

    Returns
    -------
    dict
        Inline parameters for the simulator (empty for ``motion``: its defaults).

    Raises
    ------
    GraphError
        An attitude source other than :data:`SIM_ATTITUDE_SOURCES`.

    """
    if attitude_source not in SIM_ATTITUDE_SOURCES:
        raise GraphError(
            f'attitude_source must be one of {", ".join(SIM_ATTITUDE_SOURCES)}, '
            f'got {attitude_source!r}'
        )
    if attitude_source == 'motion':
        return {}
    duration = turns * 360.0 / abs(turn_rate_deg_s) if turns > 0 and turn_rate_deg_s else 0.0
    return {'attitude_source': 'tf', 'motion_tf': True, 'duration_s': float(duration)}


def sim_graph(
    methods=PAPER_METHODS,
    tilt_aware=True,
    encoding='mono16',
    rate_hz=10.0,
    time_scale=1.0,
    turns=1.0,
    turn_rate_deg_s=10.0,
    pitch_deg=-20.0,
    roll_deg=0.0,
    scene='',
    lockstep=True,
    exit_when_done=True,
    error_map='',
    report_dir='out/sim',
    array_geometry='',
    attitude_source='motion',
) -> Graph:
    """
    Return the ``sim`` graph: simulator, estimators, correctors and the evaluator on sim time.

    Parameters
    ----------
    methods : iterable of str
        Paper methods: an estimator and a corrector each (a method whose class needs the tilt
        gets no corrector).
    tilt_aware : bool
        Also run every registered method that reads the IMU tilt (no corrector).
    encoding : {"mono16", "mono8", "32FC1"}
        Simulated camera encoding.
    rate_hz : float
        Camera frame rate [Hz] of simulated time.
    time_scale : float
        Simulated seconds per wall second.
    turns : float
        Full turns to simulate (0: until stopped).
    turn_rate_deg_s : float
        Turn rate [deg/s].
    pitch_deg, roll_deg : float
        Camera pitch and roll during the turn [deg] (paper eq 21; Fig 17: pitch -20).
    scene : str
        Scene YAML for camera, sky and sensor ("" = the paper's set-up).
    lockstep : bool
        The simulator waits for every estimator before the next frame.
    exit_when_done : bool
        Stop the whole graph after the last frame.
    error_map : str
        Tilt error map (.npz) of the correctors ("" = the map shipped with the package).
    report_dir : str
        Where the error_evaluator writes its report.
    array_geometry : str
        Photodiode-array sensor YAML: also simulate the array and run its estimators in
        namespace ``array`` ("" = no array).
    attitude_source : {"motion", "tf"}
        ``motion``: the simulator renders the built-in motion. ``tf``: it looks every stamp's
        attitude up in TF and broadcasts the motion there itself (:func:`_tf_attitude_params`).

    Returns
    -------
    Graph
        The graph; it ends with the simulator when ``exit_when_done``.

    Raises
    ------
    GraphError
        No method to run.

    """
    methods, direct = _split_direct(methods, tilt_aware)
    all_methods = methods + direct
    if not all_methods:
        raise GraphError('the sim graph needs at least one method')
    sim_time = {'use_sim_time': True}
    lock_topics = [T.method_topics(m)['status'] for m in all_methods]
    sim_params = {
        'encoding': encoding,
        'rate_hz': float(rate_hz),
        'time_scale': float(time_scale),
        'turns': float(turns),
        'turn_rate_deg_s': float(turn_rate_deg_s),
        'pitch_deg': float(pitch_deg),
        'roll_deg': float(roll_deg),
        'scene': scene,
        'clock_mode': 'sim',
        'array_geometry': array_geometry,
        'exit_when_done': bool(exit_when_done),
        'lockstep': bool(lockstep),
        'lockstep_topics': lock_topics,
        'wait_for_subscribers': len(all_methods),
        'wait_timeout_s': READERS_WAIT_TIMEOUT_S,
        # every estimator reads the IMU (prior or tilt) and so does every corrector
        'wait_for_imu_subscribers': len(all_methods) + len(methods),
        **_tf_attitude_params(attitude_source, turns, turn_rate_deg_s),
    }
    pubs, subs = T.simulator_topics(
        attitude_source, publish_clock=True, array=bool(array_geometry)
    )
    if lockstep:
        subs = list(subs) + [(t, T.T_STRING) for t in lock_topics]
    nodes = [
        NodeSpec(
            'sky_simulator',
            'sky_simulator',
            '',
            ('config/sky_simulator.yaml',),
            sim_params,
            (),
            tuple(pubs),
            tuple(subs),
        )
    ]
    nodes += [_estimator(m, dict(sim_time)) for m in all_methods]
    nodes += [_corrector(m, {**sim_time, 'error_map': error_map}) for m in methods]
    if array_geometry:  # the array's estimators in namespace array, reading the simulator's topics
        to_root = tuple((t, '/' + t) for t in (T.ARRAY, T.ARRAY_HEADER, T.IMU, T.FIX))
        nodes += [
            _array_estimator(m, {**sim_time, 'array_geometry': array_geometry}, to_root, 'array')
            for m in registry.names(accepts_units=True)
        ]
    nodes.append(
        _evaluator(
            all_methods,
            direct,
            {**sim_time, 'report_dir': report_dir, 'time_scale': float(time_scale)},
        )
    )
    nodes[0] = dataclasses.replace(
        nodes[0],
        parameters={**sim_params, 'wait_for_downstream': _downstream(nodes), 'wait_settle_s': 1.0},
    )
    return Graph(
        'sim',
        'simulated camera and IMU, every method, raw and corrected errors',
        tuple(nodes),
        shutdown_with='sky_simulator' if exit_when_done else None,
    )
