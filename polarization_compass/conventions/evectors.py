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
Angle of polarization and E-vectors.

The camera frame's AoP <-> E-vector, and the photodiode-array units (POL-OP): viewing direction and
polarizer angles -> body frame.
"""

from __future__ import annotations

import numpy as np

from .angles import fold_aop_rad


def aop_from_evector_cam_rad(e_cam):
    """
    Compute the AoP ``atan2(E_x, E_y)`` of camera-frame E-vector(s), eq 28.

    The angle of the E-vector projected on the sensor x-y plane, from +y_cam towards +x_cam.

    Parameters
    ----------
    e_cam : array_like
        E-vector(s) in the camera frame, shape (..., 3), any length and sign (axial).

    Returns
    -------
    numpy.ndarray
        AoP [rad] in [-pi/2, pi/2), shape (...).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28.

    """
    e = np.asarray(e_cam)
    return fold_aop_rad(np.arctan2(e[..., 0], e[..., 1]))


def evector_cam_from_aop(aop_rad, rays_cam):
    """
    Lift AoP to unit 3-D E-vectors perpendicular to each pixel's ray (camera frame).

    The inverse of eq 28. The sensor measures the orthographic projection of E on its x-y plane, so
    E = (sin a, cos a, e_z) up to scale with E . r = 0. Multiplying through by r_z avoids dividing
    by it (fisheye rays near 90 deg off-axis): E ~ (r_z sin a, r_z cos a, -(r_x sin a + r_y cos
    a)).

    Parameters
    ----------
    aop_rad : array_like
        AoP [rad] in the eq 28 convention, shape (...).
    rays_cam : array_like
        Viewing rays of the pixels in the camera frame, shape (..., 3), any length.

    Returns
    -------
    numpy.ndarray
        Unit E-vectors in the camera frame, shape (..., 3).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 28.

    """
    a = np.asarray(aop_rad)
    r = np.asarray(rays_cam)
    sa, ca = np.sin(a), np.cos(a)
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    e = np.stack([rz * sa, rz * ca, -(rx * sa + ry * ca)], axis=-1)
    n = np.linalg.norm(e, axis=-1, keepdims=True)
    return e / np.maximum(n, np.finfo(e.dtype).tiny)


# --------------------------------------------------------------------------------------------
# Photodiode-array units (POL-OP): viewing direction and polarizer angles -> body frame
# --------------------------------------------------------------------------------------------
#: What a unit's 0 deg polarizer is parallel to: its local meridian (the great circle through the
#: zenith and the unit's axis) or the horizon (the horizontal direction perpendicular to the axis).
ANGLE_ZEROS = ('meridian', 'horizontal')
#: Sense of increasing polarizer angle as seen looking out along the unit's axis (from the sensor
#: towards the sky): ``cw`` is a right-handed (positive) rotation about the axis.
ANGLE_SENSES = ('cw', 'ccw')


def unit_axis_body(azimuth_deg, elevation_deg):
    """
    Compute the viewing axis of a photodiode unit in the REP-103 body frame.

    A level body with its front at true bearing B sees along compass azimuth ``B + azimuth_deg`` at
    altitude ``elevation_deg``.

    Parameters
    ----------
    azimuth_deg : float or array_like
        Azimuth of the axis [deg], clockwise from the body's front seen from above (90 = the body's
        right, -y).
    elevation_deg : float or array_like
        Elevation of the axis [deg] above the body's x-y plane.

    Returns
    -------
    numpy.ndarray
        Unit vector(s) in the body frame (x forward, y left, z up), shape (..., 3).

    """
    a, e = np.broadcast_arrays(
        np.radians(np.asarray(azimuth_deg, dtype=float)),
        np.radians(np.asarray(elevation_deg, dtype=float)),
    )
    return np.stack([np.cos(e) * np.cos(a), -np.cos(e) * np.sin(a), np.sin(e)], axis=-1)


def unit_polarizer_frame_body(azimuth_deg, elevation_deg, angle_zero='meridian', angle_sense='cw'):
    """
    Compute the (zero, quarter) directions spanning a unit's polarizer plane, body frame.

    A polarizer at angle theta transmits along ``cos(theta) zero + sin(theta) quarter``. ``zero``
    is the local meridian's tangent pointing up (towards the zenith) for ``angle_zero="meridian"``,
    or the horizontal direction on the unit's right (seen looking out along the axis) for
    ``"horizontal"``; ``quarter`` is ``zero`` turned by +90 deg in ``angle_sense`` (``cw``: a
    right-handed rotation about the axis, ``quarter = axis x zero``). The meridian tangent is
    ``(-sin e * h, cos e)`` with h the unit's horizontal azimuth direction (the paper's eq 16
    meridian tangent): continuous up to a unit looking at the zenith, whose meridian is then its
    azimuth's vertical plane (so ``azimuth_deg`` orients a zenith unit).

    Parameters
    ----------
    azimuth_deg : float or array_like
        Azimuth of the unit's axis [deg], clockwise from the body's front seen from above.
    elevation_deg : float or array_like
        Elevation of the unit's axis [deg] above the body's x-y plane.
    angle_zero : {"meridian", "horizontal"}, default "meridian"
        What the 0 deg polarizer is parallel to (:data:`ANGLE_ZEROS`).
    angle_sense : {"cw", "ccw"}, default "cw"
        Sense of increasing polarizer angle looking out along the axis (:data:`ANGLE_SENSES`).

    Returns
    -------
    zero : numpy.ndarray
        Unit direction of the 0 deg polarizer, body frame, shape (..., 3).
    quarter : numpy.ndarray
        Unit direction of the 90 deg polarizer, body frame, shape (..., 3).

    Raises
    ------
    ValueError
        ``angle_zero`` or ``angle_sense`` is not one of the allowed values.

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eqs 16 (meridian tangent)
       and 17 (horizontal direction).

    """
    if angle_zero not in ANGLE_ZEROS:
        raise ValueError(f'angle_zero must be one of {ANGLE_ZEROS}, got {angle_zero!r}')
    if angle_sense not in ANGLE_SENSES:
        raise ValueError(f'angle_sense must be one of {ANGLE_SENSES}, got {angle_sense!r}')
    a, e = np.broadcast_arrays(
        np.radians(np.asarray(azimuth_deg, dtype=float)),
        np.radians(np.asarray(elevation_deg, dtype=float)),
    )
    axis = unit_axis_body(azimuth_deg, elevation_deg)
    h = np.stack(
        [np.cos(a), -np.sin(a), np.zeros_like(a)], axis=-1
    )  # horizontal, along the azimuth
    up = np.concatenate([-np.sin(e)[..., None] * h[..., :2], np.cos(e)[..., None]], axis=-1)
    right = np.cross(
        axis, up
    )  # looking out along the axis with the zenith up: the right-hand side
    zero = up if angle_zero == 'meridian' else right
    quarter = np.cross(axis, zero)  # +90 deg, right-handed about the axis (clockwise looking out)
    if angle_sense == 'ccw':
        quarter = -quarter
    return zero, quarter


def unit_evector_body(
    angle_rad, azimuth_deg, elevation_deg, angle_zero='meridian', angle_sense='cw'
):
    """
    Compute the unit E-vector, body frame, of light at a polarizer angle of a unit.

    The inverse of :func:`unit_angle_from_evector_body_rad` (axial: E and -E are the same
    polarization). A unit at elevation 90 deg, azimuth 0, ``angle_zero="meridian"``,
    ``angle_sense="ccw"`` measures the camera's eq 28 AoP of the default mounting
    (:data:`R_BODY_CAM_DEFAULT`).

    Parameters
    ----------
    angle_rad : float or array_like
        Polarization angle [rad] in the unit's polarizer angles.
    azimuth_deg : float or array_like
        Azimuth of the unit's axis [deg], clockwise from the body's front seen from above.
    elevation_deg : float or array_like
        Elevation of the unit's axis [deg] above the body's x-y plane.
    angle_zero : {"meridian", "horizontal"}, default "meridian"
        What the 0 deg polarizer is parallel to.
    angle_sense : {"cw", "ccw"}, default "cw"
        Sense of increasing polarizer angle looking out along the axis.

    Returns
    -------
    numpy.ndarray
        Unit E-vector(s) in the body frame, shape (..., 3).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 15.

    """
    zero, quarter = unit_polarizer_frame_body(azimuth_deg, elevation_deg, angle_zero, angle_sense)
    t = np.asarray(angle_rad, dtype=float)[..., None]
    return np.cos(t) * zero + np.sin(t) * quarter


def unit_angle_from_evector_body_rad(
    e_body, azimuth_deg, elevation_deg, angle_zero='meridian', angle_sense='cw'
):
    """
    Compute the polarization angle a photodiode unit measures for body-frame E-vector(s).

    The angle of E projected on the unit's polarizer plane, ``atan2(E . quarter, E . zero)``.

    Parameters
    ----------
    e_body : array_like
        E-vector(s) in the body frame, shape (..., 3), any length and sign (axial).
    azimuth_deg : float or array_like
        Azimuth of the unit's axis [deg], clockwise from the body's front seen from above.
    elevation_deg : float or array_like
        Elevation of the unit's axis [deg] above the body's x-y plane.
    angle_zero : {"meridian", "horizontal"}, default "meridian"
        What the 0 deg polarizer is parallel to.
    angle_sense : {"cw", "ccw"}, default "cw"
        Sense of increasing polarizer angle looking out along the axis.

    Returns
    -------
    numpy.ndarray
        Polarization angle [rad] in [-pi/2, pi/2), shape (...).

    References
    ----------
    .. [1] H. Liang, H. Bai, T. Zhou and K. Shen, "Influence of Sensor Tilts on Bio-inspired
       Polarized Skylight Orientation Determination" (the seed paper), eq 15 (the inverse of the
       decomposition).

    """
    zero, quarter = unit_polarizer_frame_body(azimuth_deg, elevation_deg, angle_zero, angle_sense)
    e = np.asarray(e_body, dtype=float)
    return fold_aop_rad(np.arctan2(np.sum(e * quarter, axis=-1), np.sum(e * zero, axis=-1)))
