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
`polarization-compass sim` (`make sim`): the ROS 2 sim graph without `ros2 launch`.

Starts every node of :func:`polarization_compass.graphs.sim_graph` as its own process (the console
scripts, with the graph's parameter files, parameters and remappings: exactly what ``ros2 launch
polarization_compass sim.launch.py`` starts), runs the default scene (one full turn at pitch -20
deg, the paper's Fig 17 set-up) to completion, stops every node with SIGINT, and prints the
per-method table of raw and corrected heading errors from the evaluator's report.

DDS stays on this machine: ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, and the Fast DDS shared-memory
profile for full-resolution images (config/fastdds_large_images.xml) unless the environment names
another profile. By default the simulator runs in lockstep (it waits for every estimator before the
next frame), so every frame is processed however loaded the machine is; ``--realtime`` runs at the
camera rate and reports dropped frames and latency instead (the speed benchmark).

``--ekf`` runs the ``fusion`` graph instead (what ``ros2 launch polarization_compass
fusion.launch.py`` starts): the sim graph plus robot_localization's ``ekf_node`` configured from
``config/ekf_heading_example.yaml``, fusing the simulated wheel odometry and the heading(s) named
by ``--fuse``; the table then has a ``fused`` row per filter (``odometry fused``: the odometry
alone). ``ekf_node`` is found through the ament index (a sourced ROS install, or ``source
.venv/opt/ros-cpp/setup.bash`` after ``../shared/ros-cpp/install.sh .venv``); without it the
command says what to install and exits 2 before starting anything.
"""

from __future__ import annotations

import math
from pathlib import Path
import subprocess
import sys

from ..errors import CompassError
from ..graphs.processes import _child_env, _run_graph, foreign_executable


def register(sub):
    p = sub.add_parser(
        'sim',
        help='run the ROS 2 sim graph (simulator, estimators, correctors, evaluator)',
        description='Start the sim node graph as processes (no ros2 launch needed), simulate a '
        'full turn at pitch -20 deg, print raw and corrected errors per method.',
    )
    from ..estimators import registry

    p.add_argument(
        '--methods',
        default=None,
        help='paper methods, comma separated (each gets an estimator and a corrector); '
        'unavailable ones are skipped with a note (default: '
        f'{",".join(registry.paper_methods())}; with --ekf least_squares)',
    )
    p.add_argument(
        '--no-tilt-aware',
        action='store_true',
        help=f'do not run the {", ".join(registry.tilt_methods())} estimator',
    )
    p.add_argument('--encoding', default='mono16', choices=('mono16', 'mono8', '32FC1'))
    p.add_argument('--rate', type=float, default=10.0, help='camera frame rate, Hz (default 10)')
    p.add_argument('--turns', type=float, default=1.0, help='full turns (default 1)')
    p.add_argument(
        '--turn-rate', type=float, default=10.0, help='deg/s (default 10: 36 s per turn)'
    )
    p.add_argument('--pitch', type=float, default=-20.0, help='camera pitch, deg (default -20)')
    p.add_argument('--roll', type=float, default=0.0, help='camera roll, deg (default 0)')
    p.add_argument(
        '--time-scale', type=float, default=1.0, help='simulated seconds per wall second'
    )
    p.add_argument('--scene', default='', help='scene YAML for camera, sky and sensor')
    p.add_argument(
        '--array-geometry',
        default='',
        help='photodiode-array sensor YAML: also simulate the array and run its estimators in '
        'namespace '
        "array (their headings are not in the evaluator's table)",
    )
    p.add_argument(
        '--attitude-source',
        default='motion',
        choices=('motion', 'tf'),
        help="the simulator's attitude: the built-in motion (default), or looked up in TF at "
        'every stamp with the motion broadcast there (needs tf2_ros; docs/ros.md)',
    )
    p.add_argument(
        '--realtime',
        action='store_true',
        help='no lockstep: frames at the camera rate; measures drops and latency',
    )
    p.add_argument(
        '--error-map',
        default='',
        help='error map for the correctors (default: the shipped map, else OUT/error_map.npz, '
        'built for this scenario when missing)',
    )
    p.add_argument(
        '--ekf',
        action='store_true',
        help="run the fusion graph: also robot_localization's ekf_node (config/"
        'ekf_heading_example.yaml) fusing the simulated wheel odometry and the --fuse heading(s); '
        'needs ekf_node (ament index)',
    )
    p.add_argument(
        '--fuse',
        default='least_squares',
        help="with --ekf: headings fused, one ekf_node each, comma separated ('none': the "
        'odometry alone; default least_squares)',
    )
    p.add_argument(
        '--out', default=None, help='report directory (default out/sim; with --ekf out/fusion)'
    )
    p.add_argument(
        '--timeout', type=float, default=1800.0, help='give up after this many wall seconds'
    )
    p.set_defaults(func=run)


def _available_methods(wanted: list[str]) -> tuple[list[str], list[str]]:
    from ..estimators import estimator_names

    known = set(estimator_names())
    return [m for m in wanted if m in known], [m for m in wanted if m not in known]


def scenario_sun_altitudes(
    start_time_utc: str, duration_s: float, site: tuple
) -> tuple[float, float]:
    """Lowest and highest sun altitude (deg) during the run."""
    import numpy as np

    from ..bag import ns_from_utc
    from ..scene import parse_time_utc
    from ..solar import sun_position

    t0 = ns_from_utc(parse_time_utc(start_time_utc))
    ts = np.datetime64(t0 // 1000, 'us') + (
        np.linspace(0.0, max(duration_s, 1.0), 16) * 1e6
    ).astype('timedelta64[us]')
    p = sun_position(ts, *site)
    return float(np.min(p.altitude_deg)), float(np.max(p.altitude_deg))


def ensure_error_map(
    path: Path, methods: list[str], pitch: float, roll: float, alt_range: tuple, env: dict
) -> None:
    """
    Build a small error map around the scenario when ``path`` does not exist.

    The map covers the run's sun altitudes, pitch and roll (every yaw), computed by the errormap
    command. Cubic interpolation needs 4 nodes per axis.
    """
    if path.is_file():
        return

    def span(lo, hi, step=5.0, margin=5.0):
        a = math.floor((lo - margin) / step) * step
        b = math.ceil((hi + margin) / step) * step
        while (b - a) / step < 3:
            b += step
        return a, b

    a0, a1 = span(max(alt_range[0], 0.0), min(alt_range[1], 85.0))
    a0 = max(a0, 0.0)
    p0, p1 = span(pitch, pitch, margin=10.0)
    r0, r1 = span(roll, roll, margin=10.0)
    cmd = [
        sys.executable,
        '-m',
        'polarization_compass.cli',
        'errormap',
        '--methods',
        ','.join(methods),
        '--sun-altitude',
        f'{a0:g}:{a1:g}:5',
        '--yaw',
        '-180:175:5',
        '--pitch',
        f'{p0:g}:{p1:g}:5',
        '--roll',
        f'{r0:g}:{r1:g}:5',
        '--out',
        str(path),
    ]
    print(
        f'sim: no error map at {path}: building one for this scenario (runs once):\n  '
        f'{" ".join(cmd[2:])}',
        flush=True,
    )
    rc = subprocess.call(cmd, env=env)
    if rc != 0 or not path.is_file():
        raise CompassError(
            f'building the error map failed (exit {rc}); run the command above by hand'
        )


#: What --ekf needs and where it comes from (the one-line error of a missing ekf_node).
EKF_MISSING = (
    "--ekf needs robot_localization's ekf_node, which the ament index does not find: here run "
    '../shared/ros-cpp/install.sh .venv and source .venv/opt/ros-cpp/setup.bash; on a robot apt '
    'install ros-<distro>-robot-localization and source /opt/ros/<distro>/setup.bash'
)

#: The sim options the fusion graph does not take, with their defaults (refused with --ekf).
_NOT_WITH_EKF = (
    ('encoding', '--encoding', 'mono16'),
    ('rate', '--rate', 10.0),
    ('time_scale', '--time-scale', 1.0),
    ('scene', '--scene', ''),
    ('realtime', '--realtime', False),
    ('array_geometry', '--array-geometry', ''),
    ('attitude_source', '--attitude-source', 'motion'),
)


# ------------------------------------------------------------------------------------------------
def run(args) -> int:
    from .. import graphs

    _check_ekf_options(args)
    _check_numbers(args)
    methods, tilt_aware = _selected_methods(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for old in (
        'evaluation_summary.json',
        'evaluation_summary.csv',
        'evaluation_samples.csv',
        'evaluation.png',
    ):
        (out / old).unlink(missing_ok=True)
    env = _child_env(out)
    map_path = _error_map_path(args, out)
    if methods:
        _ensure_map(args, methods, map_path, env)
    if args.ekf:
        graph = _fusion_graph(graphs, args, methods, tilt_aware, map_path, out)
    else:
        graph = _sim_graph(graphs, args, methods, tilt_aware, map_path, out)
    problems = graph.check()
    if problems:
        raise CompassError('inconsistent graph: ' + '; '.join(problems))
    return _run_graph(graph, out, env, args)


def _check_ekf_options(args) -> None:
    """Refuse options the fusion graph lacks and a missing ekf_node; fill the defaults."""
    from ..estimators import registry

    if args.ekf:
        given = [flag for attr, flag, d in _NOT_WITH_EKF if getattr(args, attr) != d]
        if given:
            raise CompassError(
                f'--ekf runs the fusion graph, which does not take {", ".join(given)} '
                '(fusion.launch.py has no such arguments)'
            )
        if foreign_executable('robot_localization', 'ekf_node') is None:
            raise CompassError(EKF_MISSING)  # before anything is built or started
    if args.methods is None:
        args.methods = 'least_squares' if args.ekf else ','.join(registry.paper_methods())
    if args.out is None:
        args.out = 'out/fusion' if args.ekf else 'out/sim'


def _check_numbers(args) -> None:
    """Refuse non-finite or out-of-range numbers and a bad scene before anything starts."""
    for name, v in (('rate', args.rate), ('turns', args.turns), ('time-scale', args.time_scale)):
        if not (math.isfinite(v) and v > 0):
            raise CompassError(f'--{name} must be a positive number, got {v}')
    if not (
        math.isfinite(args.pitch)
        and math.isfinite(args.roll)
        and abs(args.pitch) + abs(args.roll) <= 60
    ):
        raise CompassError('--pitch and --roll must be finite with |pitch| + |roll| <= 60')
    if not (math.isfinite(args.turn_rate) and 0.0 < abs(args.turn_rate) <= 360.0):
        raise CompassError(
            f'--turn-rate must be a nonzero number of deg/s within +-360, got {args.turn_rate}'
        )
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise CompassError(f'--timeout must be a positive number of seconds, got {args.timeout}')
    if args.scene:
        from ..scene import load_scene

        load_scene(args.scene)  # a bad scene is refused here, not 15 s into the run


def _selected_methods(args) -> tuple[list, bool]:
    """Return the available paper methods to run and whether tilt_aware runs."""
    from ..specs.params import PAPER_METHODS, TILT_METHODS

    wanted = [m.strip() for m in args.methods.split(',') if m.strip()]
    bad = [m for m in wanted if m not in PAPER_METHODS]
    if bad:
        raise CompassError(
            f'--methods: {bad} are not paper methods ({", ".join(PAPER_METHODS)}); '
            f'{", ".join(TILT_METHODS)} runs unless --no-tilt-aware'
        )
    methods, missing = _available_methods(wanted)
    tilt_aware = not args.no_tilt_aware and bool(TILT_METHODS)
    if missing:
        print(
            f'sim: note: method(s) {", ".join(missing)} are not available in this build: skipped',
            flush=True,
        )
    if not methods and not tilt_aware:
        raise CompassError('no heading method is available')
    return methods, tilt_aware


def _error_map_path(args, out: Path) -> Path:
    """Return the error map the correctors load: given (checked), shipped, or one to compute."""
    from ..correction import default_map_path

    if args.error_map:
        map_path = Path(args.error_map)
        from ..errormap_io import load_error_map
        from ..safe_load import regular_file

        regular_file(
            map_path, CompassError, '--error-map'
        )  # missing, a directory, a FIFO, a device
        load_error_map(map_path)  # a bad map is refused here, before the nodes start
        return map_path
    if default_map_path().is_file():
        return default_map_path()
    return out / 'error_map.npz'


def _ensure_map(args, methods, map_path: Path, env) -> None:
    """Compute the error map for the run's tilt and sun altitudes unless it is the shipped one."""
    from ..correction import default_map_path
    from ..specs.params import defaults, SIMULATOR

    d = defaults(SIMULATOR)
    duration = args.turns * 360.0 / abs(args.turn_rate)
    alts = scenario_sun_altitudes(
        d['start_time_utc'], duration, (d['latitude_deg'], d['longitude_deg'], d['altitude_m'])
    )
    if map_path != default_map_path():
        ensure_error_map(map_path, methods, args.pitch, args.roll, alts, env)


def _fusion_graph(graphs, args, methods, tilt_aware, map_path, out):
    return graphs.build(
        'fusion',
        {
            'methods': ','.join(methods),
            'tilt_aware': str(tilt_aware).lower(),
            'fuse': args.fuse,
            'turns': repr(float(args.turns)),
            'turn_rate_deg_s': repr(float(args.turn_rate)),
            'pitch_deg': repr(float(args.pitch)),
            'roll_deg': repr(float(args.roll)),
            'exit_when_done': 'true',
            'error_map': str(map_path),
            'report_dir': str(out),
        },
    )


def _sim_graph(graphs, args, methods, tilt_aware, map_path, out):
    return graphs.build(
        'sim',
        {
            'methods': ','.join(methods),
            'tilt_aware': str(tilt_aware).lower(),
            'encoding': args.encoding,
            'rate_hz': repr(float(args.rate)),
            'time_scale': repr(float(args.time_scale)),
            'turns': repr(float(args.turns)),
            'turn_rate_deg_s': repr(float(args.turn_rate)),
            'pitch_deg': repr(float(args.pitch)),
            'roll_deg': repr(float(args.roll)),
            'scene': args.scene,
            'lockstep': str(not args.realtime).lower(),
            'exit_when_done': 'true',
            'error_map': str(map_path),
            'report_dir': str(out),
            'array_geometry': args.array_geometry,
            'attitude_source': args.attitude_source,
        },
    )
