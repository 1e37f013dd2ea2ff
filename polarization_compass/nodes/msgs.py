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
Rclpy message construction and validation shared by the nodes.

Decoding is duck-typed and shared with the offline replay: :mod:`polarization_compass.bag` decodes
mosaics (:func:`decode_image`, the one image decoder: cv_bridge where installed), camera_info,
orientations and NavSatFix; this module builds rclpy messages and applies robot_localization's
conventions to the heading:

* ``orientation``: a pure REP-103 yaw quaternion (roll = pitch = 0), normalised;
* ``orientation_covariance``: row-major about x, y, z: large roll and pitch variances, the yaw
  variance from the estimator's sigma (rad^2); element 0 is never -1;
* ``angular_velocity_covariance[0] = linear_acceleration_covariance[0] = -1``: not provided;
* ``header.frame_id``: a z-up frame with a TF to base_link, never a camera optical frame;
* ``header.stamp``: the image's stamp.
"""

from __future__ import annotations

import math

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import KeyValue
import numpy as np
from sensor_msgs.msg import CameraInfo, Image, Imu, NavSatFix, NavSatStatus

from ..bag.codec import decode_orientation, stamp_ns
from ..bag.errors import MessageError
from ..bag.image import decode_mosaic, image_decoder
from ..camera import CameraModel
from ..conventions import matrix_to_quat, wrap_360_deg, yaw_enu_quaternion

__all__ = [
    'MessageError',
    'stamp_ns',
    'time_msg',
    'heading_imu',
    'attitude_imu',
    'image_msg',
    'decode_image',
    'camera_info_msg',
    'navsatfix_msg',
    'yaw_enu_from_quat',
    'bearing_from_imu',
    'heading_from_imu',
    'kv',
    'IMAGE_ENCODINGS',
    'image_decoder',
]

IMAGE_ENCODINGS = ('mono8', 'mono16', '32FC1')
NOT_PROVIDED = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]


def time_msg(t_ns: int) -> Time:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=int(sec), nanosec=int(nsec))


def heading_imu(
    t_ns: int,
    frame_id: str,
    yaw_enu_rad: float,
    yaw_variance_rad2: float,
    roll_pitch_variance_rad2: float,
) -> Imu:
    """Build the heading as robot_localization fuses it (see the module docstring)."""
    if not (
        math.isfinite(yaw_enu_rad) and math.isfinite(yaw_variance_rad2) and yaw_variance_rad2 > 0
    ):
        raise ValueError('heading_imu: non-finite yaw or non-positive variance')
    m = Imu()
    m.header.stamp = time_msg(t_ns)
    m.header.frame_id = frame_id
    q = yaw_enu_quaternion(yaw_enu_rad)
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (float(v) for v in q)
    rp = float(roll_pitch_variance_rad2)
    m.orientation_covariance = [rp, 0.0, 0.0, 0.0, rp, 0.0, 0.0, 0.0, float(yaw_variance_rad2)]
    m.angular_velocity_covariance = list(NOT_PROVIDED)
    m.linear_acceleration_covariance = list(NOT_PROVIDED)
    return m


def attitude_imu(
    t_ns: int,
    frame_id: str,
    R_enu_body: np.ndarray,
    variances_rad2,
    angular_velocity_body=None,
    gravity_body=None,
) -> Imu:
    """
    Build a full-attitude IMU message (the simulated IMU): orientation of ``frame_id`` in ENU.

    ``variances_rad2``: roll, pitch, yaw orientation variances. Angular velocity and linear
    acceleration are filled when given (rad/s, m/s^2, body frame) with a small covariance, else
    marked not provided.
    """
    m = Imu()
    m.header.stamp = time_msg(t_ns)
    m.header.frame_id = frame_id
    q = matrix_to_quat(R_enu_body)
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (float(v) for v in q)
    vr, vp, vy = (float(v) for v in variances_rad2)
    m.orientation_covariance = [vr, 0.0, 0.0, 0.0, vp, 0.0, 0.0, 0.0, vy]
    if angular_velocity_body is None:
        m.angular_velocity_covariance = list(NOT_PROVIDED)
    else:
        w = [float(v) for v in angular_velocity_body]
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = w
        m.angular_velocity_covariance = [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-6]
    if gravity_body is None:
        m.linear_acceleration_covariance = list(NOT_PROVIDED)
    else:
        a = [float(v) for v in gravity_body]
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = a
        m.linear_acceleration_covariance = [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-4]
    return m


def yaw_enu_from_quat(q_xyzw) -> float:
    """REP-103 yaw (rad, ZYX convention) of a unit quaternion (x, y, z, w)."""
    x, y, z, w = (float(v) for v in q_xyzw)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def bearing_from_imu(msg) -> float:
    """Return the true bearing (deg, [0, 360)) of body +x from an Imu orientation: 90 - yaw."""
    q = decode_orientation(msg)
    return float(wrap_360_deg(90.0 - math.degrees(yaw_enu_from_quat(q))))


def heading_from_imu(msg) -> tuple[float, float]:
    """
    Decode a heading published by :func:`heading_imu` into bearing and yaw variance.

    (bearing_deg, yaw variance rad^2) of a heading in the form :func:`heading_imu` publishes.
    Raises :class:`MessageError` (``reason`` tag) for a bad orientation or a yaw variance that is
    not finite and > 0.
    """
    bearing = bearing_from_imu(msg)
    var = float(msg.orientation_covariance[8])
    if not (math.isfinite(var) and var > 0):
        raise MessageError('bad_covariance', f'yaw variance {var!r} must be finite and > 0')
    return bearing, var


def image_msg(array: np.ndarray, t_ns: int, frame_id: str) -> Image:
    """
    Build a sensor_msgs/Image of a 2-D uint8, uint16 or float32 array.

    Encoded ``mono8``, ``mono16`` or ``32FC1``, little endian, unpadded.
    """
    a = np.asarray(array)
    enc = {
        np.dtype(np.uint8): 'mono8',
        np.dtype(np.uint16): 'mono16',
        np.dtype(np.float32): '32FC1',
    }.get(a.dtype)
    if a.ndim != 2 or enc is None:
        raise ValueError(
            f'image_msg: need a 2-D uint8/uint16/float32 array, got {a.dtype} {a.shape}'
        )
    le = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder('<'))
    m = Image()
    m.header.stamp = time_msg(t_ns)
    m.header.frame_id = frame_id
    m.height, m.width = int(a.shape[0]), int(a.shape[1])
    m.encoding = enc
    m.is_bigendian = 0
    m.step = int(a.shape[1] * a.dtype.itemsize)
    m.data = le.tobytes()
    return m


def array_msg(intensities: np.ndarray):
    """
    Build the std_msgs/Float32MultiArray of one photodiode-array sample.

    Units x channels, row-major (``layout.dim`` [units, channels]): the layout heading_estimator
    reads with ``input: array``.
    """
    from std_msgs.msg import Float32MultiArray, MultiArrayDimension

    a = np.asarray(intensities, dtype=np.float32)
    if a.ndim != 2:
        raise ValueError(f'array_msg: need (units, channels), got shape {a.shape}')
    m = Float32MultiArray()
    m.layout.dim = [
        MultiArrayDimension(label='units', size=int(a.shape[0]), stride=int(a.size)),
        MultiArrayDimension(label='channels', size=int(a.shape[1]), stride=int(a.shape[1])),
    ]
    m.data = a.ravel().tolist()
    return m


#: The one image decoder (:func:`polarization_compass.bag.image.decode_mosaic`): cv_bridge where
#: it is installed, else numpy, with the same checks; the offline replay uses it too.
decode_image = decode_mosaic
# Choose the decoder as a node starts, not in its first image callback: importing cv_bridge takes
# ~1 s, during which a burst of images overflows the image queue (test_nodes_robustness's burst).
image_decoder()


def camera_info_msg(camera: CameraModel, t_ns: int, frame_id: str) -> CameraInfo:
    """
    Build the CameraInfo of the raw mosaic (0-based principal point).

    CameraInfo of the raw mosaic: K in pixels with a 0-based principal point, the camera's
    distortion or none (``plumb_bob`` for the pinhole model, ``equidistant`` for the r = f theta
    fisheye).
    """
    fx = camera.focal_length_mm / (camera.pixel_pitch_x_um * 1e-3)
    fy = camera.focal_length_mm / (camera.pixel_pitch_y_um * 1e-3)
    cx, cy = camera.cx_px - 1.0, camera.cy_px - 1.0
    m = CameraInfo()
    m.header.stamp = time_msg(t_ns)
    m.header.frame_id = frame_id
    m.height, m.width = int(camera.height_px), int(camera.width_px)
    fisheye = camera.model == 'fisheye_equidistant'
    m.distortion_model = camera.distortion_model or ('equidistant' if fisheye else 'plumb_bob')
    m.d = list(camera.distortion) if camera.distortion else [0.0] * (4 if fisheye else 5)
    m.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    m.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    m.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return m


def navsatfix_msg(
    lat_deg: float, lon_deg: float, alt_m: float, t_ns: int, frame_id: str
) -> NavSatFix:
    m = NavSatFix()
    m.header.stamp = time_msg(t_ns)
    m.header.frame_id = frame_id
    m.status.status = NavSatStatus.STATUS_FIX
    m.status.service = NavSatStatus.SERVICE_GPS
    m.latitude, m.longitude, m.altitude = float(lat_deg), float(lon_deg), float(alt_m)
    m.position_covariance = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 4.0]
    m.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    return m


def kv(key: str, value) -> KeyValue:
    if isinstance(value, float):
        value = f'{value:.6g}'
    return KeyValue(key=str(key), value=str(value))
