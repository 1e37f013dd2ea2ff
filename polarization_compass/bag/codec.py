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

rosbag2 field runs: the topic mapping, reading with per-topic skip accounting, writing, and the
ROS-free conversions between the rosbags message classes and numpy.

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

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
import datetime as _dt
import math
from pathlib import Path

import numpy as np

from ..camera import camera_from_intrinsics, CameraError, CameraModel, check_intrinsics
from ..conventions import QuaternionError, R_BODY_CAM_DEFAULT, validate_quaternion
from ..errors import CompassError

__all__ = [
    'BagError',
    'MessageError',
    'TopicSpec',
    'TopicMap',
    'load_topic_map',
    'default_topic_map',
    'ROLES',
    'ROLE_TYPES',
    'Tally',
    'BagReader',
    'BagWriter',
    'typestore',
    'stamp_ns',
    'stamp_from_ns',
    'decode_mosaic',
    'decode_camera_info',
    'decode_orientation',
    'decode_navsatfix',
    'encode_mosaic',
    'encode_camera_info',
    'encode_imu',
    'encode_quaternion_stamped',
    'encode_navsatfix',
    'utc_from_ns',
]

ROLES = ('image', 'camera_info', 'imu', 'reference', 'navsatfix')

#: Message types each role accepts.
ROLE_TYPES = {
    'image': ('sensor_msgs/msg/Image',),
    'camera_info': ('sensor_msgs/msg/CameraInfo',),
    'imu': ('sensor_msgs/msg/Imu', 'geometry_msgs/msg/QuaternionStamped'),
    'reference': ('sensor_msgs/msg/Imu', 'geometry_msgs/msg/QuaternionStamped'),
    'navsatfix': ('sensor_msgs/msg/NavSatFix',),
}

_ENCODINGS = {
    'mono8': np.uint8,
    '8UC1': np.uint8,
    'mono16': np.uint16,
    '16UC1': np.uint16,
    '32FC1': np.float32,
}


class BagError(CompassError):
    """
    A bag error: unreadable rosbag2, bad topic mapping or a bag that cannot be written.

    A path that is not a readable rosbag2, a bad topic mapping, or a bag that cannot be written.
    """


class MessageError(CompassError):
    """One message that cannot be used. ``reason`` is a short tag for the skip summary."""

    def __init__(self, reason: str, detail: str):
        super().__init__(f'{reason}: {detail}')
        self.reason = reason
        self.detail = detail


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
# Topic mapping
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TopicSpec:
    """
    Hold the topic name and message type of one role.

    Parameters
    ----------
    topic : str
        Absolute topic name, e.g. ``"/camera/image_raw"``.
    type : str
        Message type, e.g. ``"sensor_msgs/msg/Image"`` (one of :data:`ROLE_TYPES` for the role).

    """

    topic: str
    type: str  # noqa: A003 - the ROS message type, as the topic-map YAML key ``type``


@dataclass(frozen=True)
class TopicMap:
    """
    Map roles to topics and types, plus what a bag cannot say.

    The mosaic layout, the pixel pitch, the camera mounting, fallbacks for a missing camera_info
    or NavSatFix, and synchronisation tolerances. Built by :func:`load_topic_map`.

    Parameters
    ----------
    topics : dict
        ``{role: TopicSpec}`` for every role of :data:`ROLES`.
    mosaic : dict
        The sensor's mosaic description in the form of the scene's ``sensor.mosaic`` section.
    pixel_pitch_um : float, default 3.45
        Pixel pitch [um]: converts camera_info focal lengths [px] into the model's [mm].
    R_body_cam : tuple of tuple of float
        (3, 3) rotation from camera to body (columns: the camera axes in REP-103 base_link);
        default :data:`~polarization_compass.conventions.R_BODY_CAM_DEFAULT`.
    camera : dict, optional
        Fallback :class:`CameraModel` fields when the bag has no camera_info.
    site : dict, optional
        Fallback ``{latitude_deg, longitude_deg, altitude_m}`` [deg, deg, m] when the bag has no
        NavSatFix.
    max_gap_s : dict
        For ``imu`` and ``reference``, the largest time [s] between an image stamp and a sample
        used with it (the site is the latest NavSatFix, as on the nodes).
    lookahead_s : float, default 0.5
        How far [s of bag receive time] the reader looks past an image before processing it.

    """

    topics: dict
    mosaic: dict = field(default_factory=dict)
    pixel_pitch_um: float = 3.45
    R_body_cam: tuple = tuple(map(tuple, R_BODY_CAM_DEFAULT))
    camera: dict | None = None
    site: dict | None = None
    max_gap_s: dict = field(default_factory=lambda: {'imu': 0.05, 'reference': 0.25})
    lookahead_s: float = 0.5

    def __hash__(self):
        return id(self)

    def spec(self, role: str) -> TopicSpec:
        """
        Return the topic and type of ``role``.

        Parameters
        ----------
        role : str
            One of :data:`ROLES`.

        Returns
        -------
        TopicSpec
            Its topic and type (``KeyError`` for an unknown role).

        """
        return self.topics[role]

    def role_of_topic(self, topic: str) -> str | None:
        """
        Return the role a topic is mapped to.

        Parameters
        ----------
        topic : str
            Absolute topic name.

        Returns
        -------
        str or None
            The role, or None when the topic is not mapped.

        """
        for role, s in self.topics.items():
            if s.topic == topic:
                return role
        return None

    @property
    def R_body_cam_array(self) -> np.ndarray:
        """Return the camera mounting ``R_body_cam`` as a (3, 3) float array."""
        return np.array(self.R_body_cam, dtype=float)

    def to_dict(self) -> dict:
        """
        Return the mapping in its YAML form (what :func:`load_topic_map` reads).

        Returns
        -------
        dict
            ``topics``, ``mosaic``, ``pixel_pitch_um``, ``mounting.R_body_cam``, ``camera``,
            ``site``, ``max_gap_s`` and ``lookahead_s``.

        """
        return {
            'topics': {r: {'topic': s.topic, 'type': s.type} for r, s in self.topics.items()},
            'mosaic': dict(self.mosaic),
            'pixel_pitch_um': self.pixel_pitch_um,
            'mounting': {'R_body_cam': [list(r) for r in self.R_body_cam]},
            'camera': self.camera,
            'site': self.site,
            'max_gap_s': dict(self.max_gap_s),
            'lookahead_s': self.lookahead_s,
        }


