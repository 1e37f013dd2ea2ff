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
Declarative parameter specifications of every node (ROS-free).

One :class:`Param` per ROS parameter: name, default, description, range or choices, and whether it
may change while the node runs. The nodes declare them from here (:mod:`.rosparams` turns them into
``ParameterDescriptor`` s with ``FloatingPointRange`` / ``IntegerRange`` and validates every change
in an on-set-parameters callback); the graph test checks every shipped parameter file against them;
``docs/ros.md`` lists them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable

from ..estimators.registry import MethodNames

__all__ = [
    'Param',
    'validate_value',
    'SIMULATOR',
    'ESTIMATOR',
    'CORRECTOR',
    'EVALUATOR',
    'PLAYER_FLOW',
    'SPECS',
    'spec_by_name',
    'defaults',
    'layout_from_text',
    'knob_params',
    'KNOB_PREFIX',
    'SUN_PARAMS',
    'sun_source',
    'SITE_SOURCE',
    'apply_fix',
]


@dataclass(frozen=True)
class Param:
    """
    Describe one node parameter.

    Parameters
    ----------
    name : str
        ROS parameter name, units in the name (e.g. ``latitude_deg``).
    default : bool, int, float, str or list
        Default value; its type decides the parameter's type (:attr:`kind`).
    description : str
        One-line meaning, shown by ``ros2 param describe`` and in docs/ros.md.
    lo, hi : float, optional
        Inclusive bounds of a number, in ``unit``.
    choices : tuple of str, default ()
        Allowed strings (for a string array: allowed items).
    read_only : bool, default False
        Fixed once the node runs (topics and graph wiring depend on it); otherwise a method knob
        that changes at run time.
    check : callable, optional
        Extra rule ``check(value) -> str | None`` returning an error message or None.
    unit : str, default ""
        Unit of a number for messages and docs (e.g. ``"deg"``).

    """

    name: str
    default: object
    description: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    read_only: bool = False
    check: Callable | None = field(default=None, compare=False)
    unit: str = ''

    @property
    def kind(self) -> str:
        """ROS type from the default: bool, int, float, str, str_list or float_list."""
        d = self.default
        if isinstance(d, bool):
            return 'bool'
        if isinstance(d, int):
            return 'int'
        if isinstance(d, float):
            return 'float'
        if isinstance(d, str):
            return 'str'
        if isinstance(d, (list, tuple)):
            return 'str_list' if all(isinstance(x, str) for x in d) else 'float_list'
        raise TypeError(f'parameter {self.name}: unsupported default {d!r}')


def validate_value(p: Param, value) -> str | None:
    """
    Return why ``value`` is not acceptable for ``p``, or None when it is.

    Parameters
    ----------
    p : Param
        The parameter's specification.
    value : object
        The proposed value (a ROS parameter value: bool, int, float, str or list).

    Returns
    -------
    str or None
        A one-line reason naming the parameter (type, finiteness, range with unit, choice, or the
        extra ``check``), or None when the value is acceptable.

    """
    k = p.kind
    if k == 'bool':
        if not isinstance(value, bool):
            return f'{p.name} must be true or false, got {value!r}'
        return p.check(value) if p.check else None
    if k in ('int', 'float'):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f'{p.name} must be a number, got {value!r}'
        if k == 'int' and not float(value).is_integer():
            return f'{p.name} must be an integer, got {value!r}'
        if not math.isfinite(float(value)):
            return f'{p.name} must be finite, got {value!r}'
        if p.lo is not None and value < p.lo or p.hi is not None and value > p.hi:
            return (
                f'{p.name} must be in [{p.lo}, {p.hi}]{" " + p.unit if p.unit else ""}, got '
                f'{value!r}'
            )
    elif k == 'str':
        if not isinstance(value, str):
            return f'{p.name} must be a string, got {value!r}'
        if p.choices and value not in p.choices:
            return f'{p.name} must be one of {", ".join(p.choices)}; got {value!r}'
    elif k == 'str_list':
        if not isinstance(value, (list, tuple)) or not all(isinstance(x, str) for x in value):
            return f'{p.name} must be a list of strings, got {value!r}'
        if p.choices:
            bad = [
                x for x in value if x and x not in p.choices
            ]  # "" = ROS's empty-array placeholder
            if bad:
                return f'{p.name}: unknown item(s) {bad}; allowed: {", ".join(p.choices)}'
    elif k == 'float_list':
        if not isinstance(value, (list, tuple)) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
            for x in value
        ):
            return f'{p.name} must be a list of finite numbers, got {value!r}'
    return p.check(value) if p.check else None


