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
The messages of what the compass sees (issue 25): the debug picture and the heading markers.

``~/debug_image``: ``sensor_msgs/Image``, ``rgb8``, unpadded (:func:`rgb_image_msg`).
``~/heading_marker``: ``visualization_msgs/Marker`` in the heading Imu's frame: an arrow along the
REP-103 yaw and its +-sigma sector (:func:`heading_markers`).
"""

from __future__ import annotations

import math

import numpy as np
from sensor_msgs.msg import Image

from .msgs import time_msg
from ..conventions import yaw_enu_quaternion

__all__ = ['heading_markers', 'rgb_image_msg']


def rgb_image_msg(rgb: np.ndarray, t_ns: int, frame_id: str) -> Image:
    """
    Build a sensor_msgs/Image (``rgb8``, unpadded) of a uint8 (H, W, 3) array.

    Parameters
    ----------
    rgb : numpy.ndarray
        uint8 picture, shape (H, W, 3).
    t_ns : int
        Stamp [ns].
    frame_id : str
        The header's frame.

    Returns
    -------
    sensor_msgs.msg.Image
        The message.

    Raises
    ------
    ValueError
        The array is not (H, W, 3).

    """
    a = np.ascontiguousarray(rgb, dtype=np.uint8)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f'rgb_image_msg: need a uint8 (H, W, 3) array, got {a.shape}')
    m = Image()
    m.header.stamp = time_msg(t_ns)
    m.header.frame_id = frame_id
    m.height, m.width = int(a.shape[0]), int(a.shape[1])
    m.encoding = 'rgb8'
    m.is_bigendian = 0
    m.step = int(3 * a.shape[1])
    m.data = a.tobytes()
    return m


def heading_markers(t_ns: int, frame_id: str, yaw_enu_deg: float, sigma_deg=None) -> list:
    """
    Build the heading's markers: an arrow (id 0) and its +-sigma sector (id 1, a line list).

    In ``frame_id`` like the heading Imu: the arrow (1 m) points along the REP-103 yaw (counter-
    clockwise from East, about +z), the sector's two lines at yaw +- sigma. Both last 2 s, so a
    compass that stops answering leaves no stale arrow.

    Parameters
    ----------
    t_ns : int
        Stamp [ns].
    frame_id : str
        The output frame (the heading Imu's).
    yaw_enu_deg : float
        REP-103 yaw [deg].
    sigma_deg : float, optional
        1-sigma of the yaw [deg]; no sector without it.

    Returns
    -------
    list of visualization_msgs.msg.Marker
        The arrow, then the sector when there is a sigma.

    """
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker

    yaw = math.radians(yaw_enu_deg)
    arrow = Marker()
    arrow.header.stamp = time_msg(t_ns)
    arrow.header.frame_id = frame_id
    arrow.ns, arrow.id, arrow.type, arrow.action = 'heading', 0, Marker.ARROW, Marker.ADD
    q = yaw_enu_quaternion(yaw)
    o = arrow.pose.orientation
    o.x, o.y, o.z, o.w = (float(v) for v in q)
    arrow.scale.x, arrow.scale.y, arrow.scale.z = 1.0, 0.06, 0.06
    arrow.color.r, arrow.color.g, arrow.color.b, arrow.color.a = 1.0, 0.55, 0.0, 1.0
    arrow.lifetime.sec = 2
    out = [arrow]
    if sigma_deg is not None and math.isfinite(sigma_deg):
        sec = Marker()
        sec.header = arrow.header
        sec.ns, sec.id, sec.type, sec.action = 'heading', 1, Marker.LINE_LIST, Marker.ADD
        sec.pose.orientation.w = 1.0
        s = math.radians(min(float(sigma_deg), 180.0))
        for a in (yaw - s, yaw + s):
            sec.points += [Point(), Point(x=math.cos(a), y=math.sin(a), z=0.0)]
        sec.scale.x = 0.02
        sec.color.r, sec.color.g, sec.color.b, sec.color.a = 1.0, 0.85, 0.3, 0.8
        sec.lifetime.sec = 2
        out.append(sec)
    return out
