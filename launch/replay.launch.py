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
Live replay of a recorded run: every estimator, corrector and the evaluator on sim time.

    ros2 launch polarization_compass replay.launch.py bag:=RUN_BAG report_dir:=out/replay

starts the graph and the real ``ros2 bag play RUN_BAG --clock`` (paused), resumes the player once
every node of the graph has said it is ready (a node's last start-up log line: kernels compiled,
subscriptions made), and ends the launch once the bag has played and the evaluator's current
report has not changed for ``drain_s`` seconds, 10 s at least; the evaluator then writes its
report (``evaluation_summary.json`` & co) into ``report_dir``. The player gets the launch's
environment, so the shared-memory Fast DDS profile of ``large_image_transport`` (full-resolution
images are lost in fragments without it, and every local participant discovers every other
through it).

Flow control: the ``player_flow`` node pauses the player while an estimator is ``high_water``
frames behind and resumes it once all are within ``low_water`` (the player's own pause and resume
services; its ``/clock`` stops with it). A slow estimator therefore holds a few images, not the
whole bag, and loses none: a 12 s full-resolution bag (120 images of 10 MB) at ``rate:=1`` and
``rate:=2`` on 2 cores scored 120 of 120 frames in every stream (21 lost without it). Frames lost
anyway are counted as ``not_received`` in the report.

Without ``bag`` the graph waits for a player started by hand, before or after the launch, with the
same profile, bag path first (``--clock`` takes an optional rate and would swallow a path after
it), and paused: the launch resumes it once the graph is ready and flow-controls it the same way
(a player that is not paused publishes its first frames before anyone listens):

    ros2 launch polarization_compass replay.launch.py report_dir:=out/replay
    SHARE=$(ros2 pkg prefix polarization_compass)/share/polarization_compass
    export FASTDDS_DEFAULT_PROFILES_FILE=$SHARE/config/fastdds_large_images.xml
    ros2 bag play RUN_BAG --clock --start-paused     # in a second terminal, before or after

The offline equivalent (no ROS install needed): `polarization-compass replay RUN_BAG`.

Nodes started with the default arguments (generated from polarization_compass.graphs;
test/test_launch_docs.py keeps this list current; `--show-args` lists the arguments):

    heading_estimator  heading_estimator_zenith
    heading_estimator  heading_estimator_sm_asm
    heading_estimator  heading_estimator_symmetry
    heading_estimator  heading_estimator_least_squares
    heading_estimator  heading_estimator_tilt_aware
    tilt_corrector     tilt_corrector_zenith
    tilt_corrector     tilt_corrector_sm_asm
    tilt_corrector     tilt_corrector_symmetry
    tilt_corrector     tilt_corrector_least_squares
    error_evaluator    error_evaluator

The nodes, parameter files and remappings come from polarization_compass.graphs (the single
description of each graph); launch and launch_ros are imported only when the launch runs.
"""

#: The last line each node logs at start-up (its subscriptions exist, its kernels are compiled):
#: ``[<node name>]: <text>``. The player is resumed when every node of the graph has logged it.
READY_LINES = {
    'heading_estimator': r'method \w+: \S+ from ',
    'tilt_corrector': r'\S+ \+ \S+ -> \S+ \(.*site from ',
    'error_evaluator': r'evaluating \d+ stream\(s\)',
}
PLAYER_NODE = '/rosbag2_player'
#: Resumes the paused player through its service (rosbag2_interfaces/srv/Resume) once it is
#: discovered; ``ros2 service call`` does the same where ros2cli has the ``service`` verb.
RESUME_SCRIPT = """
import sys
import rclpy
from rosbag2_interfaces.srv import Resume
rclpy.init()
node = rclpy.create_node('replay_resume_player')
client = node.create_client(Resume, sys.argv[1])
while not client.wait_for_service(timeout_sec=2.0):
    node.get_logger().info('waiting for ' + sys.argv[1])
