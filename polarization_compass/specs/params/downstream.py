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
"""Parameters of the nodes after the estimators: tilt_corrector, error_evaluator, player_flow."""

from .estimator import MOUNT
from .methods import ALL_METHODS, PAPER_METHODS, TILT_METHODS
from .site_sun import SITE, SITE_SOURCE
from .spec import Param

CORRECTOR = (
    Param(
        'method',
        'least_squares',
        'method whose raw heading this node corrects',
        choices=ALL_METHODS,
        read_only=True,
    ),
    Param(
        'correction',
        'error_map',
        'error_map: subtract the simulated tilt error interpolated at the '
        "IMU's pitch/roll; none: pass the heading through (pairing and "
        'diagnostics still run)',
        choices=('error_map', 'none'),
    ),
    Param(
        'error_map',
        '',
        "error map .npz (polarization-compass errormap --out FILE); '' = the map shipped "
        'with the package (polarization_compass/data/tilt_error_map.npz)',
    ),
    Param(
        'imu_tolerance_s',
        0.05,
        'pair a heading with IMU samples within this of its stamp',
        0.0,
        10.0,
        unit='s',
    ),
    Param(
        'imu_max_wait_s',
        0.5,
        'how long a heading waits for an IMU sample newer than its stamp (wall clock)',
        0.0,
        60.0,
        unit='s',
    ),
    Param(
        'imu_buffer_s',
        10.0,
        'IMU history kept for pairing (a change applies from the next IMU sample)',
        0.1,
        600.0,
        unit='s',
    ),
    *MOUNT,
    Param(
        'correction_sigma_deg',
        0.1,
        "added (in quadrature) to the heading sigma for the map's interpolation and model error",
        0.0,
        90.0,
        unit='deg',
    ),
    Param(
        'attitude_sigma_deg',
        0.0,
        "1-sigma camera pitch/roll error the IMU's orientation_covariance does not hold "
        '(boresight, IMU-to-camera time offset x tilt rate), added in quadrature to it; with an '
        'all-zero covariance (unknown, sensor_msgs/Imu) the whole of it. Propagated into the '
        "heading sigma through the error map's gradient",
        0.0,
        30.0,
        unit='deg',
    ),
    SITE_SOURCE,
    *SITE,
    Param(
        'sun_model',
        'spa',
        "solar position model (the sun's altitude and azimuth for the map lookup)",
        choices=('spa', 'paper'),
    ),
)

EVALUATOR = (
    Param(
        'methods',
        list(PAPER_METHODS) + list(TILT_METHODS),
        'methods to evaluate',
        choices=ALL_METHODS,
        read_only=True,
    ),
    Param(
        'direct_methods',
        list(TILT_METHODS),
        'methods without a corrector (only their raw topic is read)',
        choices=ALL_METHODS,
        read_only=True,
    ),
    Param(
        'fused_streams',
        [''],
        "state estimator outputs to score too, 'method=topic' each (nav_msgs/Odometry, e.g. "
        "least_squares=/odometry/filtered): stream '<method>/fused', its yaw interpolated at "
        'each truth stamp',
        read_only=True,
        check=lambda v: next(
            (f'fused_streams: {x!r} is not method=topic' for x in v if x and '=' not in x), None
        ),
    ),
    Param('include_raw', True, 'evaluate compass/<m>/heading_raw', read_only=True),
    Param('include_corrected', True, 'evaluate compass/<m>/heading', read_only=True),
    Param(
        'axial_methods',
        [''],
        'methods whose errors are folded to (-90, 90] (heading mod 180 deg)',
        read_only=True,
    ),
    Param(
        'report_dir',
        'out/sim',
        'CSV and PNG reports go here: kept current while the node runs, final when it stops',
        read_only=True,
    ),
    Param(
        'horizon_s',
        5.0,
        'a truth frame with no estimate on a stream after this (stamp time) counts as missed',
        0.1,
        3600.0,
        unit='s',
    ),
    Param(
        'summary_rate_hz',
        1.0,
        'rate of evaluation/summary and /diagnostics',
        0.1,
        100.0,
        unit='Hz',
    ),
    Param(
        'time_scale', 1.0, 'simulated seconds per wall second (latency_source clock)', 0.01, 100.0
    ),
    Param(
        'latency_source',
        'sim_frames',
        'sim_frames: wall time from the simulator publishing an image (sim/frames) '
        "to a heading's arrival here; clock: arrival time on this node's clock "
        '(last /clock + wall time since, under use_sim_time) minus the stamp',
        choices=('sim_frames', 'clock'),
        read_only=True,
    ),
)

PLAYER_FLOW = (
    Param(
        'status_topics',
        [''],
        "the estimators' status topics (compass/<method>/status): one answer per image each",
        read_only=True,
    ),
    Param(
        'camera_info_topic',
        'camera/camera_info',
        "the player's camera_info: one per image, the frames it has published",
        read_only=True,
    ),
    Param(
        'player', '/rosbag2_player', 'the player node (its pause/resume services)', read_only=True
    ),
    Param(
        'high_water',
        6,
        'pause the player when an estimator is this many frames behind',
        lo=1,
        hi=1000,
        unit='frames',
    ),
    Param(
        'low_water',
        2,
        'resume it when every estimator is within this many frames (less than high_water)',
        lo=0,
        hi=999,
        unit='frames',
    ),
    Param(
        'max_pause_s',
        120.0,
        'longest pause without an answer from the estimators before resuming for good',
        lo=1.0,
        hi=3600.0,
        unit='s',
    ),
)
