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

"""The node specifications the graphs are built from: estimators, correctors, the evaluator."""

from __future__ import annotations

from .spec import NodeSpec
from ..estimators import registry
from ..specs import topics as T
from ..specs.params import defaults, ESTIMATOR


def _used(remappings, pubs, subs) -> tuple:
    """Only the remappings of topics the node uses."""
    used = {t for t, _ in pubs} | {t for t, _ in subs}
    return tuple((a, b) for a, b in remappings if a in used)


#: Estimator knobs the graphs set where the method has them (accuracy for time, see docs/ros.md):
#: every 4th superpixel. Set per method (not in the shared parameter file) because the knobs differ
#: by method.
GRAPH_KNOBS = {'knob.stride': 8}


def _knob_names(method: str) -> set:
    from ..specs.params import knob_params

    return {p.name for p in knob_params(method)}


def _downstream(nodes) -> list[str]:
    """
    Return ``topic=reader,reader`` for every topic these nodes publish to each other.

    A topic counts when other nodes of the list read it: the simulator waits for those
    subscriptions before its first frame, so that no early message is lost to discovery (named
    nodes: a recorder outside the graph must not stand in for the evaluator). Topics are compared
    after namespacing and remapping; a topic in the root namespace is written relative, as before.
    """
    out = []
    for n in nodes:
        for topic, _ in n.resolved_publishes():
            if topic in ('/diagnostics', '/clock'):
                continue  # not part of the data path
            readers = sorted(
                {
                    m.name
                    for m in nodes
                    if m is not n and any(t == topic for t, _ in m.resolved_subscribes())
                }
            )
            entry = f'{topic if n.namespace else topic[1:]}={",".join(readers)}'
            if readers and entry not in out:
                out.append(entry)
    return out or ['']


def _estimator(method: str, params: dict, remappings=(), namespace='') -> NodeSpec:
    params = {**{k: v for k, v in GRAPH_KNOBS.items() if k in _knob_names(method)}, **params}
    site_source = params.get('site_source', 'parameters')
    prior = params.get('prior_source', 'imu')
    shown = {**defaults(ESTIMATOR), **params}
    pubs, subs = T.estimator_topics(
        method,
        site_source,
        needs_tilt=registry.get(method).needs_tilt,
        prior_source=prior,
        debug_image=shown['debug_rate_hz'] > 0,
        marker=bool(shown['publish_marker']),
    )
    return NodeSpec(
        'heading_estimator',
        f'heading_estimator_{method}',
        namespace,
        ('config/heading_estimator.yaml',),
        {'method': method, **params},
        _used(remappings, pubs, subs),
        tuple(pubs),
        tuple(subs),
    )


def _array_estimator(method: str, params: dict, remappings=(), namespace='') -> NodeSpec:
    """Return a photodiode array's ``array_heading_estimator`` (its own knobs: the defaults)."""
    pubs, subs = T.estimator_topics(
        method,
        params.get('site_source', 'parameters'),
        needs_tilt=registry.get(method).needs_tilt,
        prior_source=params.get('prior_source', 'imu'),
        input_kind='array',
        array_stamp=params.get('array_stamp', 'header'),
    )
    return NodeSpec(
        'array_heading_estimator',
        f'heading_estimator_array_{method}',
        namespace,
        (),
        {'method': method, **params},
        _used(remappings, pubs, subs),
        tuple(pubs),
        tuple(subs),
    )


def _corrector(method: str, params: dict, remappings=(), namespace='') -> NodeSpec:
    pubs, subs = T.corrector_topics(method, params.get('site_source', 'parameters'))
    return NodeSpec(
        'tilt_corrector',
        f'tilt_corrector_{method}',
        namespace,
        ('config/tilt_corrector.yaml',),
        {'method': method, **params},
        _used(remappings, pubs, subs),
        tuple(pubs),
        tuple(subs),
    )


def _evaluator(methods, direct, params: dict) -> NodeSpec:
    streams = T.evaluator_streams(methods, direct_methods=direct)
    pubs, subs = T.evaluator_topics(streams, params.get('latency_source', 'sim_frames'))
    return NodeSpec(
        'error_evaluator',
        'error_evaluator',
        '',
        ('config/error_evaluator.yaml',),
        {'methods': list(methods), 'direct_methods': list(direct) or [''], **params},
        (),
        tuple(pubs),
        tuple(subs),
    )


def _split_direct(methods, tilt_aware: bool) -> tuple[tuple, tuple]:
    """
    Split ``methods`` into those with a corrector and the direct ones.

    The direct ones are those whose class ``needs_tilt`` (exact at any tilt, no corrector);
    ``tilt_aware`` adds every registered method that needs the tilt.
    """
    listed = tuple(dict.fromkeys(methods))
    direct = tuple(m for m in listed if registry.get(m).needs_tilt)
    if tilt_aware:
        direct += tuple(m for m in registry.tilt_methods() if m not in direct)
    return tuple(m for m in listed if m not in direct), direct