def _topic_map_from_dict(d, where: str) -> TopicMap:
    if not isinstance(d, dict):
        raise BagError(f"{where}: a topic mapping must be a YAML mapping with a 'topics' section")
    allowed = {
        'topics',
        'mosaic',
        'pixel_pitch_um',
        'mounting',
        'camera',
        'site',
        'max_gap_s',
        'lookahead_s',
    }
    unknown = set(d) - allowed
    if unknown:
        raise BagError(f'{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}')
    base = _builtin_defaults()
    topics_d = d.get('topics') or {}
    if not isinstance(topics_d, dict):
        raise BagError(f"{where}: 'topics' must map roles ({', '.join(ROLES)}) to {{topic, type}}")
    bad = set(topics_d) - set(ROLES)
    if bad:
        raise BagError(
            f'{where}: unknown role(s) {sorted(bad)} in topics; roles: {", ".join(ROLES)}'
        )
    topics = {}
    for role in ROLES:
        entry = topics_d.get(role, {})
        if isinstance(entry, str):
            entry = {'topic': entry}
        if not isinstance(entry, dict) or set(entry) - {'topic', 'type'}:
            raise BagError(f'{where}: topics.{role} must be {{topic: /name, type: pkg/msg/Type}}')
        topic = str(entry.get('topic', base['topics'][role]['topic']))
        mtype = str(entry.get('type', ROLE_TYPES[role][0]))
        if not topic.startswith('/'):
            raise BagError(
                f"{where}: topics.{role}.topic must be an absolute name starting with '/', got "
                f'{topic!r}'
            )
        if mtype not in ROLE_TYPES[role]:
            raise BagError(
                f'{where}: topics.{role}.type {mtype!r} is not supported; '
                f'use one of {", ".join(ROLE_TYPES[role])}'
            )
        topics[role] = TopicSpec(topic, mtype)
    names = [s.topic for s in topics.values()]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise BagError(f'{where}: topic(s) {sorted(dup)} mapped to more than one role')
    mosaic = d.get('mosaic', base['mosaic']) or {}
    if not isinstance(mosaic, dict):
        raise BagError(f"{where}: 'mosaic' must be a mapping (the scene's sensor.mosaic form)")
    pitch = _pos(d.get('pixel_pitch_um', base['pixel_pitch_um']), f'{where}: pixel_pitch_um')
    mounting = d.get('mounting') or {}
    if not isinstance(mounting, dict) or set(mounting) - {'R_body_cam'}:
        raise BagError(
            f"{where}: 'mounting' must be {{R_body_cam: 3x3 rotation (columns = camera axes in "
            f'body)}}'
        )
    R = (
        np.asarray(mounting.get('R_body_cam', R_BODY_CAM_DEFAULT), dtype=float)
        if mounting
        else R_BODY_CAM_DEFAULT
    )
    if (
        R.shape != (3, 3)
        or not np.all(np.isfinite(R))
        or not np.allclose(R @ R.T, np.eye(3), atol=1e-6)
        or abs(np.linalg.det(R) - 1) > 1e-6
    ):
        raise BagError(
            f'{where}: mounting.R_body_cam must be a 3x3 rotation matrix (orthonormal, det +1)'
        )
    camera = d.get('camera')
    if camera is not None:
        if not isinstance(camera, dict):
            raise BagError(
                f"{where}: 'camera' must be null or CameraModel fields (model, width_px, ...)"
            )
        try:
            CameraModel(**camera)
        except (CameraError, TypeError) as exc:
            raise BagError(f'{where}: camera: {exc}') from None
    site = d.get('site')
    if site is not None:
        if (
            not isinstance(site, dict)
            or set(site) - {'latitude_deg', 'longitude_deg', 'altitude_m'}
            or not {'latitude_deg', 'longitude_deg'} <= set(site)
        ):
            raise BagError(
                f"{where}: 'site' must be null or {{latitude_deg, longitude_deg[, altitude_m]}}"
            )
        _finite_in(site['latitude_deg'], -90, 90, f'{where}: site.latitude_deg')
        _finite_in(site['longitude_deg'], -180, 180, f'{where}: site.longitude_deg')
        _finite_in(site.get('altitude_m', 0.0), -500, 10000, f'{where}: site.altitude_m')
    gaps = dict(base['max_gap_s'])
    g = d.get('max_gap_s') or {}
    if not isinstance(g, dict) or set(g) - set(gaps):
        raise BagError(f"{where}: 'max_gap_s' must map {sorted(gaps)} to seconds")
    for k, v in g.items():
        gaps[k] = _pos(v, f'{where}: max_gap_s.{k}')
    look = _pos(d.get('lookahead_s', base['lookahead_s']), f'{where}: lookahead_s')
    return TopicMap(topics, dict(mosaic), pitch, tuple(map(tuple, R)), camera, site, gaps, look)


