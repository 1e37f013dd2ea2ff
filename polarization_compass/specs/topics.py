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
Topic names and message types of every node, in one place.

The single source used by the nodes themselves, by :mod:`polarization_compass.graphs` (launch
files, ``polarization-compass sim``) and by the tests.

All names are relative, so a namespace moves a whole graph and ``--ros-args -r old:=new`` remaps
any of them; ``/diagnostics`` and ``/clock`` are absolute by ROS convention. Per-method topics live
under ``compass/<method>/`` so that, with default parameters, every estimator, corrector and the
evaluator connect without remapping.

ROS-free: no rclpy import here.
"""

from __future__ import annotations

__all__ = [
    'IMAGE',
    'ARRAY',
    'ARRAY_HEADER',
    'T_FLOAT32_MULTIARRAY',
    'T_HEADER',
    'CAMERA_INFO',
    'IMU',
    'TRUTH',
    'FIX',
    'CLOCK',
    'DIAGNOSTICS',
    'EVAL_SUMMARY',
    'FRAMES',
    'IMU_DEPTH',
    'method_topics',
    'simulator_topics',
    'estimator_topics',
    'corrector_topics',
    'evaluator_topics',
    'evaluator_streams',
    'fused_streams',
    'T_IMAGE',
    'T_MARKER',
    'DEBUG_IMAGE',
    'HEADING_MARKER',
    'T_CAMERA_INFO',
    'T_IMU',
    'T_FIX',
    'T_CLOCK',
    'T_DIAG',
    'T_STRING',
    'T_FLOAT64',
    'T_QUAT_STAMPED',
    'T_ODOMETRY',
    'ODOM',
    'FILTERED',
]

# message types (ROS interface names)
T_IMAGE = 'sensor_msgs/msg/Image'
T_MARKER = 'visualization_msgs/msg/Marker'
T_CAMERA_INFO = 'sensor_msgs/msg/CameraInfo'
T_IMU = 'sensor_msgs/msg/Imu'
T_FIX = 'sensor_msgs/msg/NavSatFix'
T_CLOCK = 'rosgraph_msgs/msg/Clock'
T_DIAG = 'diagnostic_msgs/msg/DiagnosticArray'
T_STRING = 'std_msgs/msg/String'
T_FLOAT64 = 'std_msgs/msg/Float64'
T_QUAT_STAMPED = 'geometry_msgs/msg/QuaternionStamped'
T_FLOAT32_MULTIARRAY = 'std_msgs/msg/Float32MultiArray'
T_HEADER = 'std_msgs/msg/Header'
T_ODOMETRY = 'nav_msgs/msg/Odometry'

IMAGE = 'camera/image_raw'  # the polarization mosaic, as a camera driver publishes it
CAMERA_INFO = 'camera/camera_info'
# photodiode-array readings, units x channels (docs/photodiode-arrays.md)
ARRAY = 'compass_array/intensities'
ARRAY_HEADER = (
    'compass_array/header'  # the stamp and frame of each array sample, published beside it
)
IMU = 'imu/data'  # attitude of base_link in ENU (roll/pitch used)
TRUTH = 'ground_truth/heading'  # simulator only: true heading, same Imu form as the estimate
FIX = 'gps/fix'  # site (latitude/longitude/altitude)
ATTITUDE_IN = 'sim/attitude'  # simulator input when attitude_source = topic
#: simulator (motion): wheel-odometry-like twist (yaw rate with noise and bias) and its dead
#: reckoning, what config/ekf_heading_example.yaml fuses as odom0
ODOM = 'odometry/wheel'
#: robot_localization's output (ekf_node's default topic), scored by the evaluator in the fusion
#: graph
FILTERED = 'odometry/filtered'
CLOCK = '/clock'
DIAGNOSTICS = '/diagnostics'
#: a heading estimator's own (node-private) topics: its diagnostic picture and heading marker
DEBUG_IMAGE = '~/debug_image'
HEADING_MARKER = '~/heading_marker'
EVAL_SUMMARY = 'evaluation/summary'  # JSON running statistics per stream
FRAMES = 'sim/frames'  # simulator: JSON {stamp_ns, wall_ns} per image (wall-clock latency)

#: History depth of the IMU subscriptions. They are best effort (REP-2003 sensor-data QoS: a
#: best-effort reader matches both reliable and best-effort writers, a reliable reader only
#: reliable ones) and deep enough for 2 s of a 100 Hz IMU, so that samples arriving while a long
#: callback runs are kept.
IMU_DEPTH = 200
#: History depth of the estimator's image subscription and queue with ``image_qos: replay``
#: (reliable): a played bag's images wait there behind an estimator slower than the player. The
#: replay's ``player_flow`` pauses the player long before (at ``high_water`` frames); the depth is
#: the memory bound (32 full-resolution mosaics of 10 MB), beyond which the oldest is dropped and
#: counted (``image_queue_full``).
REPLAY_IMAGE_DEPTH = 32


def method_topics(method: str) -> dict:
    """
    Return the per-method topic names (relative, under ``compass/<method>/``).

    Parameters
    ----------
    method : str
        Estimator name.

    Returns
    -------
    dict
        ``heading_raw`` (Imu), ``bearing_raw`` (Float64 [deg]), ``status`` (String, JSON),
        ``heading`` (Imu, tilt-corrected), ``bearing`` (Float64 [deg]) and
        ``correction_status`` (String).

    """
    base = f'compass/{method}'
    return {
        'heading_raw': f'{base}/heading_raw',  # Imu, estimator output (not tilt-corrected)
        'bearing_raw': f'{base}/bearing_raw_deg',  # Float64, same, true bearing in degrees
        'status': f'{base}/status',  # String (JSON), one per image, also failures
        'heading': f'{base}/heading',  # Imu, corrector output (what to fuse)
        'bearing': f'{base}/bearing_deg',  # Float64
        'correction_status': f'{base}/correction_status',
    }


def simulator_topics(
    attitude_source: str = 'motion',
    publish_clock: bool = True,
    attitude_input_type: str = 'imu',
    array: bool = False,
):
    """
    Return the topics the ``sky_simulator`` publishes and subscribes to.

    Parameters
    ----------
    attitude_source : str, default "motion"
        ``"motion"`` adds the wheel odometry it publishes, ``"topic"`` the attitude input
        subscription.
    publish_clock : bool, default True
        Also publish ``/clock``.
    attitude_input_type : str, default "imu"
        Message type of the attitude input: ``"imu"`` (Imu), anything else QuaternionStamped
        (the simulator's ``attitude_topic_type`` parameter).
    array : bool, default False
        Also publish a photodiode-array compass's readings and the companion header of each.

    Returns
    -------
    publishes, subscribes : list of tuple
        ``(topic, type)`` pairs.

    """
    pubs = [
        (IMAGE, T_IMAGE),
        (CAMERA_INFO, T_CAMERA_INFO),
        (IMU, T_IMU),
        (TRUTH, T_IMU),
        (FIX, T_FIX),
        (FRAMES, T_STRING),
        (DIAGNOSTICS, T_DIAG),
    ]
    if array:
        pubs += [(ARRAY, T_FLOAT32_MULTIARRAY), (ARRAY_HEADER, T_HEADER)]
    if attitude_source == 'motion':
        pubs.append((ODOM, T_ODOMETRY))
    if publish_clock:
        pubs.append((CLOCK, T_CLOCK))
    subs = []
    if attitude_source == 'topic':
        subs.append((ATTITUDE_IN, T_IMU if attitude_input_type == 'imu' else T_QUAT_STAMPED))
    return pubs, subs


def estimator_topics(
    method: str,
    site_source: str = 'parameters',
    needs_tilt: bool = False,
    prior_source: str = 'none',
    input_kind: str = 'image',
    array_stamp: str = 'header',
    debug_image: bool = False,
    marker: bool = False,
):
    """
    Return the topics a ``heading_estimator`` publishes and subscribes to.

    Parameters
    ----------
    method : str
        Estimator name.
    site_source : {"parameters", "navsatfix"}, default "parameters"
        ``"navsatfix"`` adds the fix subscription.
    needs_tilt : bool, default False
        The method needs the IMU tilt (adds the IMU subscription).
    prior_source : str, default "none"
        ``"imu"`` adds the IMU subscription as well.
    input_kind : {"image", "array"}, default "image"
        Camera image and camera_info, or a photodiode array's readings.
    array_stamp : {"header", "arrival"}, default "header"
        With an array input, ``"header"`` adds the companion header subscription.
    debug_image, marker : bool, default False
        The node publishes its diagnostic picture (a camera's ``debug_rate_hz`` > 0) and its
        heading marker (``publish_marker``), on its private topics.

    Returns
    -------
    publishes, subscribes : list of tuple
        ``(topic, type)`` pairs.

    """
    t = method_topics(method)
    pubs = [
        (t['heading_raw'], T_IMU),
        (t['bearing_raw'], T_FLOAT64),
        (t['status'], T_STRING),
        (DIAGNOSTICS, T_DIAG),
    ]
    pubs += [(DEBUG_IMAGE, T_IMAGE)] if debug_image and input_kind == 'image' else []
    pubs += [(HEADING_MARKER, T_MARKER)] if marker else []
    if input_kind == 'array':
        subs = [(ARRAY, T_FLOAT32_MULTIARRAY)] + (
            [(ARRAY_HEADER, T_HEADER)] if array_stamp == 'header' else []
        )
    else:
        subs = [(IMAGE, T_IMAGE), (CAMERA_INFO, T_CAMERA_INFO)]
    if site_source == 'navsatfix':
        subs.append((FIX, T_FIX))
    if needs_tilt or prior_source == 'imu':
        subs.append((IMU, T_IMU))
    return pubs, subs


def corrector_topics(method: str, site_source: str = 'parameters'):
    """
    Return the topics a ``tilt_corrector`` publishes and subscribes to.

    Parameters
    ----------
    method : str
        Estimator name whose raw heading it corrects.
    site_source : {"parameters", "navsatfix"}, default "parameters"
        ``"navsatfix"`` adds the fix subscription.

    Returns
    -------
    publishes, subscribes : list of tuple
        ``(topic, type)`` pairs.

    """
    t = method_topics(method)
    pubs = [
        (t['heading'], T_IMU),
        (t['bearing'], T_FLOAT64),
        (t['correction_status'], T_STRING),
        (DIAGNOSTICS, T_DIAG),
    ]
    subs = [(t['heading_raw'], T_IMU), (IMU, T_IMU)]
    if site_source == 'navsatfix':
        subs.append((FIX, T_FIX))
    return pubs, subs


def evaluator_streams(
    methods, include_raw: bool = True, include_corrected: bool = True, direct_methods=()
) -> list[tuple[str, str]]:
    """
    Return the evaluator's streams and the topics they come from.

    ``<method>/raw`` and ``<method>/corrected`` for each method, and ``<method>/raw`` only for
    methods in ``direct_methods`` (no corrector, e.g. tilt_aware).

    Parameters
    ----------
    methods : iterable of str
        Estimator names.
    include_raw : bool, default True
        Evaluate the raw headings.
    include_corrected : bool, default True
        Evaluate the corrected headings.
    direct_methods : iterable of str, default ()
        Methods without a corrector.

    Returns
    -------
    list of tuple of str
        ``(stream name, topic)`` pairs.

    """
    out = []
    for m in methods:
        t = method_topics(m)
        if include_raw or m in direct_methods:
            out.append((f'{m}/raw', t['heading_raw']))
        if include_corrected and m not in direct_methods:
            out.append((f'{m}/corrected', t['heading']))
    return out


def fused_streams(items) -> list[tuple[str, str]]:
    """
    Return the evaluator's state-estimator streams from its ``fused_streams`` parameter.

    Parameters
    ----------
    items : iterable of str
        ``"method=topic"`` each; empty items are ignored.

    Returns
    -------
    list of tuple of str
        ``("<method>/fused", topic)`` pairs.

    """
    out = []
    for x in items:
        if x:
            method, topic = x.split('=', 1)
            out.append((f'{method.strip()}/fused', topic.strip()))
    return out


def evaluator_topics(streams, latency_source: str = 'sim_frames', fused=()):
    """
    Return the topics the ``error_evaluator`` publishes and subscribes to.

    Parameters
    ----------
    streams : list of tuple of str
        ``(stream name, topic)`` pairs of :func:`evaluator_streams`.
    latency_source : str, default "sim_frames"
        ``"sim_frames"`` adds the simulator's frame-time subscription (wall-clock latency).
    fused : list of tuple of str, default ()
        ``(stream name, topic)`` pairs of :func:`fused_streams` (nav_msgs/Odometry).

    Returns
    -------
    publishes, subscribes : list of tuple
        ``(topic, type)`` pairs, with each stream's status topic.

    """
    pubs = [(EVAL_SUMMARY, T_STRING), (DIAGNOSTICS, T_DIAG)]
    subs = [(TRUTH, T_IMU), (DIAGNOSTICS, T_DIAG)] + [(topic, T_IMU) for _, topic in streams]
    if latency_source == 'sim_frames':
        subs.append((FRAMES, T_STRING))
    for name, _ in streams:  # statuses: why a frame was not published
        method, kind = name.split('/')
        subs.append(
            (method_topics(method)['status' if kind == 'raw' else 'correction_status'], T_STRING)
        )
    subs += [(topic, T_ODOMETRY) for _, topic in fused]
    return pubs, subs