def parse_downstream(items) -> list[tuple[str, frozenset]]:
    """
    Parse ``wait_for_downstream`` entries into topics and the nodes to wait for.

    Parameters
    ----------
    items : iterable of str
        Entries ``"topic=node_a,node_b"``; empty strings are ignored.

    Returns
    -------
    list of tuple
        ``[(topic, frozenset of node names)]`` in the order given.

    Raises
    ------
    ValueError
        An entry without ``=``, a topic or at least one node name (the message quotes it).

    """
    out = []
    for item in items:
        if not item:
            continue
        topic, sep, names = item.rpartition('=')
        nodes = frozenset(x.strip() for x in names.split(',') if x.strip())
        if not sep or not topic or not nodes:
            raise ValueError(
                f"wait_for_downstream entries are 'topic=node[,node...]', got {item!r}"
            )
        out.append((topic, nodes))
    return out


def _downstream_problem(v):
    try:
        parse_downstream(v)
    except ValueError as exc:
        return str(exc)
    return None


def _not_optical(frame_id: str):
    if frame_id.endswith('_optical_frame') or frame_id.endswith('_optical'):
        return (
            f'frame_id {frame_id!r} is an optical frame (z forward): robot_localization needs a '
            'z-up '
            'frame with a TF to base_link, e.g. base_link'
        )
    if not frame_id:
        return 'frame_id must not be empty'
    return None


def _iso_or_empty(text: str):
    if text == '':
        return None
    from ..scene import parse_time_utc, SceneError

    try:
        parse_time_utc(text)
    except SceneError as exc:
        return str(exc)
    return None


def _layout_problem(text: str):
    try:
        vals = [int(x) for x in text.split(',')]
    except ValueError:
        return (
            'polarizer_layout must be four comma-separated angles such as 90,45,135,0, got '
            f'{text!r}'
        )
    if sorted(vals) != [0, 45, 90, 135]:
        return f'polarizer_layout must hold 0, 45, 90 and 135 once each, got {text!r}'
    return None


def layout_from_text(text: str):
    """
    Parse a ``polarizer_layout`` parameter into a 2 x 2 layout.

    Parameters
    ----------
    text : str
        Four comma-separated polarizer angles [deg], row by row, e.g. ``"90,45,135,0"``
        (validated beforehand by the parameter's check).

    Returns
    -------
    tuple of tuple of int
        ``((90, 45), (135, 0))`` for the example.

    """
    v = [int(x) for x in text.split(',')]
    return ((v[0], v[1]), (v[2], v[3]))


SITE = (
    Param(
        'latitude_deg', 32.026778, 'site latitude, north positive (WGS84)', -90.0, 90.0, unit='deg'
    ),
    Param(
        'longitude_deg',
        118.853306,
        'site longitude, east positive (WGS84)',
        -180.0,
        180.0,
        unit='deg',
    ),
    Param('altitude_m', 30.0, 'site height above sea level', -1000.0, 20000.0, unit='m'),
)

#: The parameters the sun's position depends on: a node makes a new :func:`sun_source` when one
#: changes.
SUN_PARAMS = ('latitude_deg', 'longitude_deg', 'altitude_m', 'sun_model')


def sun_source(values):
    """
    Return the :class:`~polarization_compass.pipeline.SunSource` of a node's site parameters.

    Parameters
    ----------
    values : mapping
        Holds :data:`SUN_PARAMS`: ``latitude_deg`` and ``longitude_deg`` [deg, WGS84, north and
        east positive], ``altitude_m`` [m] and ``sun_model``.

    Returns
    -------
    SunSource
        The sun's position source at that site.

    """
    from ..pipeline import SunSource

    return SunSource(*(values[k] for k in SUN_PARAMS))


