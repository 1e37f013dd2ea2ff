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
Live replay: a recorded bag published through the real nodes of the replay graph.

The graph is graphs.build("replay") (heading_estimator per method, tilt_corrector, error_evaluator)
on DDS (loopback, the test's own domain id), with use_sim_time and /clock from the bag, as `ros2
bag play --clock` would. The nodes' errors (the evaluator's report) must equal the offline
replay's, frame by frame and stream by stream.
"""

import csv
from pathlib import Path
import subprocess
import time

import numpy as np
from polarization_compass import bag as B
from polarization_compass.camera import CameraModel
from polarization_compass.conventions import CameraAttitude
from polarization_compass.graphs import node_command
from polarization_compass.recording import record_sim, RecordSpec
from polarization_compass.replay import replay_bag, ReplayConfig
from polarization_compass.scene_load import load_scene
import pytest
from test_nodes_helpers import stop_process

pytestmark = [pytest.mark.ros, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
STRIDE = 2  # knob.stride of the nodes and of the offline replay
CAMERA = CameraModel(
    width_px=96,
    height_px=80,
    focal_length_mm=4.0,
    pixel_pitch_x_um=2448 * 3.45 / 96,
    pixel_pitch_y_um=2048 * 3.45 / 80,
)


class _Node:
    """A node of the replay graph running as a process."""

    def __init__(self, spec, share, extra, env, log_dir):
        self.name = spec.name
        self.log = open(log_dir / f'{spec.name}.log', 'w')
        self.p = subprocess.Popen(
            [*node_command(spec.executable), *spec.ros_arguments(share), *extra],
            env=env,
            stdout=self.log,
            stderr=subprocess.STDOUT,
        )
        self.path = log_dir / f'{spec.name}.log'

    def alive(self):
        return self.p.poll() is None

    def stop(self, timeout=30.0):
        return stop_process(self.p, timeout, self.log)

    def text(self):
        return self.path.read_text(errors='replace')


def _ns(text: str) -> int:
    """
    Return a stamp from evaluation_samples.csv.

    It is written as float seconds (stamp_ns / 1e9, 9 decimals), which is only good to ~0.2 us at
    today's epoch: round to the microsecond (the stamps here are whole multiples of 100 ms).
    """
    sec, _, frac = text.partition('.')
    ns = int(sec) * 1_000_000_000 + int(frac.ljust(9, '0')[:9])
    return (ns + 500) // 1000 * 1000


@pytest.fixture(scope='module')
def run_and_map(tmp_path_factory):
    """
    Record a 2 s turn at pitch -20 and a least-squares error map around it.

    The sun is ~30 deg high.
    """
    from polarization_compass.sweep import run_sweep, SweepSpec

    d = tmp_path_factory.mktemp('live')
    scene = load_scene(None).replace(camera=CAMERA, attitude=CameraAttitude(200.0, 0.0, 0.0))
    record_sim(scene, RecordSpec(duration_s=2.0, rate_hz=10.0, turns=0.5), d / 'bag')
    spec = SweepSpec(
        methods=('least_squares',),
        sun_altitude_deg=np.array([28.0, 33.0]),
        yaw_deg=np.arange(-180.0, 180.0, 30.0),
        pitch_deg=np.array([-22.0, -18.0]),
        roll_deg=np.array([-2.0, 2.0]),
        scene=scene,
        full_domain=True,
        knobs={'least_squares': {'stride': 2}},
    )
    run_sweep(spec, out=d / 'map.npz', workers=1, progress=False)
    return d / 'bag', d / 'map.npz'


def test_nodes_give_the_offline_replay_errors(run_and_map, ros_env, tmp_path):
    from polarization_compass import graphs

    bag_path, map_path = run_and_map
    methods = ('least_squares', 'tilt_aware')
    offline = replay_bag(
        bag_path,
        ReplayConfig(methods=methods, knobs={'*': {'stride': STRIDE}}, error_map=str(map_path)),
    )
    assert (
        offline.summary['least_squares/corrected']['count'] == 20
    )  # the comparison has substance

    env = dict(ros_env, NUMBA_NUM_THREADS='1')
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    report = tmp_path / 'report'
    logs = tmp_path / 'logs'
    logs.mkdir()
    g = graphs.build(
        'replay',
        {
            'methods': 'least_squares',
            'tilt_aware': 'true',
            'error_map': str(map_path),
            'report_dir': str(report),
        },
    )
    share = graphs.share_dir()
    nodes = []
    try:
        for spec in g.nodes:
            extra = (
                ['-p', f'knob.stride:={STRIDE}'] if spec.executable == 'heading_estimator' else []
            )
            nodes.append(_Node(spec, share, extra, env, logs))
        codes = _play(nodes, bag_path, env, methods)
    finally:
        for n in nodes:  # never leave a node behind, whatever failed
            if n.alive():
                n.stop()
    assert all(c == 0 for c in codes.values()), {n.name: n.text()[-1500:] for n in nodes}
    _compare(report, offline)


def _play(nodes, bag_path, env, methods) -> dict:
    """
    Publish the bag through the running nodes, stop them and return their exit codes.

    The nodes run in lockstep per image.
    """
    import json
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter('ignore', DeprecationWarning)
        import rosidl_generator_py  # noqa: F401
    from polarization_compass.specs import topics as T
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import CameraInfo, Image, Imu, NavSatFix
    from std_msgs.msg import String

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=int(env['ROS_DOMAIN_ID']))
    player = Node('bag_player', context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(player)
    statuses = {m: set() for m in methods}
    corrections = set()

    def on_status(m, msg):
        statuses[m].add(int(json.loads(msg.data)['stamp_ns']))

    def on_corr(msg):
        corrections.add(int(json.loads(msg.data)['stamp_ns']))

    for m in methods:
        player.create_subscription(
            String,
            T.method_topics(m)['status'],
            lambda msg, m=m: on_status(m, msg),
            QoSProfile(depth=100),
        )
    player.create_subscription(
        String,
        T.method_topics('least_squares')['correction_status'],
        on_corr,
        QoSProfile(depth=100),
    )
    tm = B.default_topic_map()
    types = {
        'image': Image,
        'camera_info': CameraInfo,
        'imu': Imu,
        'reference': Imu,
        'navsatfix': NavSatFix,
    }
    # what `ros2 bag play` does: the recorded CDR bytes, on the recorded topic names, default QoS
    pubs = {
        role: player.create_publisher(types[role], tm.spec(role).topic, QoSProfile(depth=100))
        for role in types
    }
    clock = player.create_publisher(Clock, T.CLOCK, QoSProfile(depth=10))

    def spin_until(cond, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return True
            dead = [n.name for n in nodes if not n.alive()]
            assert not dead, {
                n: next(x for x in nodes if x.name == n).text()[-2000:] for n in dead
            }
            ex.spin_once(timeout_sec=0.02)
        return cond()

    try:
        # every node subscribed before the first message (a player waits for its subscribers too)
        ok = spin_until(
            lambda: (
                pubs['image'].get_subscription_count() >= 2
                and pubs['imu'].get_subscription_count() >= 3
                and pubs['reference'].get_subscription_count() >= 1
            ),
            120,
        )
        assert ok, 'nodes did not come up: ' + ' | '.join(n.text()[-500:] for n in nodes)
        spin_until(lambda: False, 1.0)
        images = 0
        with B.BagReader(bag_path) as r:
            for topic, mtype, log_ns, raw in r.messages([s.topic for s in tm.topics.values()]):
                role = tm.role_of_topic(topic)
                sec, nsec = divmod(log_ns, 1_000_000_000)
                c = Clock()
                c.clock.sec, c.clock.nanosec = int(sec), int(nsec)
                clock.publish(c)
                pubs[role].publish(bytes(raw))
                ex.spin_once(timeout_sec=0.0)
                if role == 'image':
                    images += 1
                    t = B.stamp_ns(B.deserialize(raw, mtype).header)
                    # lockstep: the next message only when every estimator answered this image
                    assert spin_until(lambda: all(t in s for s in statuses.values()), 60), (
                        f'no answer to {t}'
                    )
                else:
                    spin_until(lambda: False, 0.002)
        assert images == 20
        assert spin_until(lambda: len(corrections) >= 20, 30), f'{len(corrections)} corrections'
        spin_until(lambda: False, 1.0)
    finally:
        codes = {n.name: n.stop() for n in nodes}
        ex.shutdown()
        player.destroy_node()
        rclpy.try_shutdown(context=ctx)
    return codes


def _compare(report, offline) -> None:
    import json

    with open(report / 'evaluation_samples.csv') as f:
        live = {
            (row['stream'], _ns(row['stamp_s'])): float(row['error_deg'])
            for row in csv.DictReader(f)
        }
    want = {}
    for r in offline.rows:
        if r.raw_error_deg is not None:
            want[(f'{r.method}/raw', r.stamp_ns)] = r.raw_error_deg
        if r.corrected_error_deg is not None:
            want[(f'{r.method}/corrected', r.stamp_ns)] = r.corrected_error_deg
    assert len(want) == 60  # 20 frames x 3 streams
    assert set(live) == set(want)
    diffs = np.array([live[k] - want[k] for k in want])
    assert np.abs(diffs).max() < 2e-6, diffs  # the CSV keeps 6 decimals
    # the statistics agree too
    js = json.loads((report / 'evaluation_summary.json').read_text())['streams']
    for name, s in offline.summary.items():
        assert js[name]['count'] == s['count'] and js[name]['rms'] == pytest.approx(
            s['rms'], abs=1e-6
        )
