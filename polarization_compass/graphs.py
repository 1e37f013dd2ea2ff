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
The single description of each node graph (ROS-free).

``launch/sim.launch.py``, ``compass.launch.py`` and ``replay.launch.py`` build their
LaunchDescription from here, and ``polarization-compass sim`` (``make sim``) starts the very same
graph as subprocesses without ``ros2 launch`` (:meth:`NodeSpec.command`). A graph lists its nodes:
executable (a console script of ``setup.py``), node name, namespace, parameter files (paths in the
package's share directory), inline parameters (applied after the files) and remappings, plus the
topics each node publishes and subscribes to (from :mod:`polarization_compass.specs.topics`, the
names the node code itself uses) so that the wiring can be checked without running anything.

Graphs
------
``sim``      sky_simulator -> one heading_estimator per method -> one tilt_corrector per paper
             method -> error_evaluator; sim time from the simulator's ``/clock``.
``compass``  a real camera and IMU: one heading_estimator (``method``) and its tilt_corrector;
             the input topics are launch arguments (remappings).
``replay``   ``ros2 bag play --clock`` of a recorded run: the sim graph without the simulator,
             ``use_sim_time`` on, the site from the bag's NavSatFix.
``fusion``   the sim graph plus robot_localization's ``ekf_node`` configured from the shipped
             ``config/ekf_heading_example.yaml``: the simulator's wheel odometry and a compass
             heading fused; the evaluator scores ``/odometry/filtered`` too.

Launch arguments are strings (as ``ros2 launch`` passes them); :func:`build` parses them with the
types of :data:`ARGUMENTS`.

"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
import os
from pathlib import Path
import shutil
import sys

import yaml

from .errors import CompassError
from .estimators import registry
from .specs import topics as T
from .specs.params import ALL_METHODS, PAPER_METHODS, SUN_PARAMS

__all__ = [
    'PACKAGE',
    'LaunchArg',
    'NodeSpec',
    'Graph',
    'ARGUMENTS',
    'build',
    'sim_graph',
    'compass_graph',
    'replay_graph',
    'fusion_graph',
    'EKF_CONFIG',
    'share_dir',
    'GraphError',
    'parse_arg',
    'GRAPH_NAMES',
    'FASTDDS_PROFILE',
    'STOP_TIMEOUT_S',
    'SIGKILL_TIMEOUT_S',
]

PACKAGE = 'polarization_compass'
GRAPH_NAMES = ('sim', 'compass', 'replay', 'fusion')
#: Fast DDS profile for full-resolution images on one machine (shared memory with a large segment):
#: with the default transports, best-effort 10 MB images are lost in fragments. Used by
#: ``polarization-compass sim`` and the tests; optional on a robot (docs/ros.md).
FASTDDS_PROFILE = 'config/fastdds_large_images.xml'
#: Seconds a node gets to stop after SIGINT before SIGTERM (then SIGKILL after SIGKILL_TIMEOUT_S
#: more): ``sigterm_timeout`` of every launched node and the wait of ``polarization-compass sim``.
#: A node stops in well under a second (nodes.runner), but the evaluator draws its report figure at
#: the end and ten processes share two cores here: launch's default of 5 s was measured too short
#: (issue 15).
STOP_TIMEOUT_S = 20.0
SIGKILL_TIMEOUT_S = 5.0


#: ``attitude_source`` of the sim graph (the simulator's ``topic`` needs a publisher outside it)
SIM_ATTITUDE_SOURCES = ('motion', 'tf')


class GraphError(CompassError):
    """Unknown graph, bad launch argument or an inconsistent graph."""


@dataclass(frozen=True)
class LaunchArg:
    """
    Describe one launch argument of a graph (a string, as ``ros2 launch`` passes it).

    Parameters
    ----------
    name : str
        Argument name, units in the name (e.g. ``rate_hz``).
    default : str
        Default text.
    description : str
        Meaning, shown by ``ros2 launch --show-args``.
    kind : {"str", "bool", "float", "int", "list"}, default "str"
        How :func:`parse_arg` reads the text (``list``: comma separated).
    choices : tuple of str, default ()
        Allowed values (for a list: allowed items).

    """

    name: str
    default: str
    description: str
    kind: str = 'str'  # str | bool | float | int | list (comma separated)
    choices: tuple = ()


@dataclass(frozen=True)
class NodeSpec:
    """
    Describe one node of a graph.

    Parameters
    ----------
    executable : str
        Console script of ``setup.py``, e.g. ``"heading_estimator"``.
    name : str
        Node name.
    namespace : str, default ""
        Node namespace ("" = root).
    param_files : tuple of str, default ()
        Parameter files, paths in the package's share directory.
    parameters : dict, default {}
        Inline parameters, applied after the files.
    remappings : tuple of tuple of str, default ()
        ``((from, to), ...)`` topic remappings.
    publishes, subscribes : tuple of tuple of str, default ()
        ``((topic, type), ...)`` before remapping (the names of
        :mod:`polarization_compass.specs.topics`).
    package : str, default "polarization_compass"
        ROS package of the executable.

    """

    executable: str
    name: str
    namespace: str = ''
    param_files: tuple = ()
    parameters: dict = field(default_factory=dict)
    remappings: tuple = ()  # ((from, to), ...)
    publishes: tuple = ()  # ((topic, type), ...)
    subscribes: tuple = ()
    package: str = PACKAGE

    def remap(self, topic: str) -> str:
        """
        Return a topic's name after this node's remappings (namespace not applied).

        Parameters
        ----------
        topic : str
            Topic name as the node code uses it.

        Returns
        -------
        str
            The remapped name, or ``topic`` when no remapping names it.

        """
        for a, b in self.remappings:
            if a == topic:
                return b
        return topic

    def resolved(self, topic: str) -> str:
        """
        Return the absolute name of a (possibly relative) topic after remapping and namespacing.

        Parameters
        ----------
        topic : str
            Topic name as the node code uses it.

        Returns
        -------
        str
            Absolute topic name, e.g. ``"/array/imu/data"``.

        """
        t = self.remap(topic)
        if t.startswith('/'):
            return t
        ns = self.namespace.strip('/')
        return f'/{ns}/{t}' if ns else f'/{t}'

    def resolved_publishes(self) -> list[tuple[str, str]]:
        """
        Return the topics this node publishes, resolved (:meth:`resolved`).

        Returns
        -------
        list of tuple of str
            ``(absolute topic, type)`` pairs.

        """
        return [(self.resolved(t), ty) for t, ty in self.publishes]

    def resolved_subscribes(self) -> list[tuple[str, str]]:
        """
        Return the topics this node subscribes to, resolved (:meth:`resolved`).

        Returns
        -------
        list of tuple of str
            ``(absolute topic, type)`` pairs.

        """
        return [(self.resolved(t), ty) for t, ty in self.subscribes]

    def ros_arguments(self, share: Path) -> list[str]:
        """
        Return the ``--ros-args ...`` to run the executable directly, as ``ros2 launch`` would.

        Parameters
        ----------
        share : pathlib.Path
            The package's share directory (:func:`share_dir`), where the parameter files are.

        Returns
        -------
        list of str
            Node name, namespace, ``--params-file`` per file, ``-p name:=value`` per inline
            parameter (YAML scalars) and ``-r from:=to`` per remapping.

        """
        args = ['--ros-args', '-r', f'__node:={self.name}']
        if self.namespace:
            args += ['-r', f'__ns:=/{self.namespace.strip("/")}']
        for f in self.param_files:
            args += ['--params-file', str(Path(share) / f)]
        for k, v in self.parameters.items():
            args += ['-p', f'{k}:={_yaml_scalar(v)}']
        for a, b in self.remappings:
            args += ['-r', f'{a}:={b}']
        return args


def _yaml_scalar(v) -> str:
    text = yaml.safe_dump(v, default_flow_style=True, width=10_000).strip()
    if text.endswith('\n...'):
        text = text[:-4].strip()
    if text.endswith('...'):
        text = text[:-3].strip()
    return text


@dataclass(frozen=True)
class Graph:
    """
    Describe one node graph: its nodes and what it expects from outside.

    Parameters
    ----------
    name : str
        Graph name (one of :data:`GRAPH_NAMES`).
    description : str
        One-line description.
    nodes : tuple of NodeSpec
        The nodes.
    external_inputs : tuple of str, default ()
        Absolute topics expected from outside the graph (a camera driver, ``ros2 bag play``).
    shutdown_with : str, optional
        Name of the node whose exit ends the whole graph.

    """

    name: str
    description: str
    nodes: tuple
    external_inputs: tuple = ()  # absolute topics expected from outside the graph
    shutdown_with: str | None = None  # node name whose exit ends the whole graph

    def node(self, name: str) -> NodeSpec:
        """
        Return the node named ``name``.

        Parameters
        ----------
        name : str
            Node name.

        Returns
        -------
        NodeSpec
            The node.

        Raises
        ------
        GraphError
            The graph has no such node.

        """
        for n in self.nodes:
            if n.name == name:
                return n
        raise GraphError(f'graph {self.name!r} has no node {name!r}')

    def published_topics(self) -> dict:
        """
        Return every topic the graph's nodes publish, resolved, with its types.

        Returns
        -------
        dict
            ``{absolute topic: set of types}``.

        """
        out: dict = {}
        for n in self.nodes:
            for t, ty in n.resolved_publishes():
                out.setdefault(t, set()).add(ty)
        return out

    def check(self) -> list[str]:
        """
        Return the wiring problems of the graph.

        A subscription nobody in the graph (or outside it) publishes, a topic with two types,
        duplicate node names, a corrector whose site (gps/fix or parameters) is not its
        estimator's.

        Returns
        -------
        list of str
            One line per problem; empty when the graph is consistent.

        """
        problems = []
        names = [(n.namespace, n.name) for n in self.nodes]
        if len(set(names)) != len(names):
            problems.append('duplicate node names')
        pubs = self.published_topics()
        for t, types in pubs.items():
            if len(types) > 1:
                problems.append(f'{t} is published with several types {sorted(types)}')
        for n in self.nodes:
            for t, ty in n.resolved_subscribes():
                if t in self.external_inputs:
                    continue
                if t not in pubs:
                    problems.append(
                        f'{n.name} subscribes to {t}, which nothing in graph {self.name!r} '
                        'publishes'
                    )
                elif ty not in pubs[t]:
                    problems.append(
                        f'{n.name} subscribes to {t} as {ty}, published as {sorted(pubs[t])}'
                    )

        # the corrector computes the sun (error-map lookup) for the site its estimator used
        def fix(n):
            return n.resolved(T.FIX) if any(t == T.FIX for t, _ in n.subscribes) else None

        estimators = {
            (n.namespace, n.parameters.get('method')): n
            for n in self.nodes
            if n.executable == 'heading_estimator'
        }
        for n in self.nodes:
            est = estimators.get((n.namespace, n.parameters.get('method')))
            if n.executable == 'tilt_corrector' and est is not None and fix(n) != fix(est):
                problems.append(
                    f'{n.name} takes the site from {fix(n) or "its parameters"} but {est.name} '
                    'from '
                    f'{fix(est) or "its parameters"}: set the same site_source and fix topic'
                )
            if n.executable == 'tilt_corrector' and est is not None:
                differ = [
                    k
                    for k in SUN_PARAMS + ('site_source',)
                    if n.parameters.get(k) != est.parameters.get(k)
                ]
                if differ:
                    problems.append(f'{n.name} and {est.name} set different {", ".join(differ)}')
        return problems


# ------------------------------------------------------------------------------------------------
# Launch arguments
# ------------------------------------------------------------------------------------------------
_COMMON = (
    LaunchArg(
        'error_map',
        '',
        "tilt error map (.npz) for the correctors; '' = the map shipped with the package; make "
        'one '
        "with 'polarization-compass errormap' (polarization-compass sim builds one when needed)",
    ),
    LaunchArg('report_dir', 'out/sim', 'where error_evaluator writes its CSV and PNG report'),
)

ARGUMENTS = {
    'sim': (
        LaunchArg(
            'methods',
            ','.join(PAPER_METHODS),
            'paper methods: an estimator and a corrector each',
            'list',
            PAPER_METHODS,
        ),
        LaunchArg(
            'tilt_aware',
            'true',
            'also run the tilt_aware estimator (IMU tilt, no corrector)',
            'bool',
        ),
        LaunchArg(
            'encoding', 'mono16', 'simulated camera encoding', 'str', ('mono16', 'mono8', '32FC1')
        ),
        LaunchArg('rate_hz', '10.0', 'camera frame rate (simulated time)', 'float'),
        LaunchArg('time_scale', '1.0', 'simulated seconds per wall second', 'float'),
        LaunchArg('turns', '1.0', 'full turns to simulate (0: until stopped)', 'float'),
        LaunchArg('turn_rate_deg_s', '10.0', 'turn rate, deg/s', 'float'),
        LaunchArg(
            'pitch_deg', '-20.0', 'camera pitch during the turn (paper Fig 17: -20)', 'float'
        ),
        LaunchArg('roll_deg', '0.0', 'camera roll during the turn', 'float'),
        LaunchArg('scene', '', "scene YAML for camera, sky and sensor ('' = the paper's set-up)"),
        LaunchArg(
            'lockstep',
            'true',
            'simulator waits for every estimator before the next frame: every frame is '
            'processed however loaded the machine is (the README table); false = real time at the '
            'camera '
            'rate, frames an estimator cannot keep up with are missed (the speed measurement)',
            'bool',
        ),
        LaunchArg(
            'array_geometry',
            '',
            'photodiode-array sensor YAML: also simulate the array and run '
            "least_squares/tilt_aware on it in namespace 'array' (not evaluated); '' = no array",
        ),
        LaunchArg('exit_when_done', 'true', 'stop the whole graph after the last frame', 'bool'),
        LaunchArg(
            'attitude_source',
            'motion',
            "where the simulator's attitude comes from: motion = the built-in turn (frames "
            'rendered ahead); tf = looked up in TF (tf2_ros) at every stamp, the motion '
            'broadcast there as a robot has it (map -> base_link, base_link -> '
            'camera_optical_frame static), no wheel odometry',
            'str',
            SIM_ATTITUDE_SOURCES,
        ),
        *_COMMON,
    ),
    'compass': (
        LaunchArg('method', 'least_squares', 'heading method', 'str', ALL_METHODS),
        LaunchArg(
            'correction',
            'error_map',
            'tilt correction of the heading',
            'str',
            ('error_map', 'none'),
        ),
        LaunchArg('image_topic', T.IMAGE, 'raw polarizer mosaic (mono8/mono16)'),
        LaunchArg('camera_info_topic', T.CAMERA_INFO, 'camera_info of the mosaic'),
        LaunchArg('imu_topic', T.IMU, 'IMU with orientation (roll/pitch used)'),
        LaunchArg('fix_topic', T.FIX, 'NavSatFix for the site (site_source navsatfix)'),
        LaunchArg(
            'site_source',
            'navsatfix',
            'site from parameters or NavSatFix',
            'str',
            ('parameters', 'navsatfix'),
        ),
        LaunchArg('frame_id', 'base_link', 'frame_id of the published heading (z up)'),
        LaunchArg('namespace', '', 'namespace of the compass nodes'),
        LaunchArg('use_sim_time', 'false', 'use /clock', 'bool'),
        LaunchArg(
            'sky_check',
            'true',
            'check every heading against the whole sky (misfit sigma, 180 deg side, '
            'poor_fit/inconsistent): a real sky is not the model, so a wrong heading is never '
            "'ok' "
            'unchecked (~15-30 ms per image)',
            'bool',
        ),
        _COMMON[0],
    ),
    'fusion': (
        LaunchArg(
            'methods',
            'least_squares',
            'paper methods: an estimator and a corrector each',
            'list',
            PAPER_METHODS,
        ),
        LaunchArg(
            'tilt_aware',
            'true',
            'also run the tilt_aware estimator (IMU tilt, no corrector)',
            'bool',
        ),
        LaunchArg(
            'fuse',
            'least_squares',
            'headings robot_localization fuses, one ekf_node each '
            "(config/ekf_heading_example.yaml with imu0 = that method's corrected heading, "
            "tilt_aware's own): the first is "
            'ekf_filter_node on /odometry/filtered, the others ekf_filter_node_<method> on '
            "/odometry/filtered_<method>; 'none' = one fusing the wheel odometry alone",
            'list',
            tuple(ALL_METHODS) + ('none',),
        ),
        LaunchArg('turns', '1.0', 'full turns to simulate (0: until stopped)', 'float'),
        LaunchArg('turn_rate_deg_s', '10.0', 'turn rate, deg/s', 'float'),
        LaunchArg('pitch_deg', '-20.0', 'camera pitch during the turn', 'float'),
        LaunchArg('roll_deg', '0.0', 'camera roll during the turn', 'float'),
        LaunchArg(
            'odom_yaw_rate_bias_deg_s',
            '0.5',
            "wheel odometry's yaw-rate bias (dead reckoning drifts by it)",
            'float',
        ),
        LaunchArg(
            'odom_yaw_rate_noise_deg_s', '0.2', "wheel odometry's yaw-rate noise, 1 sigma", 'float'
        ),
        LaunchArg('exit_when_done', 'true', 'stop the whole graph after the last frame', 'bool'),
        *_COMMON,
    ),
    'replay': (
        LaunchArg(
            'methods',
            ','.join(PAPER_METHODS),
            'paper methods to run on the bag',
            'list',
            PAPER_METHODS,
        ),
        LaunchArg('tilt_aware', 'true', 'also run the tilt_aware estimator', 'bool'),
        LaunchArg(
            'site_source',
            'navsatfix',
            "site from the bag's NavSatFix or parameters",
            'str',
            ('parameters', 'navsatfix'),
        ),
        _COMMON[0],
        LaunchArg(
            'report_dir', 'out/replay', 'where error_evaluator writes its CSV and PNG report'
        ),
    ),
}


def parse_arg(arg: LaunchArg, text) -> object:
    """
    Return the value of a launch-argument string.

    Parameters
    ----------
    arg : LaunchArg
        The argument's description (its ``kind`` and ``choices``).
    text : str
        The text: bool ``true/false/1/0/yes/no``, a finite float, an int, or a comma-separated
        list.

    Returns
    -------
    bool, float, int, str or list of str
        The value.

    Raises
    ------
    GraphError
        The text cannot be read as the argument's kind, or is (holds) a value outside its choices.

    """
    s = str(text).strip()
    try:
        if arg.kind == 'bool':
            low = s.lower()
            if low not in ('true', 'false', '1', '0', 'yes', 'no'):
                raise ValueError(s)
            return low in ('true', '1', 'yes')
        if arg.kind == 'float':
            v = float(s)
            if v != v or v in (float('inf'), float('-inf')):
                raise ValueError(s)
            return v
        if arg.kind == 'int':
            return int(s)
        if arg.kind == 'list':
            items = [x.strip() for x in s.split(',') if x.strip()]
    except ValueError:
        raise GraphError(
            f'launch argument {arg.name}: cannot read {text!r} as {arg.kind}'
        ) from None
    if arg.kind == 'list':
        bad = [x for x in items if arg.choices and x not in arg.choices]
        if bad:
            raise GraphError(
                f'launch argument {arg.name}: unknown item(s) {bad}; allowed: '
                f'{", ".join(arg.choices)}'
            )
        return items
    if arg.choices and s not in arg.choices:
        raise GraphError(
            f'launch argument {arg.name} must be one of {", ".join(arg.choices)}, got {s!r}'
        )
    return s


def build(name: str, args: dict | None = None) -> Graph:
    """
    Return the graph ``name`` for launch arguments ``args``.

    Parameters
    ----------
    name : str
        One of :data:`GRAPH_NAMES`.
    args : dict, optional
        ``{argument: text}`` (strings, as ``ros2 launch`` passes them); missing ones take their
        default.

    Returns
    -------
    Graph
        The graph (not yet checked: see :meth:`Graph.check`).

    Raises
    ------
    GraphError
        Unknown graph or argument, or an argument that :func:`parse_arg` refuses.

    """
    if name not in ARGUMENTS:
        raise GraphError(f'unknown graph {name!r}; known: {", ".join(GRAPH_NAMES)}')
    args = dict(args or {})
    specs = {a.name: a for a in ARGUMENTS[name]}
    unknown = set(args) - set(specs)
    if unknown:
        raise GraphError(
            f'graph {name!r} has no launch argument(s) {sorted(unknown)}; '
            f'known: {", ".join(sorted(specs))}'
        )
    values = {k: parse_arg(a, args.get(k, a.default)) for k, a in specs.items()}
    return {
        'sim': sim_graph,
        'compass': compass_graph,
        'replay': replay_graph,
        'fusion': fusion_graph,
    }[name](**values)


def node_command(executable: str) -> list[str]:
    """
    Return the command that starts one of the package's node executables outside ``ros2 launch``.

    The console script next to this interpreter (a venv's ``bin``) when it is there, else one on
    ``PATH``, else ``python -m polarization_compass.nodes.<executable>``: on a ROS install the
    scripts live in ``install/lib/polarization_compass``, which is on neither, and the module form
    runs the same ``main``.

    Parameters
    ----------
    executable : str
        Node executable name as in ``setup.py``'s console scripts (e.g. ``"heading_estimator"``).

    Returns
    -------
    list of str
        The argv prefix; append ``--ros-args ...``.

    """
    here = Path(sys.executable).parent / executable
    if here.is_file() and os.access(here, os.X_OK):
        return [str(here)]
    found = shutil.which(executable)
    if found:
        return [found]
    return [sys.executable, '-m', f'{PACKAGE}.nodes.{executable}']


def node_lines(name: str, args: dict | None = None) -> list[str]:
    """
    Return one line per node that graph ``name`` starts: executable and name.

    The launch files quote this list (with the default arguments) in their docstrings, so that a
    reader sees what a launch starts without running it; ``test/test_launch_docs.py`` keeps the
    quoted lists equal to the generated graphs.

    Parameters
    ----------
    name : str
        One of :data:`GRAPH_NAMES`.
    args : dict, optional
        Launch arguments as for :func:`build`.

    Returns
    -------
    list of str
        ``"<executable> [/<namespace>/]<node name>"`` per node.

    """
    return [
        f'{n.executable:<18} {("/" + n.namespace.strip("/") + "/") if n.namespace else ""}{n.name}'
        for n in build(name, args).nodes
    ]


# ------------------------------------------------------------------------------------------------
# The graphs
# ------------------------------------------------------------------------------------------------
def _used(remappings, pubs, subs) -> tuple:
    """Only the remappings of topics the node uses."""
    used = {t for t, _ in pubs} | {t for t, _ in subs}
    return tuple((a, b) for a, b in remappings if a in used)


#: Estimator knobs the graphs set where the method has them (accuracy for time, see docs/ros.md):
#: every 4th superpixel. Set per method (not in the shared parameter file) because the knobs differ
#: by method.
GRAPH_KNOBS = {'knob.stride': 8}


def _knob_names(method: str) -> set:
    from .specs.params import knob_params

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
    pubs, subs = T.estimator_topics(
        method, site_source, needs_tilt=registry.get(method).needs_tilt, prior_source=prior
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


#: robot_localization's parameter file the fusion graph runs ekf_node with: the example users copy
EKF_CONFIG = 'config/ekf_heading_example.yaml'
#: ekf_node's name in EKF_CONFIG (the node the file's parameters are for)
EKF_NODE = 'ekf_filter_node'
#: How long the fusion graph's simulator waits for all its readers before the first frame [s]
FUSION_WAIT_TIMEOUT_S = 600.0


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
                    # every reader, the filters included, before the first frame: a cold numba
                    # cache (a fresh install space) took an estimator 130 s to start under load
                    'wait_timeout_s': FUSION_WAIT_TIMEOUT_S,
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


# ------------------------------------------------------------------------------------------------
# Where the parameter files are
# ------------------------------------------------------------------------------------------------
def share_dir() -> Path:
    """
    Return the package's share directory (``config/``, ``launch/``).

    ``POLARIZATION_COMPASS_SHARE`` if set; else the source tree when this is a source checkout
    (same layout); else the colcon install found through the ament index.

    Returns
    -------
    pathlib.Path
        The directory.

    Raises
    ------
    GraphError
        None of them is found.

    """
    env = os.environ.get('POLARIZATION_COMPASS_SHARE')
    if env:
        return Path(env)
    src = Path(__file__).resolve().parent.parent
    if (src / 'config').is_dir() and (src / 'setup.py').is_file():
        return src  # a source checkout (or an editable install of one)
    try:
        from ament_index_python.packages import get_package_share_directory, PackageNotFoundError

        try:
            return Path(get_package_share_directory(PACKAGE))
        except (PackageNotFoundError, LookupError, ValueError):
            pass
    except ImportError:
        pass
    raise GraphError(
        'cannot find the polarization_compass share directory (config/, launch/): install the '
        'package with colcon or set POLARIZATION_COMPASS_SHARE'
    )


# ------------------------------------------------------------------------------------------------
# ros2 launch
# ------------------------------------------------------------------------------------------------
def launch_description(name: str):
    """
    Return the LaunchDescription of graph ``name`` (used by ``launch/<name>.launch.py``).

    Declares the graph's launch arguments (plus ``large_image_transport``); the nodes are built
    from :func:`build` once the arguments are known (an OpaqueFunction), with the parameter files
    of the installed share directory. When the graph names a node whose exit ends it (the simulator
    with exit_when_done), the launch shuts down with it.

    * ``large_image_transport`` (every graph, default true) points Fast DDS at
      config/fastdds_large_images.xml for the launched nodes unless FASTDDS_DEFAULT_PROFILES_FILE
      is set; the camera driver must publish with the same profile (without it a full-resolution
      camera's best-effort images are lost in fragments: issue 15, docs/ros.md).
    * Every node gets ``sigterm_timeout`` = :data:`STOP_TIMEOUT_S` (the wait of
      ``polarization-compass sim``) and ``sigkill_timeout`` = :data:`SIGKILL_TIMEOUT_S` instead of
      launch's 5 s and 5 s: the evaluator draws its report figure when it stops and ten processes
      share two cores here.

    Parameters
    ----------
    name : str
        One of :data:`GRAPH_NAMES`.

    Returns
    -------
    launch.LaunchDescription
        The argument declarations and the OpaqueFunction that starts the nodes.

    Raises
    ------
    MissingDependencyError
        ``launch`` or ``launch_ros`` is not installed (a ROS 2 install has them).
    GraphError
        Unknown graph; when the launch runs, a bad argument or an inconsistent graph (one line).

    """
    from .errors import MissingDependencyError

    try:
        from launch import LaunchDescription
        from launch.actions import (
            DeclareLaunchArgument,
            EmitEvent,
            OpaqueFunction,
            RegisterEventHandler,
            SetEnvironmentVariable,
        )
        from launch.event_handlers import OnProcessExit
        from launch.events import Shutdown
        from launch.substitutions import LaunchConfiguration
        from launch_ros.actions import Node
    except ImportError:
        raise MissingDependencyError(
            'ros2 launch (launch, launch_ros)',
            'ros-<distro>-launch-ros (e.g. sudo apt install ros-jazzy-launch-ros); '
            "here, 'polarization-compass sim' runs the sim graph without it",
        ) from None
    if name not in ARGUMENTS:
        raise GraphError(f'unknown graph {name!r}; known: {", ".join(GRAPH_NAMES)}')
    actions = [
        DeclareLaunchArgument(
            a.name,
            default_value=a.default,
            description=a.description + (f' ({", ".join(a.choices)})' if a.choices else ''),
        )
        for a in ARGUMENTS[name]
    ]
    actions.append(
        DeclareLaunchArgument(
            'large_image_transport',
            default_value='true',
            description="set FASTDDS_DEFAULT_PROFILES_FILE to the package's shared-memory profile "
            'for '
            'full-resolution images (unless already set); false when the camera is on another '
            'machine: the profile carries data over shared memory only',
        )
    )

    def make_nodes(context, *_, **__):
        values = {a.name: LaunchConfiguration(a.name).perform(context) for a in ARGUMENTS[name]}
        graph = build(name, values)
        problems = graph.check()
        if problems:
            raise GraphError('inconsistent graph: ' + '; '.join(problems))
        share = share_dir()
        out = []
        if parse_arg(
            LaunchArg('large_image_transport', 'true', '', 'bool'),
            LaunchConfiguration('large_image_transport').perform(context),
        ) and not os.environ.get('FASTDDS_DEFAULT_PROFILES_FILE'):
            out.append(
                SetEnvironmentVariable(
                    'FASTDDS_DEFAULT_PROFILES_FILE', str(share / FASTDDS_PROFILE)
                )
            )
        by_name = {}
        for n in graph.nodes:
            node = Node(
                package=n.package,
                executable=n.executable,
                name=n.name,
                namespace=n.namespace or None,
                parameters=[str(share / f) for f in n.param_files] + [dict(n.parameters)],
                remappings=list(n.remappings),
                output='screen',
                emulate_tty=True,
                # a node stops in < 1 s, the evaluator draws its figure first, ten processes
                # share two cores: launch's default 5 s before SIGTERM was too short (issue 15)
                sigterm_timeout=str(STOP_TIMEOUT_S),
                sigkill_timeout=str(SIGKILL_TIMEOUT_S),
            )
            by_name[n.name] = node
            out.append(node)
        if graph.shutdown_with:
            out.append(
                RegisterEventHandler(
                    OnProcessExit(
                        target_action=by_name[graph.shutdown_with],
                        on_exit=[
                            EmitEvent(event=Shutdown(reason=f'{graph.shutdown_with} finished'))
                        ],
                    )
                )
            )
        return out

    actions.append(OpaqueFunction(function=make_nodes))
    return LaunchDescription(actions)