future = client.call_async(Resume.Request())
rclpy.spin_until_future_complete(node, future, timeout_sec=30.0)
node.get_logger().info('player resumed' if future.done() else 'no answer from ' + sys.argv[1])
code = 0 if future.done() else 1
node.destroy_node()
rclpy.shutdown()
sys.exit(code)
"""
#: Launch arguments of the player (added to the replay graph's own, polarization_compass.graphs).
PLAYER_ARGUMENTS = (
    ('bag', '', "rosbag2 to play with 'ros2 bag play BAG --clock' ('' = none: play it by hand)"),
    ('rate', '1.0', "the player's --rate (0.5 = half speed, 2 = twice real time)"),
    ('settle_s', '1.0', 'wall seconds between the last node ready and resuming the player'),
    (
        'high_water',
        '6',
        'player_flow pauses the player when an estimator is this many frames behind',
    ),
    ('low_water', '2', 'and resumes it when every estimator is within this many frames'),
    (
        'drain_s',
        '10.0',
        'after the bag has played, the launch ends once the report has not changed for this [s]',
    ),
)
#: Longest wait after the bag has played for the estimators' queues to drain [s]
DRAIN_LIMIT_S = 1800.0


def _positive(name: str, text: str, allow_zero: bool = False) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float('nan')
    if not (v > 0 or (allow_zero and v == 0)) or v == float('inf'):
        from polarization_compass.graphs import GraphError

        raise GraphError(f'launch argument {name}: expected a positive number, got {text!r}')
    return v


def _player(context):
    """
    Return the graph's player actions: resume once ready, flow control, the player (bag given).

    Without ``bag``, a player started by hand (``--start-paused``, before or after the launch)
    is resumed once the graph is ready and flow-controlled the same way; the launch runs until
    stopped.
    """
    from pathlib import Path
    import re

    from launch.substitutions import LaunchConfiguration
    from polarization_compass.graphs import ARGUMENTS, build, GraphError

    def arg(name):
        return LaunchConfiguration(name).perform(context)

    bag = arg('bag').strip()
    if bag and not (Path(bag) / 'metadata.yaml').is_file() and not Path(bag).is_file():
        raise GraphError(f'launch argument bag: {bag!r} is not a rosbag2 (no metadata.yaml)')
    settle_s = _positive('settle_s', arg('settle_s'), allow_zero=True)
    graph = build('replay', {a.name: arg(a.name) for a in ARGUMENTS['replay']})
    patterns = {
        n.name: re.compile(rf'\[{n.name}\]: {READY_LINES[n.executable]}') for n in graph.nodes
    }
    water = {k: int(_positive(k, arg(k), allow_zero=True)) for k in ('high_water', 'low_water')}
    actions = _resume_when_ready(patterns, settle_s) + [_flow_control(graph, **water)]
    if not bag:
        return actions
    rate = _positive('rate', arg('rate'))
    drain_s = _positive('drain_s', arg('drain_s'), allow_zero=True)
    return actions + _play(bag, rate, Path(arg('report_dir')), drain_s)


def _resume_when_ready(patterns, settle_s) -> list:
    """Return the actions that resume the player once every node of the graph has logged ready."""
    import sys

    from launch.actions import EmitEvent, ExecuteProcess, RegisterEventHandler
    from launch.event_handlers import OnProcessExit, OnProcessIO
    from launch.events import Shutdown

    resume = ExecuteProcess(
        cmd=[sys.executable, '-c', RESUME_SCRIPT, f'{PLAYER_NODE}/resume'],
        name='resume_player',
        output='screen',
    )
    on_output = _ready_watcher(patterns, settle_s, resume)

    def on_resume_exit(event, _context):
        if event.returncode != 0:
            return [EmitEvent(event=Shutdown(reason='the player could not be resumed'))]
        return None

    return [
        RegisterEventHandler(OnProcessIO(on_stdout=on_output, on_stderr=on_output)),
        RegisterEventHandler(OnProcessExit(target_action=resume, on_exit=on_resume_exit)),
    ]


def _play(bag: str, rate: float, report_dir, drain_s: float) -> list:
    """Return the paused player of ``bag`` and the handler that ends the launch after it."""
    from launch.actions import (
        EmitEvent,
        ExecuteProcess,
        LogInfo,
        OpaqueFunction,
        RegisterEventHandler,
    )
    from launch.event_handlers import OnProcessExit
    from launch.events import Shutdown

    player = ExecuteProcess(
        cmd=[
            'ros2',
            'bag',
            'play',
            bag,
            '--clock',
            '--rate',
            str(rate),
            '--start-paused',
            '--disable-keyboard-controls',
        ],
        name='ros2_bag_play',
        output='screen',
        sigterm_timeout='5',
    )
    quiet_s, drained = _drain_watcher(report_dir, drain_s)

    def on_player_exit(event, _context):
        if event.returncode != 0:
            return [EmitEvent(event=Shutdown(reason=f'ros2 bag play failed ({event.returncode})'))]
        return [
            LogInfo(
                msg=f'replay: the bag has played; stopping when the report has not changed for '
                f'{quiet_s:g} s (drain_s, at least two report periods)'
            ),
            OpaqueFunction(function=drained),
        ]

    return [
        RegisterEventHandler(OnProcessExit(target_action=player, on_exit=on_player_exit)),
        player,
    ]


def _flow_control(graph, high_water: int, low_water: int):
    """Return the ``player_flow`` node that pauses the player while an estimator is behind."""
    from launch_ros.actions import Node
    from polarization_compass.specs import topics

    status = [
        topics.method_topics(n.parameters['method'])['status']
        for n in graph.nodes
        if n.executable == 'heading_estimator'
    ]
    return Node(
        package='polarization_compass',
        executable='player_flow',
        name='player_flow',
        parameters=[
            {
                'status_topics': status,
                'player': PLAYER_NODE,
                'high_water': high_water,
                'low_water': low_water,
            }
        ],
        output='screen',
        sigterm_timeout='5',
    )


def _ready_watcher(patterns, settle_s, resume):
    """Return the output handler that resumes the player once every node logged ready."""
    from launch.actions import LogInfo, TimerAction

    ready: set = set()
    tails: dict = {}

    def on_output(event):
        if len(ready) == len(patterns):
            return None
        key = id(event.action)  # a line may arrive in two pieces: search a short tail
        text = (tails.get(key, '') + event.text.decode(errors='replace'))[-4096:]
        tails[key] = text
        for name, pat in patterns.items():
            if name not in ready and pat.search(text):
                ready.add(name)
        if len(ready) < len(patterns):
            return None
        return [
            LogInfo(
                msg=f'replay: all {len(patterns)} nodes ready; resuming the player in '
                f'{settle_s:g} s'
            ),
            TimerAction(period=settle_s, actions=[resume]),
        ]

    return on_output


def _drain_watcher(report_dir, drain_s):
    """Return the quiet time and the check that ends the launch once the report settles."""
    from launch.actions import EmitEvent, LogInfo, OpaqueFunction, TimerAction
    from launch.events import Shutdown
    from polarization_compass.nodes.error_evaluator import REPORT_PERIOD_S

    summary = report_dir / 'evaluation_summary.json'  # the evaluator's current one
    # the current report is rewritten at most every REPORT_PERIOD_S: quiet for two periods at least
    quiet_s = max(drain_s, 2.0 * REPORT_PERIOD_S)
    last = {'stamp': None, 'since': 0.0, 'waited': 0.0}

    def drained(_context):
        # the estimators may still be working through their image queues (image_qos replay):
        # stop once the evaluator's current report has not changed for quiet_s
        try:
            st = summary.stat()
            stamp = (st.st_mtime_ns, st.st_size)
        except OSError:
            stamp = None
        if stamp != last['stamp']:
            last['stamp'], last['since'] = stamp, 0.0
        if last['since'] >= quiet_s or last['waited'] >= DRAIN_LIMIT_S:
            return [
                LogInfo(msg=f'replay: no new result for {last["since"]:g} s; stopping'),
                EmitEvent(event=Shutdown(reason='bag played')),
            ]
        last['since'] += 1.0
        last['waited'] += 1.0
        return [TimerAction(period=1.0, actions=[OpaqueFunction(function=drained)])]

    return quiet_s, drained


def generate_launch_description():
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from polarization_compass.graphs import launch_description

    ld = launch_description('replay')
    for name, default, description in PLAYER_ARGUMENTS:
        ld.add_action(DeclareLaunchArgument(name, default_value=default, description=description))
    # after the graph's actions: the player inherits FASTDDS_DEFAULT_PROFILES_FILE set there
    ld.add_action(OpaqueFunction(function=lambda context: _player(context)))
    return ld