def _pos(v, what) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise BagError(f'{what} must be a number, got {v!r}') from None
    if not (math.isfinite(f) and f > 0):
        raise BagError(f'{what} must be positive and finite, got {v!r}')
    return f


def _finite_in(v, lo, hi, what) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise BagError(f'{what} must be a number, got {v!r}') from None
    if not (math.isfinite(f) and lo <= f <= hi):
        raise BagError(f'{what} must be finite and in [{lo}, {hi}], got {v!r}')
    return f


#: The defaults: what ``record-sim`` writes. ``config/replay_topics.yaml`` is this mapping written
#: out for users to copy and edit (a test keeps the two identical).
BUILTIN_TOPIC_MAP = {
    'topics': {
        'image': {'topic': '/camera/image_raw', 'type': 'sensor_msgs/msg/Image'},
        'camera_info': {'topic': '/camera/camera_info', 'type': 'sensor_msgs/msg/CameraInfo'},
        'imu': {'topic': '/imu/data', 'type': 'sensor_msgs/msg/Imu'},
        'reference': {'topic': '/ground_truth/heading', 'type': 'sensor_msgs/msg/Imu'},
        'navsatfix': {'topic': '/gps/fix', 'type': 'sensor_msgs/msg/NavSatFix'},
    },
    'mosaic': {},
    'pixel_pitch_um': 3.45,
    'mounting': {'R_body_cam': [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]},
    'camera': None,
    'site': None,
    'max_gap_s': {'imu': 0.05, 'reference': 0.25},
    'lookahead_s': 0.5,
}


def _builtin_defaults() -> dict:
    return BUILTIN_TOPIC_MAP


def load_topic_map(path: str | Path | None = None) -> TopicMap:
    """
    Load a topic mapping YAML (safe loader); keys not given keep their defaults.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The YAML file (form of ``config/replay_topics.yaml``); None gives the defaults (what
        ``record-sim`` writes).

    Returns
    -------
    TopicMap
        The validated mapping.

    Raises
    ------
    BagError
        The file is missing or unreadable, not valid YAML, or a key, role, topic, type, mounting
        rotation, camera, site or tolerance is invalid (one-line message naming it).

    """
    from ..safe_load import load_yaml, read_text

    if path is None:
        return _topic_map_from_dict(_builtin_defaults(), 'default topic mapping')
    text = read_text(path, BagError, 'topic mapping')  # missing, directory, not UTF-8: one line
    return _topic_map_from_dict(load_yaml(text, str(path), BagError) or {}, str(path))