#: Where a node takes the site from (heading_estimator and tilt_corrector: the same choice in a
#: graph).
SITE_SOURCE = Param(
    'site_source',
    'parameters',
    'where the site comes from: parameters (latitude_deg, longitude_deg, altitude_m) or navsatfix '
    '(gps/fix, the latest fix; until the first fix nothing that needs the sun is published, a '
    'status '
    'says why)',
    choices=('parameters', 'navsatfix'),
    read_only=True,
)


def apply_fix(sun, diag, msg):
    """
    Move ``sun`` to the site of a sensor_msgs/NavSatFix.

    A fix :func:`~polarization_compass.bag.decode_navsatfix` refuses is counted on ``diag`` as
    rejected ``fix_<reason>``; a site the ephemeris refuses as ``fix_bad_value`` (``sun`` keeps
    its site then).

    Parameters
    ----------
    sun : SunSource
        The node's sun source, updated in place.
    diag : Diagnostics
        The node's :class:`~polarization_compass.nodes.diagnostics.Diagnostics` (counts
        rejections).
    msg : sensor_msgs.msg.NavSatFix
        The fix.

    Returns
    -------
    tuple of float or None
        The site ``(latitude_deg, longitude_deg, altitude_m)``, or None when the fix was rejected.

    """
    from ..bag import decode_navsatfix
    from ..errors import CompassError

    site = diag.decoded('fix', decode_navsatfix, msg)
    if site is None:
        return None
    try:
        sun.set_site(*site)
    except CompassError as exc:
        diag.reject('fix_bad_value', str(exc))
        return None
    return site


# Live views of the estimator registry: choices see a method registered after this module was
# imported.
PAPER_METHODS = MethodNames(paper=True)
ALL_METHODS = MethodNames()
TILT_METHODS = MethodNames(needs_tilt=True)

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

