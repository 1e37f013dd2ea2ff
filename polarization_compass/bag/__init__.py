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
rosbag2 field runs: topic mapping, reading, writing and message conversions.

The topic mapping (:mod:`.topic_map`), reading with per-topic skip accounting (:mod:`.reader`,
with :mod:`.recovery` for a truncated bag), writing (:mod:`.writer`), and the ROS-free
conversions between the rosbags message classes and numpy (:mod:`.codec`, :mod:`.image`).

Bags are read and written with the `rosbags` library (pure Python; both rosbag2 storage formats:
MCAP, the default of ``ros2 bag record`` since Jazzy, and sqlite3). Nothing here imports rclpy.

Roles
-----
A field run has five roles; a small YAML file (:func:`load_topic_map`, default
``config/replay_topics.yaml``, the names ``record-sim`` writes) maps each role to a topic and type:

``image``        sensor_msgs/msg/Image: the raw 2x2 polarizer mosaic as the driver publishes it
                 (``mono8``/``mono16``; no ROS encoding exists for polarization mosaics, the layout
                 comes from the mapping's ``mosaic`` section).
``camera_info``  sensor_msgs/msg/CameraInfo of the raw mosaic (``plumb_bob``/``equidistant``, no
                 distortion).
``imu``          sensor_msgs/msg/Imu (or geometry_msgs/msg/QuaternionStamped): body attitude in
                 ENU; only its roll and pitch are used (the tilt), its yaw is ignored.
``reference``    the true heading, e.g. a dual-antenna GNSS: sensor_msgs/msg/Imu (the form the
                 estimator publishes and robot_localization reads: REP-103 yaw in ENU, frame
                 ``base_link``) or geometry_msgs/msg/QuaternionStamped.
``navsatfix``    sensor_msgs/msg/NavSatFix: the site, for the sun's position.

Frames: the IMU and reference quaternions are the orientation of the body (REP-103 ``base_link``: x
forward, y left, z up) in ENU. The camera is mounted by ``R_body_cam`` (mapping key
``mounting.R_body_cam``, default :data:`~polarization_compass.conventions.R_BODY_CAM_DEFAULT`:
looking up, camera +y forward), so ``R_enu_cam = R_enu_body @ R_body_cam``. With the default
mounting the REP-103 yaw of the body is exactly ``90 deg - bearing`` of the camera (eq 21), tilted
or not.

Corrupt input
-------------
A message that cannot be used is never silently dropped: :class:`Tally` counts it per topic and
reason (``bad_cdr``, ``bad_encoding``, ``bad_size``, ``non_finite``, ``bad_quaternion``, ...), it
is skipped, and the rest of the bag is processed.

"""

from .codec import (
    decode_camera_info,
    decode_navsatfix,
    decode_orientation,
    deserialize,
    encode_camera_info,
    encode_imu,
    encode_mosaic,
    encode_navsatfix,
    encode_quaternion_stamped,
    ns_from_utc,
    stamp_from_ns,
    stamp_ns,
    typestore,
    utc_from_ns,
)
from .errors import BagError, MessageError
from .image import decode_mosaic
from .reader import BagReader, Tally
from .topic_map import (
    BUILTIN_TOPIC_MAP,
    default_topic_map,
    load_topic_map,
    ROLE_TYPES,
    ROLES,
    TopicMap,
    TopicSpec,
)
from .writer import BagWriter

__all__ = [
    'BagError',
    'MessageError',
    'TopicSpec',
    'TopicMap',
    'BUILTIN_TOPIC_MAP',
    'load_topic_map',
    'default_topic_map',
    'ROLES',
    'ROLE_TYPES',
    'Tally',
    'BagReader',
    'BagWriter',
    'typestore',
    'deserialize',
    'stamp_ns',
    'stamp_from_ns',
    'utc_from_ns',
    'ns_from_utc',
    'decode_mosaic',
    'decode_camera_info',
    'decode_orientation',
    'decode_navsatfix',
    'encode_mosaic',
    'encode_camera_info',
    'encode_imu',
    'encode_quaternion_stamped',
    'encode_navsatfix',
]