def default_topic_map() -> TopicMap:
    """
    Return the default topic mapping (what ``record-sim`` writes).

    Returns
    -------
    TopicMap
        :func:`load_topic_map` of None.

    """
    return load_topic_map(None)


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
def decode_mosaic(msg) -> np.ndarray:
    """
    Return the raw mosaic of a sensor_msgs/Image as a (height, width) array, native byte order.

    uint8 (``mono8``/``8UC1``), uint16 (``mono16``/``16UC1``: drivers put 10/12-bit samples in
    these) or float32 (``32FC1``: the simulator's ideal polarizer intensities, finite and >= 0).

    Parameters
    ----------
    msg : sensor_msgs.msg.Image
        The message (rosbags class or rclpy message: duck-typed).

    Returns
    -------
    numpy.ndarray
        The mosaic [counts, or intensity for ``32FC1``], shape (height, width); a view of the
        message's data when already native and unpadded.

    Raises
    ------
    MessageError
        ``bad_encoding`` (unsupported encoding), ``bad_size`` (odd or < 2 dimensions, step <
        width x bytes per pixel, data length != step x height), and for ``32FC1``
        ``non_finite`` (NaN/inf) or ``bad_value`` (negative intensities).

    """
    enc = str(msg.encoding)
    if enc not in _ENCODINGS:
        raise MessageError(
            'bad_encoding',
            f'image encoding {enc!r} is not a raw polarizer mosaic '
            f'(expected one of {", ".join(_ENCODINGS)})',
        )
    dtype = np.dtype(_ENCODINGS[enc])
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    buf = (
        np.frombuffer(msg.data, dtype=np.uint8)
        if not isinstance(msg.data, np.ndarray)
        else msg.data.view(np.uint8).reshape(-1)
    )
    if h < 2 or w < 2 or h % 2 or w % 2:
        raise MessageError('bad_size', f'mosaic {w}x{h} must have even width and height >= 2')
    if step < w * dtype.itemsize:
        raise MessageError('bad_size', f'step {step} < width {w} x {dtype.itemsize} bytes')
    if buf.size != step * h:
        raise MessageError('bad_size', f'data has {buf.size} bytes, step x height = {step * h}')
    rows = buf.reshape(h, step)[:, : w * dtype.itemsize]
    img = (
        rows.view(dtype.newbyteorder('>' if msg.is_bigendian else '<'))
        if dtype.itemsize > 1
        else rows
    )
    img = np.ascontiguousarray(img, dtype=dtype)  # a view when already native and unpadded
    if dtype.kind == 'f':
        if not np.isfinite(img).all():
            raise MessageError('non_finite', f'{enc} mosaic has NaN or inf pixels')
        if (img < 0).any():
            raise MessageError('bad_value', f'{enc} mosaic has negative intensities')
    return img


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