ESTIMATOR = (
    Param(
        'method',
        'least_squares',
        'heading method (one node per method)',
        choices=ALL_METHODS,
        read_only=True,
    ),
    Param(
        'demosaic',
        'superpixel',
        'how the 2x2 mosaic becomes AoP/DoP',
        choices=('superpixel', 'bilinear'),
    ),
    Param(
        'polarizer_layout',
        '90,45,135,0',
        'polarizer angles (deg, from +x_cam towards +y_cam) of the '
        '2x2 cell, row-major from the top-left pixel (Sony IMX250MZR: '
        '90,45,135,0)',
        check=lambda v: _layout_problem(v),
    ),
    Param(
        'pol45_toward',
        '+x-y',
        'image direction of the 45 deg polarizer: +x-y (up and right on the '
        'displayed image: the IMX250MZR as delivered) or +x+y (a readout '
        "flipped in x or y); check with 'polarization-compass check-polarizer'",
        choices=('+x+y', '+x-y'),
    ),
    Param(
        'polarizer_check_every',
        100,
        'every N-th image, fit the sky under each polarizer hypothesis '
        '(check-polarizer) and publish a diagnostics ERROR with the fix when '
        'the sky contradicts polarizer_layout/pol45_toward (0 = never)',
        0,
        100000,
    ),
    Param(
        'sky_check',
        False,
        "check every result against the whole sky (as 'estimate' does on real images): "
        "sigma includes the frame's model misfit, the 180 deg side is decided by the "
        'whole sky, status poor_fit when no single sun fits (~15-30 ms per image)',
    ),
    Param(
        'debug_rate_hz',
        1.0,
        'most diagnostic images per second on ~/debug_image (rgb8: AoP, DoP, pixels used and '
        'masked, residual, fitted sun, heading; README "What the compass sees"), rendered only '
        'while someone subscribes (0 = never)',
        0.0,
        30.0,
        unit='Hz',
    ),
    Param(
        'debug_width_px',
        640,
        'width of the ~/debug_image picture',
        200,
        2600,
        unit='px',
    ),
    Param(
        'publish_marker',
        True,
        'publish the heading as a visualization_msgs/Marker arrow (id 0) and its +-sigma sector '
        '(id 1) on ~/heading_marker, in frame_id (as the heading Imu)',
    ),
    Param(
        'use_intensity',
        False,
        'also compute S0 so that a method can resolve the 180 deg ambiguity from '
        "the sky's brightness gradient (costs a second pass over the mosaic)",
    ),
    Param(
        'frame_id',
        'base_link',
        'frame_id of the published heading: z up, with a TF to base_link '
        '(never a camera optical frame)',
        check=_not_optical,
    ),
    SITE_SOURCE,
    *SITE,
    Param(
        'time_source',
        'stamp',
        "stamp: the sun at the image's header.stamp (UTC); parameter: at time_utc",
        choices=('stamp', 'parameter'),
    ),
    Param(
        'time_utc',
        '',
        'fixed UTC time (ISO 8601) when time_source is parameter',
        check=_iso_or_empty,
    ),
    Param('sun_model', 'spa', 'solar position model', choices=('spa', 'paper')),
    Param(
        'camera_info_source',
        'topic',
        'topic: intrinsics from camera_info (parameters until the first '
        'one arrives); parameters: always the parameters below',
        choices=('topic', 'parameters'),
    ),
    Param(
        'camera_model',
        'pinhole',
        'fallback intrinsics: lens model',
        choices=('pinhole', 'fisheye_equidistant'),
    ),
    Param('focal_length_mm', 4.0, 'fallback intrinsics: focal length', 0.1, 1000.0, unit='mm'),
    Param(
        'pixel_pitch_um',
        3.45,
        "pixel pitch (also converts camera_info's K to a focal length)",
        0.1,
        100.0,
        unit='um',
    ),
    Param(
        'max_field_angle_deg',
        90.0,
        'fisheye: largest field angle with sky',
        1.0,
        180.0,
        unit='deg',
    ),
    Param(
        'prior_source',
        'imu',
        'resolves the 180 deg ambiguity: imu = yaw of the IMU message (coarse '
        "is enough), last = this node's previous heading, none = publish only "
        'headings the method resolves itself',
        choices=('imu', 'last', 'none'),
    ),
    Param(
        'prior_max_age_s',
        2.0,
        'the prior is the IMU yaw (or last heading) nearest the image stamp within this',
        0.0,
        3600.0,
        unit='s',
    ),
    Param(
        'prior_sigma_deg',
        15.0,
        '1-sigma of the IMU yaw (prior_source imu): a heading further from it than '
        '3 x sqrt(sigma^2 + this^2) gets status prior_disagrees and is not published '
        '(0 = no check)',
        0.0,
        180.0,
        unit='deg',
    ),
    Param(
        'imu_tolerance_s',
        0.05,
        'tilt_aware: the IMU at the image stamp, interpolated between samples within this of it',
        0.0,
        10.0,
        unit='s',
    ),
    Param(
        'imu_max_wait_s',
        0.5,
        'tilt_aware: how long an image newer than the newest IMU sample waits for it (wall clock)',
        0.0,
        60.0,
        unit='s',
    ),
    Param(
        'attitude_sigma_deg',
        0.0,
        "tilt_aware: 1-sigma camera pitch/roll error the IMU's orientation_covariance does not "
        'hold (boresight, IMU-to-camera time offset x tilt rate), added in quadrature to it; with '
        'an all-zero covariance (unknown, sensor_msgs/Imu) the whole of it. Propagated into the '
        'heading sigma',
        0.0,
        30.0,
        unit='deg',
    ),
    Param(
        'publish_ambiguous',
        False,
        'also publish headings known only modulo 180 deg on the Imu topics '
        '(never fuse those into robot_localization)',
    ),
    Param(
        'sigma_floor_deg',
        0.01,
        'smallest yaw sigma published (model error of real skies)',
        0.0,
        90.0,
        unit='deg',
    ),
    Param(
        'roll_pitch_variance_rad2',
        1000.0,
        'orientation_covariance roll and pitch variance (the heading carries no roll/pitch)',
        1.0,
        1.0e9,
        unit='rad^2',
    ),
    Param(
        'image_qos',
        'sensor_data',
        'subscription QoS of the image: sensor_data (REP-2003, best effort), reliable (5 deep) or '
        'replay (reliable, 32 deep: the images of a played bag queue behind a slow estimator, '
        "which replay.launch.py's player_flow keeps short; the replay graph)",
        choices=('sensor_data', 'reliable', 'replay'),
        read_only=True,
    ),
)


