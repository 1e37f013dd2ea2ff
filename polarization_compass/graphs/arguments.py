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

"""The launch arguments of each graph (:data:`ARGUMENTS`) and how their text is read."""

from __future__ import annotations

from .spec import GraphError, LaunchArg, SIM_ATTITUDE_SOURCES
from ..specs import topics as T
from ..specs.params import ALL_METHODS, PAPER_METHODS

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
