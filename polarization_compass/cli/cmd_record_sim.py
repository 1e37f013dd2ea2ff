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

"""`polarization-compass record-sim`: a synthetic field run written to a rosbag2 (MCAP/sqlite3)."""

from __future__ import annotations

import json

from ._progress import advance_to, progress_bar
from ..errors import CompassError


def register(sub):
    p = sub.add_parser(
        'record-sim',
        help='write a synthetic field run to a rosbag2 as a real rig records it',
        description="Render a field run of a scene (a full turn at a fixed tilt, like the paper's "
        'Fig 17) and write it as `ros2 bag record` would: raw polarizer mosaic + '
        'camera_info, IMU, reference heading (dual-antenna GNSS form) and NavSatFix. '
        'Topic names: config/replay_topics.yaml (or --topics).',
    )
    _add_run_options(p)
    _add_sensor_options(p)
    p.set_defaults(func=run)


def _add_run_options(p) -> None:
    """Add the run: scene, length, output bag, frame rate and encoding, tilt and turns."""
    p.add_argument(
        '--scene',
        help='scene YAML: site, start time, camera, sky, sensor effects; its attitude gives '
        "the start bearing and, if tilted, the tilt (default: the paper's set-up)",
    )
    p.add_argument(
        '--duration', type=float, required=True, metavar='S', help='length of the run, seconds'
    )
    p.add_argument(
        '--out', required=True, metavar='BAG', help='output rosbag2 directory (must not exist)'
    )
    p.add_argument(
        '--storage',
        choices=('mcap', 'sqlite3'),
        default='mcap',
        help='rosbag2 storage (default mcap, as ros2 bag record on Jazzy/Kilted)',
    )
    p.add_argument(
        '--rate', type=float, default=10.0, metavar='HZ', help='camera frame rate (default 10)'
    )
    p.add_argument(
        '--encoding', choices=('mono16', 'mono8'), default='mono16', help='image encoding'
    )
    p.add_argument(
        '--pitch',
        type=float,
        help="camera pitch, deg (default: the scene's tilt, else -20 as Fig 17)",
    )
    p.add_argument(
        '--roll', type=float, help="camera roll, deg (default: the scene's tilt, else 0)"
    )
    p.add_argument(
        '--turns',
        type=float,
        default=1.0,
        help='turns over the run, clockwise positive (default 1)',
    )


def _add_sensor_options(p) -> None:
    """Add the other sensors (IMU, reference heading), the topic names and the noise seed."""
    p.add_argument(
        '--imu-rate', type=float, default=50.0, metavar='HZ', help='IMU rate (default 50)'
    )
    p.add_argument(
        '--imu-noise',
        type=float,
        default=0.05,
        metavar='DEG',
        help='IMU roll/pitch noise, 1 sigma',
    )
    p.add_argument(
        '--reference-noise',
        type=float,
        default=0.1,
        metavar='DEG',
        help='reference heading noise, 1 sigma (default 0.1: a 2 m dual-antenna GNSS)',
    )
    p.add_argument(
        '--reference-rate',
        type=float,
        metavar='HZ',
        help="reference on the receiver's own epochs at this rate (default: with every image)",
    )
    p.add_argument(
        '--topics',
        metavar='MAPPING.yaml',
        help='topic names to write (default: the replay defaults)',
    )
    p.add_argument('--seed', type=int, default=0, help='noise seed')


def run(args) -> int:
    from ..bag import load_topic_map
    from ..recording import record_sim, RecordSpec
    from ..scene_load import load_scene

    if args.seed < 0:
        raise CompassError(f'--seed must be >= 0, got {args.seed}')
    scene = load_scene(args.scene)
    spec = RecordSpec(
        duration_s=args.duration,
        rate_hz=args.rate,
        storage=args.storage,
        encoding=args.encoding,
        pitch_deg=args.pitch,
        roll_deg=args.roll,
        turns=args.turns,
        imu_rate_hz=args.imu_rate,
        imu_attitude_noise_deg=args.imu_noise,
        reference_noise_deg=args.reference_noise,
        reference_rate_hz=args.reference_rate,
        seed=args.seed,
    )
    tm = load_topic_map(args.topics)
    with progress_bar('record-sim', ' frames') as bar:
        summary = record_sim(scene, spec, args.out, tm, lambda k, n: advance_to(bar, k, n))
    summary.pop('truth')
    print(json.dumps(summary, indent=1))
    return 0