#: Parameters ``array_heading_estimator`` shares with ``heading_estimator`` (same meaning).
_ARRAY_SHARED = (
    'frame_id',
    'site_source',
    *(p.name for p in SITE),
    'time_source',
    'time_utc',
    'sun_model',
    'prior_source',
    'prior_max_age_s',
    'prior_sigma_deg',
    'imu_tolerance_s',
    'imu_max_wait_s',
    'publish_ambiguous',
    'sigma_floor_deg',
    'roll_pitch_variance_rad2',
)

ARRAY_ESTIMATOR = (
    Param(
        'method',
        'least_squares',
        "heading method (one node per method; only those that run on a photodiode array's units: "
        'least_squares, tilt_aware)',
        choices=ALL_METHODS,
        read_only=True,
    ),
    Param(
        'array_stamp',
        'header',
        'header = each sample takes the stamp and frame_id of the '
        'std_msgs/Header its driver publishes beside it on compass_array/header '
        '(paired by arrival time; unpaired samples are dropped and counted); '
        "arrival = this node's clock when the sample arrives (drivers without a "
        'header; latency becomes heading lag)',
        choices=('header', 'arrival'),
        read_only=True,
    ),
    Param(
        'array_header_tolerance_s',
        0.04,
        'array_stamp header: largest difference of the arrival times of '
        'a sample and its header (keep below half the sample interval)',
        0.0,
        1.0,
        unit='s',
        read_only=True,
    ),
    Param(
        'array_header_timeout_s',
        0.5,
        'array_stamp header: how long a sample waits for its header before '
        'it is dropped (wall clock)',
        0.001,
        60.0,
        unit='s',
        read_only=True,
    ),
    Param(
        'array_geometry',
        '',
        'the sensor description YAML (units, channels_deg, angle_zero, angle_sense, gains)',
        read_only=True,
    ),
    Param(
        'array_qos',
        'sensor_data',
        'subscription QoS of the samples: sensor_data (REP-2003, best effort) or reliable',
        choices=('sensor_data', 'reliable'),
        read_only=True,
    ),
    *(p for p in ESTIMATOR if p.name in _ARRAY_SHARED),
)

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

SPECS = {
    'sky_simulator': SIMULATOR,
    'heading_estimator': ESTIMATOR,
    'array_heading_estimator': ARRAY_ESTIMATOR,
    'tilt_corrector': CORRECTOR,
    'error_evaluator': EVALUATOR,
    'player_flow': PLAYER_FLOW,
}


def spec_by_name(specs) -> dict:
    """
    Return a node's parameter specifications by name.

    Parameters
    ----------
    specs : iterable of Param
        E.g. :data:`ESTIMATOR`.

    Returns
    -------
    dict
        ``{name: Param}``.

    """
    return {p.name: p for p in specs}


def defaults(specs) -> dict:
    """
    Return the default value of every parameter (tuples as lists, as ROS gives them).

    Parameters
    ----------
    specs : iterable of Param
        E.g. :data:`ESTIMATOR`.

    Returns
    -------
    dict
        ``{name: default}``.

    """
    return {
        p.name: (list(p.default) if isinstance(p.default, (list, tuple)) else p.default)
        for p in specs
    }


KNOB_PREFIX = 'knob.'


