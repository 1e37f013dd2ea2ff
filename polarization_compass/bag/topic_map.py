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
The topic mapping of a field run: the topic and type of each role, and what a bag cannot say.

The mosaic layout, the pixel pitch, the camera mounting, fallbacks for a missing camera_info or
NavSatFix and synchronisation tolerances; read from a small YAML file (:func:`load_topic_map`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path

import numpy as np

from .errors import BagError
from ..camera import CameraError, CameraModel, READOUT_FLIPS
from ..conventions import R_BODY_CAM_DEFAULT

__all__ = [
    'ROLES',
    'ROLE_TYPES',
    'TopicSpec',
    'TopicMap',
    'BUILTIN_TOPIC_MAP',
    'load_topic_map',
    'default_topic_map',
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
    readout_flip : {"", "x", "y", "xy"}, default ""
        The image axes the camera mirrors on readout (the node's ``readout_flip``, CAMERA.yaml's):
        images and camera_info are read back as the sensor sees them, and ``mosaic`` describes the
        sensor.

    """

    topics: dict
    mosaic: dict = field(default_factory=dict)
    pixel_pitch_um: float = 3.45
    R_body_cam: tuple = tuple(map(tuple, R_BODY_CAM_DEFAULT))
    camera: dict | None = None
    site: dict | None = None
    max_gap_s: dict = field(default_factory=lambda: {'imu': 0.05, 'reference': 0.25})
    lookahead_s: float = 0.5
    readout_flip: str = ''

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
            ``site``, ``max_gap_s``, ``lookahead_s`` and ``readout_flip``.

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
            'readout_flip': self.readout_flip or 'none',
        }


def _topic_map_from_dict(d, where: str) -> TopicMap:
    """Return the :class:`TopicMap` of a mapping's YAML form, validated; absent keys: defaults."""
    _check_keys(d, where)
    base = _builtin_defaults()
    topics = _topics_from_dict(d.get('topics') or {}, base, where)
    mosaic = d.get('mosaic', base['mosaic']) or {}
    if not isinstance(mosaic, dict):
        raise BagError(f"{where}: 'mosaic' must be a mapping (the scene's sensor.mosaic form)")
    pitch = _pos(d.get('pixel_pitch_um', base['pixel_pitch_um']), f'{where}: pixel_pitch_um')
    R = _mounting_from_dict(d.get('mounting') or {}, where)
    camera = _checked_camera(d.get('camera'), where)
    site = _checked_site(d.get('site'), where)
    gaps = _gaps_from_dict(d.get('max_gap_s') or {}, base, where)
    look = _pos(d.get('lookahead_s', base['lookahead_s']), f'{where}: lookahead_s')
    flip = _readout_flip(d.get('readout_flip', base['readout_flip']), where)
    return TopicMap(
        topics, dict(mosaic), pitch, tuple(map(tuple, R)), camera, site, gaps, look, flip
    )


def _readout_flip(value, where: str) -> str:
    """Read ``readout_flip``: none (or null), x, y, xy (or yx); BagError otherwise."""
    v = '' if value in (None, 'none') else value
    if isinstance(v, str) and ''.join(sorted(v.lower())) in READOUT_FLIPS:
        return ''.join(sorted(v.lower()))
    raise BagError(f'{where}: readout_flip must be one of none, x, y, xy, got {value!r}')


def _check_keys(d, where: str) -> None:
    """Refuse a mapping that is not a dict or has keys other than the mapping's sections."""
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
        'readout_flip',
    }
    unknown = set(d) - allowed
    if unknown:
        raise BagError(f'{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}')


def _topics_from_dict(topics_d, base: dict, where: str) -> dict:
    """Return ``{role: TopicSpec}`` of the ``topics`` section (defaults for roles not given)."""
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
    return topics


def _mounting_from_dict(mounting, where: str) -> np.ndarray:
    """Return the mounting ``R_body_cam`` of the ``mounting`` section, checked to be a rotation."""
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
    return R


def _checked_camera(camera, where: str):
    """Return the fallback ``camera`` section (None or CameraModel fields the model accepts)."""
    if camera is not None:
        if not isinstance(camera, dict):
            raise BagError(
                f"{where}: 'camera' must be null or CameraModel fields (model, width_px, ...)"
            )
        try:
            CameraModel(**camera)
        except (CameraError, TypeError) as exc:
            raise BagError(f'{where}: camera: {exc}') from None
    return camera


def _checked_site(site, where: str):
    """Return the fallback ``site`` section (None or latitude, longitude[, altitude] in range)."""
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
    return site


def _gaps_from_dict(g, base: dict, where: str) -> dict:
    """Return the ``max_gap_s`` tolerances [s]: the defaults updated by the section's entries."""
    gaps = dict(base['max_gap_s'])
    if not isinstance(g, dict) or set(g) - set(gaps):
        raise BagError(f"{where}: 'max_gap_s' must map {sorted(gaps)} to seconds")
    for k, v in g.items():
        gaps[k] = _pos(v, f'{where}: max_gap_s.{k}')
    return gaps


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
    'readout_flip': 'none',
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
