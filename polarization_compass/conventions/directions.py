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

"""Directions and headings: ENU unit vectors from azimuth and altitude, bearing, psi and yaw."""

from __future__ import annotations

import numpy as np

from .angles import wrap_180_deg, wrap_360_deg


def enu_direction(azimuth_deg, altitude_deg):
    """
    Compute ENU unit vector(s) of an azimuth and altitude.

    ``(cos h sin A, cos h cos A, sin h)`` for azimuth A clockwise from North and altitude h.

    Parameters
    ----------
    azimuth_deg : float or array_like
        Azimuth [deg], clockwise from true North.
    altitude_deg : float or array_like
        Altitude above the horizon [deg].

    Returns
    -------
    numpy.ndarray
        Unit vector(s) in ENU, shape (..., 3).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 16 (the same angles; Fig
       2).

    """
    A = np.radians(np.asarray(azimuth_deg, dtype=float))
    h = np.radians(np.asarray(altitude_deg, dtype=float))
    return np.stack([np.cos(h) * np.sin(A), np.cos(h) * np.cos(A), np.sin(h)], axis=-1)


def azimuth_altitude_from_enu(v):
    """
    Compute azimuth and altitude of ENU vector(s), the inverse of :func:`enu_direction`.

    Uses ``atan2`` for both angles (the paper's eqs 23-24 in the ENU frame, without the quotient).

    Parameters
    ----------
    v : array_like
        Vector(s) in ENU, shape (..., 3), any non-zero length.

    Returns
    -------
    azimuth_deg : float or numpy.ndarray
        Azimuth [deg] in [0, 360), clockwise from North.
    altitude_deg : numpy.ndarray
        Altitude [deg] in [-90, 90].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 23-24.

    """
    v = np.asarray(v, dtype=float)
    az = wrap_360_deg(np.degrees(np.arctan2(v[..., 0], v[..., 1])))
    alt = np.degrees(np.arctan2(v[..., 2], np.hypot(v[..., 0], v[..., 1])))
    return az, alt


def bearing_to_yaw_enu_deg(bearing_deg):
    """
    Convert a true bearing to REP-103 yaw, ``yaw_enu = 90 - bearing``.

    Parameters
    ----------
    bearing_deg : float or array_like
        True bearing [deg], clockwise from North.

    Returns
    -------
    float or numpy.ndarray
        REP-103 yaw [deg], counter-clockwise from East, in (-180, 180].

    References
    ----------
    .. [1] T. Foote and M. Purvis, "REP 103: Standard Units of Measure and Coordinate Conventions",
       ROS Enhancement Proposals, 2010.

    """
    return wrap_180_deg(90.0 - np.asarray(bearing_deg, dtype=float))


def yaw_enu_to_bearing_deg(yaw_enu_deg):
    """
    Convert REP-103 yaw to a true bearing, ``bearing = 90 - yaw_enu``.

    Parameters
    ----------
    yaw_enu_deg : float or array_like
        REP-103 yaw [deg], counter-clockwise from East.

    Returns
    -------
    float or numpy.ndarray
        True bearing [deg], clockwise from North, in [0, 360).

    References
    ----------
    .. [1] T. Foote and M. Purvis, "REP 103: Standard Units of Measure and Coordinate Conventions",
       ROS Enhancement Proposals, 2010.

    """
    return wrap_360_deg(90.0 - np.asarray(yaw_enu_deg, dtype=float))


def psi_to_bearing_deg(psi_deg, sun_azimuth_deg):
    """
    Convert the paper's psi (yaw in the Sun-azimuth frame) to the true bearing.

    ``bearing = psi + A_sun``, the relation of eq 26 with its sign erratum fixed.

    Parameters
    ----------
    psi_deg : float or array_like
        Yaw psi [deg] of camera +y relative to the sun's azimuth.
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], clockwise from North.

    Returns
    -------
    float or numpy.ndarray
        True bearing of camera +y [deg] in [0, 360).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 21 and 26 (with the sign
       erratum of eq 26 fixed).

    """
    return wrap_360_deg(
        np.asarray(psi_deg, dtype=float) + np.asarray(sun_azimuth_deg, dtype=float)
    )


def bearing_to_psi_deg(bearing_deg, sun_azimuth_deg):
    """
    Convert a true bearing to the paper's psi, ``psi = bearing - A_sun``.

    Parameters
    ----------
    bearing_deg : float or array_like
        True bearing of camera +y [deg], clockwise from North.
    sun_azimuth_deg : float or array_like
        Sun azimuth [deg], clockwise from North.

    Returns
    -------
    float or numpy.ndarray
        Yaw psi [deg] in the Sun-azimuth frame, in (-180, 180].

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 21 and 26 (with the sign
       erratum of eq 26 fixed).

    """
    return wrap_180_deg(
        np.asarray(bearing_deg, dtype=float) - np.asarray(sun_azimuth_deg, dtype=float)
    )