# --------------------------------------------------------------------------------------------
# Skip accounting
# --------------------------------------------------------------------------------------------
class Tally:
    """
    Count per topic the messages read, used, and skipped by reason.

    Nothing leaves a bag unaccounted: for every topic, ``read == used + sum(skipped)`` once a
    replay finishes (:meth:`balanced`). ``read`` and ``used`` are :class:`collections.Counter`
    objects by topic that callers increment.
    """

    def __init__(self):
        self.read: Counter = Counter()
        self.used: Counter = Counter()
        self.skipped: Counter = Counter()  # (topic, reason) -> n
        self.notes: Counter = Counter()  # (topic, note) -> n, not skips (e.g. out_of_order)
        self.examples: dict = {}  # (topic, reason) -> first detail message

    def skip(self, topic: str, reason: str, detail: str = '') -> None:
        """
        Count one skipped message of ``topic``.

        Parameters
        ----------
        topic : str
            Topic name.
        reason : str
            Short tag, e.g. ``"bad_cdr"`` (a :class:`MessageError`'s ``reason``).
        detail : str, default ""
            Message of the first skip for this topic and reason, kept as an example.

        """
        self.skipped[(topic, reason)] += 1
        self.examples.setdefault((topic, reason), detail)

    def note(self, topic: str, what: str) -> None:
        """
        Count one event of ``topic`` that is not a skip (e.g. ``out_of_order``).

        Parameters
        ----------
        topic : str
            Topic name.
        what : str
            Short tag of the event.

        """
        self.notes[(topic, what)] += 1

    def skipped_total(self, topic: str | None = None) -> int:
        """
        Return the number of skipped messages.

        Parameters
        ----------
        topic : str, optional
            Count this topic only; None counts all topics.

        Returns
        -------
        int
            Skips over all reasons.

        """
        return sum(n for (t, _), n in self.skipped.items() if topic is None or t == topic)

    def balanced(self) -> bool:
        """
        Return whether every topic's read count equals used plus skipped.

        Returns
        -------
        bool
            True when no message is unaccounted.

        """
        return all(self.read[t] == self.used[t] + self.skipped_total(t) for t in self.read)

    def to_dict(self) -> dict:
        """
        Return the counts as plain data, by topic.

        Returns
        -------
        dict
            ``{topic: {"read", "used", "skipped": {reason: n}, "notes": {what: n}[, "first_reason":
            {reason: detail}]}}``, topics sorted.

        """
        topics = sorted(set(self.read) | {t for t, _ in self.skipped} | {t for t, _ in self.notes})
        out = {}
        for t in topics:
            out[t] = {
                'read': self.read[t],
                'used': self.used[t],
                'skipped': {r: n for (tt, r), n in sorted(self.skipped.items()) if tt == t},
                'notes': {r: n for (tt, r), n in sorted(self.notes.items()) if tt == t},
            }
            ex = {
                r: self.examples[(tt, r)]
                for (tt, r) in self.skipped
                if tt == t and self.examples.get((tt, r))
            }
            if ex:
                out[t]['first_reason'] = ex
        return out

    def lines(self) -> list[str]:
        """
        Return a human-readable summary, one line per topic.

        Returns
        -------
        list of str
            E.g. ``"/imu/data: read 10, used 9, skipped: bad_cdr 1"``.

        """
        out = []
        for t, d in self.to_dict().items():
            s = ', '.join(f'{r} {n}' for r, n in d['skipped'].items()) or 'none'
            extra = (
                '; ' + ', '.join(f'{r} {n}' for r, n in d['notes'].items()) if d['notes'] else ''
            )
            out.append(f'{t}: read {d["read"]}, used {d["used"]}, skipped: {s}{extra}')
        return out


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
class BagReader:
    """
    A rosbag2 (directory with metadata.yaml; MCAP or sqlite3) opened for reading.

    ``BagReader(path)`` raises :class:`BagError` with one line if the path is not a readable bag.
    Use as a context manager. :meth:`messages` yields ``(topic, msgtype, log_time_ns, raw_cdr)``
    in the bag's receive-time order for the topics asked.
    """

    def __init__(self, path):
        from rosbags.rosbag2 import Reader

        p = Path(path)
        if not p.exists():
            raise BagError(f'bag {str(p)!r} does not exist')
        if p.is_file() and p.suffix == '.mcap' and not (p.parent / 'metadata.yaml').exists():
            raise BagError(
                f'{str(p)!r} is a bare MCAP file; give the rosbag2 directory (with '
                'metadata.yaml), '
                'or run `ros2 bag reindex` on its directory'
            )
        if p.is_file() and (p.parent / 'metadata.yaml').exists():
            p = p.parent
        if not p.is_dir():
            raise BagError(
                f'{str(p)!r} is not a rosbag2 directory (a directory with metadata.yaml)'
            )
        self.path = p
        self.damage: str | None = None  # what went wrong reading, once the bag is read (one line)
        self.recovered: str | None = None  # how a damaged bag was opened (one line), or None
        self._read_counts: Counter = Counter()  # messages yielded per topic
        storage = sorted(x for x in p.iterdir() if x.suffix in ('.mcap', '.db3') and x.is_file())
        if (p / 'metadata.yaml').exists() or (p / 'metadata.yaml').is_symlink():
            from ..safe_load import (
                regular_file,  # not a FIFO or /dev/zero (rosbags would read it forever)
            )

            regular_file(p / 'metadata.yaml', BagError, 'bag metadata', max_bytes=16 << 20)
        if not (p / 'metadata.yaml').is_file():
            if len(storage) != 1:
                raise BagError(f'{str(p)!r} is not a rosbag2 directory: it has no metadata.yaml')
            # a recorder killed before it wrote metadata.yaml: read its one storage file up to the
            # damage
            self._reader = _recovered_storage(
                storage[0], 'no metadata.yaml (a recorder killed before the end)'
            )
            self.recovered = self._reader.note
            return
        try:
            self._reader = Reader(p)
            self._reader.open()
        except Exception as exc:  # noqa: BLE001 - rosbags raises several types for a bad bag
            first = f'{str(p)!r} is not a readable rosbag2: {_one_line(exc)}'
            if len(storage) != 1:
                raise BagError(first) from None
            try:
                self._reader = _recovered_storage(storage[0], _one_line(exc))
            except Exception:  # noqa: BLE001 - not recoverable either: the first error says why
                raise BagError(first) from None
            self.recovered = self._reader.note

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Close the bag; errors while closing a half-broken bag are ignored."""
        try:
            self._reader.close()
        except Exception:  # noqa: BLE001 - closing a half-broken bag must not mask the real error
            pass

    @property
    def duration_s(self) -> float:
        """Time between the first and the last message [s] (0 for an empty bag)."""
        return self._reader.duration / 1e9 if self._reader.message_count else 0.0

    @property
    def message_count(self) -> int:
        """Return the number of messages in the bag, all topics."""
        return int(self._reader.message_count)

    def topic_types(self) -> dict:
        """
        Return each topic's message types and counts over all connections.

        Returns
        -------
        dict
            ``{topic: {msgtype: message count}}`` (a topic recorded from publishers of different
            types has one connection per type).

        """
        out: dict = {}
        for c in self._reader.connections:
            types = out.setdefault(c.topic, {})
            types[c.msgtype] = types.get(c.msgtype, 0) + int(c.msgcount)
        return out

    def topics(self) -> dict:
        """
        Return the topics of the bag with their types and message counts.

        Returns
        -------
        dict
            ``{topic: (msgtype, message count)}`` over all connections (types joined by ``|``
            when a topic has several).

        """
        out: dict = {}
        for c in self._reader.connections:
            t, n = out.get(c.topic, (c.msgtype, 0))
            if t != c.msgtype:
                t = f'{t}|{c.msgtype}'
            out[c.topic] = (t, n + int(c.msgcount))
        return out

    def messages(self, topics):
        """
        Yield the messages of the given topics in receive-time order.

        Parameters
        ----------
        topics : iterable of str
            Topic names; unknown ones are ignored.

        Yields
        ------
        tuple
            ``(topic, msgtype, log_time_ns, raw)``: receive time [ns], raw CDR bytes.

        Raises
        ------
        BagError
            A storage-level failure part-way (truncated file, bad chunk), naming the bag.

        """
        conns = [c for c in self._reader.connections if c.topic in set(topics)]
        if not conns:
            return
        self._requested = getattr(self, '_requested', set()) | {c.topic for c in conns}
        try:
            for c, t, raw in self._reader.messages(connections=conns):
                self._read_counts[c.topic] += 1
                yield c.topic, c.msgtype, int(t), raw
        except BagError:
            raise
        # damage part-way: what was read stands, the rest is counted lost
        except Exception as exc:  # noqa: BLE001
            self.damage = f'reading stopped part-way ({_one_line(exc)})'

    def lost(self) -> dict:
        """
        Return the messages the bag's index announces that were not read (a damaged bag).

        Returns
        -------
        dict
            ``{topic: count}`` for the topics read by :meth:`messages`; empty when everything
            announced was read or nothing is announced.

        """
        expected = {c.topic: 0 for c in self._reader.connections}
        for c in self._reader.connections:
            expected[c.topic] += int(getattr(c, 'msgcount', 0) or 0)
        announced = getattr(self._reader, 'announced', None) or expected
        asked = getattr(self, '_requested', set())
        return {
            t: n - self._read_counts.get(t, 0)
            for t, n in announced.items()
            if n > self._read_counts.get(t, 0) and t in asked
        }

    def damage_notes(self) -> list[str]:
        """
        Return one-line statements of damage found while opening or reading.

        Returns
        -------
        list of str
            Empty for a sound bag; else how it was read and the messages lost per topic.

        """
        notes = []
        if self.recovered:
            notes.append(f'damaged bag: {self.recovered}')
        if self.damage:
            notes.append(f'damaged bag: {self.damage}')
        lost = self.lost() if (self.recovered or self.damage) else {}
        if lost:
            notes.append(
                'messages lost to the damage: '
                + ', '.join(f'{t} {n}' for t, n in sorted(lost.items()))
            )
        elif self.recovered or self.damage:
            notes.append(
                'messages lost to the damage: unknown (the bag has no index of what it held)'
            )
        return notes


class _RecoveredConnection:
    """A connection of a recovered storage file (what rosbags' readers expose)."""

    def __init__(self, cid, topic, msgtype, msgcount):
        self.id, self.topic, self.msgtype, self.msgcount = cid, topic, msgtype, msgcount


class _RecoveredMcap:
    """
    An MCAP file cut short, read up to its last complete record.

    An MCAP file cut short (a killed recorder, a copy that stopped) read with rosbags' own MCAP
    reader up to the last complete record: the reader gets the intact prefix followed by a footer
    that announces no summary, so it scans the records (``McapReader.meta_scan``/``messages_scan``,
    as for an unindexed file) instead of refusing the missing footer (``File end magic is
    invalid``).
    """

    _MAGIC = b'\x89MCAP0\r\n'

    def __init__(self, path: Path, why: str):
        import struct

        from rosbags.rosbag2.storage_mcap import McapReader

        self.path = path
        size = path.stat().st_size
        with open(path, 'rb') as fh:
            head = fh.read(8)
            if head != self._MAGIC:
                raise BagError(f'{path.name}: not an MCAP file')
            pos = 8
            good = None
            while pos + 9 <= size:  # records: opcode (1), length (8), body
                fh.seek(pos)
                op, n = struct.unpack('<BQ', fh.read(9))
                end = pos + 9 + n
                if end > size or op == 0x0F and n == 0:
                    break
                if op in (
                    0x02,
                    0x0E,
                    0x0F,
                ):  # footer, summary offset, data end: the data ends here
                    break
                good = end
                pos = end
        if good is None:
            raise BagError(f'{path.name}: no complete MCAP record')
        self.discarded_bytes = size - good
        footer = bytes([0x02]) + struct.pack('<QQQI', 20, 0, 0, 0) + self._MAGIC
        self._bio = _PrefixWithTail(path, good, footer)
        self._mcap = McapReader(path)
        self._mcap.bio = self._bio
        try:
            self._mcap._open()  # rosbags' own reader; scans (no index)
        except BaseException:
            self._bio.close()
            raise
        if not self._mcap.connections or not self._mcap.metadata.message_count:
            self._bio.close()
            raise BagError(f'{path.name}: nothing readable before the damage')
        self.connections = [
            _RecoveredConnection(c.id, c.topic, c.msgtype, c.msgcount)
            for c in self._mcap.connections
        ]
        self._by_id = {c.id: c for c in self._mcap.connections}
        self.message_count = int(self._mcap.metadata.message_count)
        self.duration = int(self._mcap.metadata.duration)
        self.announced = _announced_counts(path.parent)
        self.note = (
            f"{why}; read with rosbags' MCAP reader up to the last complete record "
            f'({self.message_count} messages; {self.discarded_bytes} bytes at the end discarded)'
        )

    def messages(self, connections):
        conns = [self._by_id[c.id] for c in connections]
        for c, t, raw in self._mcap.messages(conns):
            yield c, t, raw

    def close(self):
        self._bio.close()


class _PrefixWithTail:
    """
    A read-only file object: the first ``n`` bytes of ``path`` followed by ``tail``.

    A read-only file object: the first ``n`` bytes of ``path`` followed by ``tail`` (a synthetic
    footer).
    """

    def __init__(self, path: Path, n: int, tail: bytes):
        self._fh = open(path, 'rb')
        self._n, self._tail, self._pos = int(n), bytes(tail), 0

    def seek(self, off: int, whence: int = 0) -> int:
        size = self._n + len(self._tail)
        self._pos = max(0, {0: off, 1: self._pos + off, 2: size + off}[whence])
        return self._pos

    def tell(self) -> int:
        return self._pos

    def read(self, k: int = -1) -> bytes:
        size = self._n + len(self._tail)
        k = size - self._pos if k is None or k < 0 else min(k, size - self._pos)
        out = b''
        if self._pos < self._n and k > 0:
            self._fh.seek(self._pos)
            out = self._fh.read(min(k, self._n - self._pos))
        rest = k - len(out)
        if rest > 0:
            start = self._pos + len(out) - self._n
            out += self._tail[start:start + rest]
        self._pos += len(out)
        return out

    def close(self) -> None:
        self._fh.close()


class _RecoveredSqlite:
    """
    A truncated rosbag2 sqlite3 file read with Python's sqlite3.

    A truncated rosbag2 sqlite3 file read with Python's sqlite3 (rosbags' reader counts every
    topic's messages when it opens, which fails on the first missing page): a temporary copy whose
    header page count is set to the pages present, read in insertion order (rowid) until the first
    missing page.
    """

    def __init__(self, path: Path, why: str):
        import shutil
        import sqlite3
        import struct
        import tempfile

        self.path = path
        self._tmp = tempfile.TemporaryDirectory(prefix='pc_bag_recover_')
        copy = Path(self._tmp.name) / path.name
        shutil.copyfile(path, copy)
        with open(copy, 'r+b') as fh:
            hdr = fh.read(100)
            if not hdr.startswith(b'SQLite format 3\x00'):
                raise BagError(f'{path.name}: not an SQLite file')
            page = struct.unpack('>H', hdr[16:18])[0]
            page = 65536 if page == 1 else page
            pages = copy.stat().st_size // page
            fh.truncate(pages * page)
            fh.seek(28)
            fh.write(struct.pack('>I', pages))
        self._db = sqlite3.connect(f'file:{copy}?mode=ro', uri=True, check_same_thread=False)
        rows = self._db.execute('SELECT id, name, type FROM topics ORDER BY id').fetchall()
        counts: Counter = Counter()
        try:  # what is readable (topic ids only: no message data is read)
            for (cid,) in self._db.execute('SELECT topic_id FROM messages ORDER BY id'):
                counts[cid] += 1
        except sqlite3.DatabaseError:
            pass
        self.connections = [
            _RecoveredConnection(i, name, mtype, counts[i]) for i, name, mtype in rows
        ]
        self.message_count = sum(counts.values())
        if not self.message_count:
            self.close()
            raise BagError(f'{path.name}: nothing readable before the damage')
        self.duration = 0
        self.announced = _announced_counts(path.parent)
        self.note = (
            f"{why}; read with Python's sqlite3 from a copy whose header counts the pages "
            'present, '
            'in recording order up to the first missing page'
        )

    def messages(self, connections):
        by_id = {c.id: c for c in connections}
        for cid, t, data in self._db.execute(
            'SELECT topic_id, timestamp, data FROM messages ORDER BY id'
        ):
            c = by_id.get(cid)
            if c is not None:
                yield c, int(t), data

    def close(self):
        try:
            self._db.close()
        finally:
            self._tmp.cleanup()


def _announced_counts(directory: Path) -> dict | None:
    """{topic: message count} from a rosbag2 metadata.yaml, or None when absent or unreadable."""
    from ..safe_load import load_yaml, read_text

    try:
        d = load_yaml(
            read_text(directory / 'metadata.yaml', BagError, 'bag metadata'), 'metadata', BagError
        )
        info = d['rosbag2_bagfile_information']
        return {
            t['topic_metadata']['name']: int(t['message_count'])
            for t in info['topics_with_message_count']
        }
    except (BagError, KeyError, TypeError, ValueError):
        return None


def _recovered_storage(path: Path, why: str):
    """
    Open a damaged bag's single storage file up to the damage.

    A damaged bag's single storage file opened up to the damage (:class:`_RecoveredMcap` or
    :class:`_RecoveredSqlite`); raises when that is not possible either.
    """
    return (_RecoveredMcap if path.suffix == '.mcap' else _RecoveredSqlite)(path, why)


def _one_line(exc) -> str:
    s = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {s[0]}' if s else type(exc).__name__


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


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
class BagWriter:
    """
    Write a rosbag2 with rosbags; one connection per role.

    ``write(role, msg, log_time_ns)`` serialises a rosbags message; ``write_raw`` stores bytes as
    they are (tests use it to plant corrupt messages). Use as a context manager.

    Parameters
    ----------
    path : str or os.PathLike
        The bag directory to create; it must not exist (rosbag2 refuses to overwrite) and its
        parent must.
    topic_map : TopicMap, optional
        Topics and types of the roles; default :func:`default_topic_map`.
    storage : {"mcap", "sqlite3"}, default "mcap"
        Storage plugin.
    extra_topics : dict, optional
        ``{topic: msgtype}`` of further connections, written under the topic name as role.

    Raises
    ------
    BagError
        The path exists, its directory does not, or the storage is unknown.

    """

    def __init__(
        self, path, topic_map: TopicMap | None = None, storage: str = 'mcap', extra_topics=None
    ):
        from rosbags.rosbag2 import StoragePlugin, Writer

        p = Path(path)
        if p.exists():
            raise BagError(f'output {str(p)!r} already exists; rosbag2 does not overwrite bags')
        if not p.parent.is_dir():
            raise BagError(f'directory {str(p.parent)!r} for the output bag does not exist')
        plugins = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
        if storage not in plugins:
            raise BagError(f"storage must be 'mcap' or 'sqlite3', got {storage!r}")
        self.path = p
        self.topic_map = topic_map or default_topic_map()
        self._writer = Writer(p, version=9, storage_plugin=plugins[storage])
        self._writer.open()
        self._conns = {}
        ts = typestore()
        for role, spec in self.topic_map.topics.items():
            self._conns[role] = self._writer.add_connection(spec.topic, spec.type, typestore=ts)
        for topic, mtype in (extra_topics or {}).items():
            self._conns[topic] = self._writer.add_connection(topic, mtype, typestore=ts)
        self.counts: Counter = Counter()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Close the bag (writes its metadata); closing twice is harmless."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def write(self, role: str, msg, log_time_ns: int) -> None:
        """
        Serialise and write one message.

        Parameters
        ----------
        role : str
            A role of the topic map, or a topic of ``extra_topics``.
        msg : object
            A rosbags message of that connection's type.
        log_time_ns : int
            Receive time [ns since the Unix epoch] (the bag's order).

        """
        raw = typestore().serialize_cdr(msg, self._conns[role].msgtype)
        self.write_raw(role, raw, log_time_ns)

    def write_raw(self, role: str, raw: bytes, log_time_ns: int) -> None:
        """
        Write bytes as they are (no serialisation), e.g. a planted corrupt message.

        Parameters
        ----------
        role : str
            A role of the topic map, or a topic of ``extra_topics``.
        raw : bytes
            The CDR payload.
        log_time_ns : int
            Receive time [ns since the Unix epoch].

        """
        self._writer.write(self._conns[role], int(log_time_ns), raw)
        self.counts[role] += 1