def knob_params(method: str, specs: dict | None = None) -> tuple:
    """
    Return the estimator's own knobs as run-time parameters ``knob.<name>``.

    Ranges come from the estimator. ``region`` and optional numbers become strings: ``""``
    means None, a region is ``"x0,y0,w,h"`` [px].

    Parameters
    ----------
    method : str
        A registered estimator name.
    specs : dict, optional
        Another knob table than the method's (a photodiode array's ``ARRAY_KNOBS``).

    Returns
    -------
    tuple of Param
        One parameter per knob, sorted by name, not read-only.

    """
    from ..estimators import registry

    specs = registry.get(method).knob_specs() if specs is None else specs
    out = []
    for name, k in sorted(specs.items()):
        lo = None if not math.isfinite(k.lo) else float(k.lo)
        hi = None if not math.isfinite(k.hi) else float(k.hi)
        desc = f'estimator knob: {k.doc}' if k.doc else 'estimator knob'
        if k.kind == 'int':
            out.append(
                Param(
                    KNOB_PREFIX + name,
                    int(k.default),
                    desc,
                    None if lo is None else int(lo),
                    None if hi is None else int(hi),
                )
            )
        elif k.kind == 'float':
            out.append(Param(KNOB_PREFIX + name, float(k.default), desc, lo, hi))
        elif k.kind == 'bool':
            out.append(Param(KNOB_PREFIX + name, bool(k.default), desc))
        elif k.kind == 'choice':
            out.append(
                Param(
                    KNOB_PREFIX + name,
                    str(k.default),
                    desc,
                    choices=tuple(str(c) for c in k.choices),
                )
            )
        else:  # region, float_or_none: text, "" = None
            d = (
                ''
                if k.default is None
                else ','.join(str(v) for v in k.default)
                if k.kind == 'region'
                else str(k.default)
            )
            out.append(
                Param(
                    KNOB_PREFIX + name,
                    d,
                    desc
                    + " ('' = none"
                    + (', else x0,y0,width,height)' if k.kind == 'region' else ', else a number)'),
                )
            )
    return tuple(out)


def knob_values(method: str, values: dict, specs: dict | None = None) -> dict:
    """
    Return estimator knobs from ``knob.<name>`` parameter values.

    Strings go back to None, tuples or choices (the inverse of :func:`knob_params`); knobs not in
    ``values`` are left out.

    Parameters
    ----------
    method : str
        A registered estimator name.
    values : dict
        Parameter values by full name (``knob.<name>``).
    specs : dict, optional
        As for :func:`knob_params`.

    Returns
    -------
    dict
        ``{knob name: value}`` for the estimator's constructor.

    """
    from ..estimators import registry

    specs = registry.get(method).knob_specs() if specs is None else specs
    out = {}
    for name, k in specs.items():
        key = KNOB_PREFIX + name
        if key not in values:
            continue
        v = values[key]
        if k.kind == 'region':
            v = None if v == '' else tuple(int(float(x)) for x in str(v).split(','))
        elif k.kind == 'float_or_none':
            v = None if v == '' else float(v)
        elif k.kind == 'choice':
            match = [c for c in k.choices if str(c) == v]
            v = match[0] if match else v
        out[name] = v
    return out


def markdown_tables() -> str:
    """
    Return the parameter tables of docs/ros.md (a test keeps the document equal to this).

    Returns
    -------
    str
        One Markdown table per node: parameter, default, range or choices, run time, meaning.

    """
    lines = []
    for node, specs in SPECS.items():
        lines += [
            '',
            f'#### {node}',
            '',
            '| parameter | default | range / choices | run time | meaning |',
            '|---|---|---|---|---|',
        ]
        for p in specs:
            if p.choices:
                rng = ' \\| '.join(p.choices)
            elif p.lo is not None:
                rng = f'[{p.lo:g}, {p.hi:g}]' + (f' {p.unit}' if p.unit else '')
            else:
                rng = p.unit
            d = str(p.default).lower() if isinstance(p.default, bool) else p.default
            d = '`""`' if d == '' else f'`{d}`'
            lines.append(
                f'| `{p.name}` | {d} | {rng} | {"no" if p.read_only else "yes"} | {p.description} '
                '|'
            )
    lines += [
        '',
        '#### heading_estimator knobs (`knob.<name>`, least_squares)',
        '',
        '| parameter | default | range / choices | meaning |',
        '|---|---|---|---|',
    ]
    for p in knob_params('least_squares'):
        if p.choices:
            rng = ' \\| '.join(p.choices)
        elif p.lo is not None and p.hi is not None:
            rng = f'[{p.lo:g}, {p.hi:g}]'
        elif p.lo is not None:
            rng = f'>= {p.lo:g}'
        else:
            rng = ''
        lines.append(
            f'| `{p.name}` | `{p.default}` | {rng} | '
            f'{p.description.replace("estimator knob: ", "")} |'
        )
    return '\n'.join(lines) + '\n'
