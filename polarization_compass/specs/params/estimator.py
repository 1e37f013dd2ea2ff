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
"""The heading estimators' parameters: ``heading_estimator`` and ``array_heading_estimator``."""

from .methods import ALL_METHODS
from .site_sun import SITE, SITE_SOURCE
from .spec import _iso_or_empty, _layout_problem, _not_optical, Param

#: the camera's tilt on the body, composed with the IMU's attitude wherever the camera's tilt is
#: read (heading_estimator, tilt_corrector)
MOUNT = (
    Param(
        'mount_pitch_deg',
        0.0,
        "the camera's pitch on the body (CAMERA.yaml mount: pitch_deg, written by "
        "'polarization-compass calibrate-mount'): composed with the IMU's attitude wherever the "
        "camera's tilt is read (tilt_aware's levelling, the tilt corrector's error map)",
        -45.0,
        45.0,
        unit='deg',
        read_only=True,
    ),
    Param(
        'mount_roll_deg',
        0.0,
        "the camera's roll on the body (CAMERA.yaml mount: roll_deg), as mount_pitch_deg",
        -45.0,
        45.0,
        unit='deg',
        read_only=True,
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
        'readout_flip',
        'none',
        'image axes the camera mirrors on readout (GenICam ReverseX = x, ReverseY = y, both = '
        'xy): the image is read back as the sensor sees it and the camera_info K mirrored with '
        "it; the layout then describes the sensor (check with 'polarization-compass "
        "check-polarizer')",
        choices=('none', 'x', 'y', 'xy'),
        read_only=True,
    ),
    Param(
        'pol45_toward',
        '+x-y',
        'image direction of the 45 deg polarizer on the sensor: +x-y (up and right on the '
        'displayed image: the IMX250MZR as delivered) or +x+y; a mirrored readout is '
        "readout_flip, not this; check with 'polarization-compass check-polarizer'",
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
        'principal_point_sigma_px',
        -1.0,
        "the camera calibration's 1-sigma of the principal point (camera_info states none); "
        "negative: 0.5 % of the focal length, a calibration's typical one. As the camera tilt it "
        "is equivalent to, atan(sigma / f), it grows every heading's sigma (the sky cannot see a "
        "principal point off across the sun's image direction); 0 for exact intrinsics",
        -1.0,
        2000.0,
        unit='px',
        read_only=True,
    ),
    *MOUNT,
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
        'subscription QoS of the samples: sensor_data (REP-2003, best effort) or reliable; '
        'either keeps 100 samples waiting (a slow first estimate loses none)',
        choices=('sensor_data', 'reliable'),
        read_only=True,
    ),
    *(p for p in ESTIMATOR if p.name in _ARRAY_SHARED),
)
