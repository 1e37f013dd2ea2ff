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
The ROS-free message codec: rosbags message classes <-> numpy, and ROS stamps <-> time.

Decoding is duck-typed (rosbags classes and rclpy messages alike): camera_info, orientations and
NavSatFix; encoding builds the rosbags messages a driver, an IMU or a GNSS would publish.
"""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from .errors import _one_line, BagError, MessageError
from ..camera import camera_from_intrinsics, CameraError, CameraModel, check_intrinsics
from ..conventions import QuaternionError, validate_quaternion

__all__ = [
    'typestore',
    'stamp_ns',
    'stamp_from_ns',
    'utc_from_ns',
    'ns_from_utc',
    'decode_camera_info',
    'decode_orientation',
    'decode_navsatfix',
    'encode_mosaic',
    'encode_camera_info',
    'encode_imu',
    'encode_quaternion_stamped',
    'encode_navsatfix',
    'deserialize',
]


# --------------------------------------------------------------------------------------------
# Typestore (one, cached): ROS 2 Kilted message definitions (identical to Jazzy for these types)
# --------------------------------------------------------------------------------------------
_TYPESTORE = None


def typestore():
    """
    Return the rosbags typestore used to (de)serialize: ROS 2 Kilted definitions (cached).

    Returns
    -------
    rosbags.typesys.store.Typestore
        The one typestore of the process (Kilted, the ROS this repo pins; identical to Jazzy for
        the message types used here).

    """
    global _TYPESTORE
    if _TYPESTORE is None:
        from rosbags.typesys import get_typestore, Stores

        _TYPESTORE = get_typestore(Stores.ROS2_KILTED)
    return _TYPESTORE


# --------------------------------------------------------------------------------------------
# Time
# --------------------------------------------------------------------------------------------
def stamp_ns(header) -> int:
    """
    Return the nanoseconds since the epoch of a std_msgs/Header or builtin_interfaces/Time.

    Parameters
    ----------
    header : object
        A message header with a ``stamp``, or the stamp itself (``sec``, ``nanosec``).

    Returns
    -------
    int
        The stamp [ns since the Unix epoch].

    """
    st = getattr(header, 'stamp', header)
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def stamp_from_ns(t_ns: int):
    """
    Return a builtin_interfaces/msg/Time (rosbags class) for nanoseconds since the epoch.

    Parameters
    ----------
    t_ns : int
        Stamp [ns since the Unix epoch].

    Returns
    -------
    builtin_interfaces.msg.Time
        ``sec`` and ``nanosec`` (in [0, 1e9)).

    """
    Time = typestore().types['builtin_interfaces/msg/Time']
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=int(sec), nanosec=int(nsec))


def utc_from_ns(t_ns: int) -> _dt.datetime:
    """
    Return the aware UTC datetime of a ROS stamp (ROS time is Unix time: UTC, no leap seconds).

    Parameters
    ----------
    t_ns : int
        Stamp [ns since the Unix epoch].

    Returns
    -------
    datetime.datetime
        UTC, truncated to the microsecond.

    """
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return _dt.datetime.fromtimestamp(sec, tz=_dt.timezone.utc) + _dt.timedelta(
        microseconds=nsec // 1000
    )


def ns_from_utc(t: _dt.datetime) -> int:
    """
    Return the ROS stamp of a datetime (the inverse of :func:`utc_from_ns`).

    Parameters
    ----------
    t : datetime.datetime
        An aware datetime (any zone; a naive one is taken as local time by ``astimezone``).

    Returns
    -------
    int
        Stamp [ns since the Unix epoch], exact to the microsecond.

    """
    t = t.astimezone(_dt.timezone.utc)
    epoch = _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)
    d = t - epoch
    return (d.days * 86400 + d.seconds) * 1_000_000_000 + d.microseconds * 1000


# --------------------------------------------------------------------------------------------
# Decoding (message -> numpy). Duck-typed: works on rosbags classes and on rclpy messages alike.
# --------------------------------------------------------------------------------------------
def decode_camera_info(msg, pixel_pitch_um: float) -> CameraModel:
    """
    Return a :class:`CameraModel` from the sensor_msgs/CameraInfo of the raw mosaic.

    ROS ``K = [fx 0 cx; 0 fy cy; 0 0 1]`` in pixels with a 0-based principal point; the model is
    1-based (eq 20), so ``principal_x_px = cx + 1``. The focal length in mm is ``fx *
    pixel_pitch``; the y pitch is scaled by ``fx / fy`` so non-square pixels keep their shape.
    ``plumb_bob``/``rational_polynomial`` -> pinhole, ``equidistant`` -> fisheye_equidistant (r = f
    theta); non-zero D is the lens distortion, undistorted through OpenCV
    (:func:`~polarization_compass.camera.camera_from_intrinsics`). Implausible intrinsics
    (:func:`~polarization_compass.camera.check_intrinsics`: principal point outside the image or
    far from its centre, fx and fy differing by more than 5 %) are ``bad_camera_info``.

    Parameters
    ----------
    msg : sensor_msgs.msg.CameraInfo
        The message (duck-typed).
    pixel_pitch_um : float
        Pixel pitch [um] along x (the bag does not carry it).

    Returns
    -------
    CameraModel
        The camera, focal length [mm], principal point [px, 1-based].

    Raises
    ------
    MessageError
        ``non_finite`` (K/D NaN, inf or wrong size), ``bad_camera_info`` (focal lengths <= 0 or
        intrinsics the camera model refuses), ``unsupported_camera`` (other distortion model,
        binning or a region of interest).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 20.

    """
    K = np.asarray(msg.k, dtype=float).reshape(-1)
    D = np.asarray(msg.d, dtype=float).reshape(-1)
    if K.size != 9 or not np.all(np.isfinite(K)) or not np.all(np.isfinite(D)):
        raise MessageError('non_finite', 'camera_info K/D has NaN, inf or the wrong size')
    fx, fy = K[0], K[4]
    if not (fx > 0 and fy > 0):
        raise MessageError(
            'bad_camera_info', f'focal lengths must be positive, got fx={fx}, fy={fy}'
        )
    if str(msg.distortion_model) not in ('', 'plumb_bob', 'rational_polynomial', 'equidistant'):
        raise MessageError('unsupported_camera', f'distortion model {msg.distortion_model!r}')
    if int(msg.binning_x) > 1 or int(msg.binning_y) > 1:
        raise MessageError('unsupported_camera', 'binned images are not supported')
    roi = msg.roi
    if int(roi.width) not in (0, int(msg.width)) or int(roi.height) not in (0, int(msg.height)):
        raise MessageError('unsupported_camera', 'a region of interest is not supported')
    try:
        cam = camera_from_intrinsics(
            int(msg.width), int(msg.height), K, D, str(msg.distortion_model), float(pixel_pitch_um)
        )
        return check_intrinsics(cam)  # plausible calibration: pp near the centre, fx ~ fy
    except CameraError as exc:
        raise MessageError('bad_camera_info', str(exc)) from None


def decode_orientation(msg) -> np.ndarray:
    """
    Return the unit quaternion of a sensor_msgs/Imu or geometry_msgs/QuaternionStamped.

    Parameters
    ----------
    msg : sensor_msgs.msg.Imu or geometry_msgs.msg.QuaternionStamped
        The message (duck-typed); the orientation is the body (REP-103 base_link) in ENU.

    Returns
    -------
    numpy.ndarray
        ``(x, y, z, w)``, normalised.

    Raises
    ------
    MessageError
        ``no_orientation`` (an Imu whose ``orientation_covariance[0]`` is -1, REP-145),
        ``non_finite`` (NaN/inf components) or ``bad_quaternion`` (not a usable quaternion).

    """
    if hasattr(msg, 'orientation'):
        cov = np.asarray(msg.orientation_covariance, dtype=float).reshape(-1)
        if cov.size and cov[0] == -1:
            raise MessageError(
                'no_orientation', 'Imu orientation_covariance[0] = -1: no orientation given'
            )
        q = msg.orientation
    else:
        q = msg.quaternion
    try:
        return validate_quaternion([q.x, q.y, q.z, q.w])
    except QuaternionError as exc:
        reason = 'non_finite' if 'NaN' in str(exc) else 'bad_quaternion'
        raise MessageError(reason, str(exc)) from None


def decode_navsatfix(msg) -> tuple[float, float, float]:
    """
    Return the site of a sensor_msgs/NavSatFix with a fix.

    A NaN altitude (allowed by the message: "unknown") becomes 0 m; it changes the sun by far less
    than a microdegree.

    Parameters
    ----------
    msg : sensor_msgs.msg.NavSatFix
        The message (duck-typed).

    Returns
    -------
    latitude_deg, longitude_deg : float
        WGS-84 latitude [deg] in [-90, 90] and longitude [deg] in [-180, 180], east positive.
    altitude_m : float
        Altitude [m] (0 when unknown).

    Raises
    ------
    MessageError
        ``no_fix`` (status < STATUS_FIX, 0), ``non_finite`` (NaN/inf latitude or longitude) or
        ``bad_value`` (out of range).

    """
    status = int(msg.status.status)
    if status < 0:
        raise MessageError('no_fix', f'NavSatFix status {status} (no fix)')
    lat, lon, alt = float(msg.latitude), float(msg.longitude), float(msg.altitude)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise MessageError('non_finite', 'NavSatFix latitude/longitude is NaN or inf')
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise MessageError('bad_value', f'NavSatFix latitude {lat} / longitude {lon} out of range')
    if not math.isfinite(alt):
        alt = 0.0
    return lat, lon, alt


# --------------------------------------------------------------------------------------------
# Encoding (numpy -> rosbags message), what a driver / GNSS / IMU would publish
# --------------------------------------------------------------------------------------------
def _header(t_ns: int, frame_id: str):
    Header = typestore().types['std_msgs/msg/Header']
    return Header(stamp=stamp_from_ns(t_ns), frame_id=frame_id)


def encode_mosaic(mosaic: np.ndarray, t_ns: int, frame_id: str):
    """
    Return a sensor_msgs/Image ``mono8``/``mono16`` (little endian) of a raw mosaic.

    As a camera driver sends it.

    Parameters
    ----------
    mosaic : numpy.ndarray
        2-D uint8 or uint16 raw mosaic [counts].
    t_ns : int
        Header stamp [ns since the Unix epoch].
    frame_id : str
        Header frame id.

    Returns
    -------
    sensor_msgs.msg.Image
        The rosbags message.

    Raises
    ------
    BagError
        The mosaic is not a 2-D uint8/uint16 array.

    """
    m = np.asarray(mosaic)
    if m.ndim != 2 or m.dtype not in (np.uint8, np.uint16):
        raise BagError(f'a mosaic must be a 2-D uint8/uint16 array, got {m.dtype} {m.shape}')
    enc = 'mono8' if m.dtype == np.uint8 else 'mono16'
    le = np.ascontiguousarray(m, dtype=m.dtype.newbyteorder('<'))
    Image = typestore().types['sensor_msgs/msg/Image']
    return Image(
        header=_header(t_ns, frame_id),
        height=int(m.shape[0]),
        width=int(m.shape[1]),
        encoding=enc,
        is_bigendian=0,
        step=int(m.shape[1] * m.dtype.itemsize),
        data=le.view(np.uint8).reshape(-1),
    )


def encode_camera_info(camera: CameraModel, t_ns: int, frame_id: str):
    """
    Return the sensor_msgs/CameraInfo of a :class:`CameraModel`.

    The inverse of :func:`decode_camera_info`: K in pixels with a 0-based principal point, the
    model's distortion (or none: zeros of ``plumb_bob``/``equidistant``).

    Parameters
    ----------
    camera : CameraModel
        The camera (focal length [mm], pixel pitch [um], principal point [px, 1-based]).
    t_ns : int
        Header stamp [ns since the Unix epoch].
    frame_id : str
        Header frame id.

    Returns
    -------
    sensor_msgs.msg.CameraInfo
        The rosbags message.

    """
    ts = typestore().types
    fx = camera.focal_length_mm / (camera.pixel_pitch_x_um * 1e-3)
    fy = camera.focal_length_mm / (camera.pixel_pitch_y_um * 1e-3)
    cx, cy = camera.cx_px - 1.0, camera.cy_px - 1.0
    K = np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=float)
    P = np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], dtype=float)
    fisheye = camera.model == 'fisheye_equidistant'
    roi = ts['sensor_msgs/msg/RegionOfInterest'](
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    return ts['sensor_msgs/msg/CameraInfo'](
        header=_header(t_ns, frame_id),
        height=int(camera.height_px),
        width=int(camera.width_px),
        distortion_model=camera.distortion_model or ('equidistant' if fisheye else 'plumb_bob'),
        d=np.array(camera.distortion, dtype=float)
        if camera.distortion
        else np.zeros(4 if fisheye else 5),
        k=K,
        r=np.eye(3).reshape(-1),
        p=P,
        binning_x=0,
        binning_y=0,
        roi=roi,
    )


def encode_imu(q_xyzw, t_ns: int, frame_id: str, orientation_var_rad2=(0.0, 0.0, 0.0)):
    """
    Return a sensor_msgs/Imu carrying an orientation only.

    Angular velocity and acceleration covariances are -1 (REP-145: not provided).

    Parameters
    ----------
    q_xyzw : array_like
        Orientation quaternion ``(x, y, z, w)`` of the body in ENU.
    t_ns : int
        Header stamp [ns since the Unix epoch].
    frame_id : str
        Header frame id.
    orientation_var_rad2 : sequence of float, default (0, 0, 0)
        Roll, pitch and yaw variances [rad^2] (the covariance's diagonal).

    Returns
    -------
    sensor_msgs.msg.Imu
        The rosbags message.

    """
    ts = typestore().types
    q = np.asarray(q_xyzw, dtype=float)
    Q = ts['geometry_msgs/msg/Quaternion'](
        x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
    )
    zero = ts['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
    none = np.zeros(9)
    none[0] = -1.0
    return ts['sensor_msgs/msg/Imu'](
        header=_header(t_ns, frame_id),
        orientation=Q,
        orientation_covariance=np.diag(np.asarray(orientation_var_rad2, float)).reshape(-1),
        angular_velocity=zero,
        angular_velocity_covariance=none.copy(),
        linear_acceleration=zero,
        linear_acceleration_covariance=none.copy(),
    )


def encode_quaternion_stamped(q_xyzw, t_ns: int, frame_id: str):
    """
    Return a geometry_msgs/QuaternionStamped of an orientation.

    Parameters
    ----------
    q_xyzw : array_like
        Orientation quaternion ``(x, y, z, w)`` of the body in ENU.
    t_ns : int
        Header stamp [ns since the Unix epoch].
    frame_id : str
        Header frame id.

    Returns
    -------
    geometry_msgs.msg.QuaternionStamped
        The rosbags message.

    """
    ts = typestore().types
    q = np.asarray(q_xyzw, dtype=float)
    Q = ts['geometry_msgs/msg/Quaternion'](
        x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
    )
    return ts['geometry_msgs/msg/QuaternionStamped'](header=_header(t_ns, frame_id), quaternion=Q)


def encode_navsatfix(
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    t_ns: int,
    frame_id: str,
    horizontal_sigma_m: float = 1.0,
    vertical_sigma_m: float = 2.0,
):
    """
    Return a sensor_msgs/NavSatFix with a GPS fix at a site.

    Parameters
    ----------
    lat_deg, lon_deg : float
        WGS-84 latitude and longitude [deg], east positive.
    alt_m : float
        Altitude [m].
    t_ns : int
        Header stamp [ns since the Unix epoch].
    frame_id : str
        Header frame id.
    horizontal_sigma_m, vertical_sigma_m : float, default 1 and 2
        Position standard deviations [m] (diagonal covariance, type
        ``COVARIANCE_TYPE_DIAGONAL_KNOWN``).

    Returns
    -------
    sensor_msgs.msg.NavSatFix
        The rosbags message (status ``STATUS_FIX``, service GPS).

    """
    ts = typestore().types
    St = ts['sensor_msgs/msg/NavSatStatus']
    status = St(status=0, service=1)  # STATUS_FIX, SERVICE_GPS
    cov = np.diag([horizontal_sigma_m**2, horizontal_sigma_m**2, vertical_sigma_m**2]).reshape(-1)
    return ts['sensor_msgs/msg/NavSatFix'](
        header=_header(t_ns, frame_id),
        status=status,
        latitude=float(lat_deg),
        longitude=float(lon_deg),
        altitude=float(alt_m),
        position_covariance=cov,
        position_covariance_type=2,
    )


def deserialize(raw, msgtype: str):
    """
    Return the rosbags message of CDR bytes.

    Through a memoryview: rosbags then slices without copying, and array fields (an image's data)
    are read-only views of ``raw`` (a 10 MB mosaic is not copied twice per frame).

    Parameters
    ----------
    raw : bytes or memoryview
        Serialized message.
    msgtype : str
        Message type, e.g. ``"sensor_msgs/msg/Imu"``.

    Returns
    -------
    object
        The message (rosbags class).

    Raises
    ------
    MessageError
        ``bad_cdr`` if the bytes do not parse.

    """
    try:
        return typestore().deserialize_cdr(memoryview(raw), msgtype)
    except Exception as exc:  # noqa: BLE001 - SerdeError, struct.error, ... all mean the same here
        raise MessageError('bad_cdr', _one_line(exc)) from None
