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
"""The ``sky_simulator`` node's parameters."""

from .site_sun import SITE
from .spec import _downstream_problem, _iso_or_empty, _not_optical, Param

SIMULATOR = (
    Param(
        'scene',
        '',
        'scene YAML (camera, sky, sensor, validity); empty: the embedded paper set-up. '
        "Site, time and attitude come from this node's parameters, not from the scene",
        read_only=True,
    ),
    Param(
        'array_geometry',
        '',
        'also simulate a photodiode-array compass (sensor description YAML) on '
        "compass_array/intensities with every frame; '' = only if the scene declares one",
        read_only=True,
    ),
    Param(
        'encoding',
        'mono16',
        'image encoding: mono16/mono8 = raw 2x2 polarizer mosaic as a camera '
        'driver publishes it (needs a scene with sensor effects, else an ideal '
        'noise-free mosaic quantised to full scale); 32FC1 = ideal mosaic of '
        'polarizer intensities (float, no noise, no quantisation)',
        choices=('mono16', 'mono8', '32FC1'),
        read_only=True,
    ),
    Param(
        'rate_hz',
        10.0,
        'camera frame rate (simulated time); fixed at start: frame k is stamped start + '
        'k / rate_hz, so a new rate would move the stamps of a running camera',
        0.1,
        100.0,
        unit='Hz',
        read_only=True,
    ),
    Param(
        'imu_rate_hz',
        50.0,
        'simulated IMU rate (simulated time); fixed at start: sample k is stamped start '
        '+ k / imu_rate_hz',
        1.0,
        1000.0,
        unit='Hz',
        read_only=True,
    ),
    Param(
        'time_scale', 1.0, 'simulated seconds per wall-clock second (clock_mode sim)', 0.01, 100.0
    ),
    Param(
        'clock_mode',
        'sim',
        'sim: publish /clock, stamps are simulated UTC starting at start_time_utc '
        "(other nodes need use_sim_time); system: stamps are this node's ROS "
        'time and the sun is rendered for that time',
        choices=('sim', 'system'),
        read_only=True,
    ),
    Param(
        'clock_rate_hz',
        20.0,
        'how often /clock is published (clock_mode sim), wall clock; every node with '
        'use_sim_time receives each one, and nothing here needs it finer than the '
        'stamps of the data (ros2 bag play --clock: 40 Hz)',
        1.0,
        1000.0,
        unit='Hz',
        read_only=True,
    ),
    Param(
        'start_time_utc',
        '2019-11-15T06:00:00Z',
        'simulated UTC at the first frame (ISO 8601)',
        check=lambda v: 'start_time_utc must not be empty' if v == '' else _iso_or_empty(v),
        read_only=True,
    ),
    *SITE,
    Param('sun_model', 'spa', 'solar position model', choices=('spa', 'paper')),
    Param(
        'attitude_source',
        'motion',
        'motion: built-in profile; topic: attitude from a '
        'sensor_msgs/Imu or geometry_msgs/QuaternionStamped; tf: look up '
        'tf_world_frame -> tf_body_frame with tf2',
        choices=('motion', 'topic', 'tf'),
        read_only=True,
    ),
    Param(
        'attitude_topic_type',
        'imu',
        'message type on sim/attitude when attitude_source is topic',
        choices=('imu', 'quaternion'),
        read_only=True,
    ),
    Param('tf_world_frame', 'map', 'ENU world frame for attitude_source tf'),
    Param('tf_body_frame', 'base_link', 'body frame (REP-103, z up) for attitude_source tf'),
    Param(
        'tf_timeout_s',
        0.2,
        'attitude_source tf: how long (wall clock) a frame or IMU sample waits for the transforms '
        'at its stamp; none by then (missing or stale TF): skipped, counted and logged, never '
        'rendered at another attitude',
        0.0,
        10.0,
        unit='s',
        read_only=True,
    ),
    Param(
        'motion_tf',
        False,
        'attitude_source tf: also broadcast the built-in motion (turn and tilt) on /tf as '
        'tf_world_frame -> tf_body_frame, ahead of the frames, and the default camera mounting '
        'tf_body_frame -> camera_frame_id on /tf_static: the ground truth of the sim graph '
        "(attitude_source:=tf); false = the TF comes from elsewhere (a robot's)",
        read_only=True,
    ),
    Param(
        'start_bearing_deg',
        0.0,
        'motion: initial true bearing of the camera +y axis (= body +x)',
        -360.0,
        720.0,
        unit='deg',
    ),
    Param(
        'turn_rate_deg_s',
        10.0,
        'motion: rate of change of the bearing (clockwise positive)',
        -360.0,
        360.0,
        unit='deg/s',
    ),
    Param(
        'turns',
        1.0,
        'motion: stop after this many full turns (0: run until stopped; with turn rate '
        "0: duration_s decides); fixed at start (the run's length)",
        0.0,
        1000.0,
        read_only=True,
    ),
    Param(
        'duration_s',
        0.0,
        "stop after this much simulated time (0: see turns); fixed at start (the run's length)",
        0.0,
        1.0e7,
        unit='s',
        read_only=True,
    ),
    Param(
        'pitch_deg',
        -20.0,
        "motion: camera pitch (paper's alpha, about camera x)",
        -60.0,
        60.0,
        unit='deg',
    ),
    Param(
        'roll_deg',
        0.0,
        "motion: camera roll (paper's beta, about camera y)",
        -60.0,
        60.0,
        unit='deg',
    ),
    Param('pitch_amplitude_deg', 0.0, 'motion: sinusoidal pitch amplitude', 0.0, 60.0, unit='deg'),
    Param('roll_amplitude_deg', 0.0, 'motion: sinusoidal roll amplitude', 0.0, 60.0, unit='deg'),
    Param(
        'tilt_period_s',
        20.0,
        'motion: period of the pitch/roll sinusoids (roll lags pitch by 90 deg)',
        0.1,
        1.0e5,
        unit='s',
    ),
    Param(
        'exit_when_done',
        False,
        'exit (code 0) after the last frame (and linger_s more) instead of idling',
    ),
    Param(
        'linger_s',
        2.0,
        'after the last frame, keep /clock running this long (wall) before exiting',
        0.0,
        600.0,
        unit='s',
    ),
    Param(
        'wait_for_subscribers',
        0,
        'before the first frame, wait until the image and camera_info topics have '
        'this many subscribers (and the truth topic one), at most wait_timeout_s',
        0,
        1000,
        read_only=True,
    ),
    Param(
        'wait_for_imu_subscribers',
        0,
        'before the first frame, wait until imu/data has this many subscribers',
        0,
        1000,
        read_only=True,
    ),
    Param(
        'wait_for_downstream',
        [''],
        "before the first frame, also wait until each 'topic=node[,node...]' "
        'has a subscription of each named node in the ROS graph (the whole data '
        'path, e.g. the headings the correctors and the evaluator read), then '
        'wait_settle_s, so that no early message is lost to discovery',
        read_only=True,
        check=lambda v: _downstream_problem(v),
    ),
    Param(
        'wait_settle_s',
        0.3,
        'after the subscribers are there and camera_info, fix and the first IMU sample '
        'are sent: wait this long (wall clock) before the first frame',
        0.0,
        60.0,
        unit='s',
        read_only=True,
    ),
    Param(
        'wait_timeout_s',
        60.0,
        'longest wait for subscribers (wall clock)',
        0.0,
        3600.0,
        unit='s',
        read_only=True,
    ),
    Param(
        'imu_attitude_noise_deg',
        0.05,
        'simulated IMU: white noise on roll and pitch (1 sigma)',
        0.0,
        30.0,
        unit='deg',
    ),
    Param('imu_roll_bias_deg', 0.0, 'simulated IMU: roll bias', -30.0, 30.0, unit='deg'),
    Param('imu_pitch_bias_deg', 0.0, 'simulated IMU: pitch bias', -30.0, 30.0, unit='deg'),
    Param(
        'imu_yaw_noise_deg',
        2.0,
        'simulated IMU: white noise on yaw (1 sigma; a magnetometer-grade '
        'yaw, usable as a prior to resolve the 180 deg ambiguity)',
        0.0,
        90.0,
        unit='deg',
    ),
    Param('imu_yaw_bias_deg', 5.0, 'simulated IMU: yaw bias', -90.0, 90.0, unit='deg'),
    Param(
        'odom_yaw_rate_noise_deg_s',
        0.2,
        'simulated wheel odometry (odometry/wheel, motion only): white noise on the yaw rate '
        '(1 sigma per sample at imu_rate_hz; its variance is the twist covariance reported)',
        0.0,
        90.0,
        unit='deg/s',
    ),
    Param(
        'odom_yaw_rate_bias_deg_s',
        0.5,
        'simulated wheel odometry: yaw-rate bias, not in the reported covariance (dead '
        'reckoning drifts by it, like a gyro)',
        -90.0,
        90.0,
        unit='deg/s',
    ),
    Param(
        'odom_tf',
        True,
        'also broadcast the dead-reckoned odom -> imu_frame_id transform on /tf, as a wheel '
        'odometry driver does (needs tf2_ros; without it only the topic, logged once)',
        read_only=True,
    ),
    Param('camera_frame_id', 'camera_optical_frame', 'frame_id of the image and camera_info'),
    Param('imu_frame_id', 'base_link', 'frame_id of the simulated IMU (z up)', check=_not_optical),
    Param(
        'heading_frame_id',
        'base_link',
        'frame_id of the ground-truth heading (z up)',
        check=_not_optical,
    ),
    Param(
        'seed', 0, 'noise seed (sensor noise and IMU noise); frame k uses seed + k', 0, 2**31 - 1
    ),
    Param(
        'lockstep',
        False,
        'wait (up to lockstep_timeout_s) for every listed heading topic to answer a '
        'frame before rendering the next: deterministic runs on a loaded machine',
        read_only=True,
    ),
    Param(
        'lockstep_topics',
        [''],
        'status topics (std_msgs/String, JSON with a stamp) that must answer '
        'each frame when lockstep is on',
        read_only=True,
    ),
    Param(
        'lockstep_timeout_s',
        5.0,
        'longest wait for one frame in lockstep mode (wall clock)',
        0.01,
        600.0,
        unit='s',
    ),
)
