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
Frames and angle conventions: the only place that defines them; everything else imports them.

Frames
------
``enu``      World frame East-North-Up (REP-103 ``map``/``odom`` style, z up).
``sun``      The paper's Sun-azimuth frame ``a`` (eq 1): ENU rotated about Up so that +y points at
             the sun's azimuth. A world azimuth A becomes ``A - A_sun`` there.
``cam``      Camera optical frame (paper Fig 4 and the ROS ``*_optical_frame`` convention): +x
             along image columns (right), +y along image rows (down), +z the optical axis. A level
             camera looks at the zenith.
``body``     The robot's REP-103 body frame (x forward, y left, z up). The default mounting puts
             the camera looking up with its +y axis along body +x (forward), so body +y is camera
             -x.

Angles (all names carry their unit: ``_deg`` or ``_rad``)
------
``azimuth``  of a direction: clockwise from true North, as the paper does (``A``). Direction ``(cos
             h sin A, cos h cos A, sin h)`` in ENU for altitude h.
``bearing``  of the camera: the true bearing of the camera +y axis, clockwise from North.
``psi``      the paper's yaw: the bearing relative to the sun's azimuth, ``psi = bearing - A_sun``
             (eq 21 with the erratum of eq 26 fixed: ``A_g = A_a + A_sun``).
``pitch``    the paper's alpha, a rotation about camera +x; ``roll`` the paper's beta, about camera
             +y.
``yaw_enu``  REP-103 yaw of the body: counter-clockwise from East, ``yaw_enu = 90 deg - bearing``.
``aop``      angle of polarization in the paper's eq 28 convention: angle of the E-vector projected
             on the sensor x-y plane, measured from +y_cam towards +x_cam, axial (mod 180 deg).

Camera attitude (eq 21): ``R_sun_cam = Rz(-psi) @ Rx(pitch) @ Ry(roll)`` with the standard
right-handed elementary rotations, and ``R_enu_cam = Rz(-bearing) @ Rx(pitch) @ Ry(roll)``.

Wrapping: ``wrap_180`` -> (-180, 180], ``wrap_360`` -> [0, 360), ``fold_axial`` -> (-90, 90] for
axial errors, and AoP images are folded to [-pi/2, pi/2) (``fold_aop_rad``). The ``*_float`` forms
take one finite float without numpy (per-estimate code, numba kernels) and give the same bits.

Modules: :mod:`.angles` (wrapping, axial angles), :mod:`.rotations` (elementary rotations,
eq 21, :class:`CameraAttitude`), :mod:`.directions` (ENU directions, bearing, psi, yaw),
:mod:`.quaternions` (ROS quaternions, the body-camera mounting) and :mod:`.evectors` (AoP and
E-vectors, photodiode-array units); the names below are the package's documented surface.
"""

from .angles import (
    axial_difference_deg,
    axial_mean_rad,
    fold_aop_rad,
    fold_axial_deg,
    fold_axial_rad,
    fold_axial_rad_float,
    wrap_180_deg,
    wrap_180_deg_float,
    wrap_360_deg,
    wrap_360_deg_float,
)
from .directions import (
    azimuth_altitude_from_enu,
    bearing_to_psi_deg,
    bearing_to_yaw_enu_deg,
    enu_direction,
    psi_to_bearing_deg,
    yaw_enu_to_bearing_deg,
)
from .evectors import (
    ANGLE_SENSES,
    ANGLE_ZEROS,
    aop_from_evector_cam_rad,
    evector_cam_from_aop,
    unit_angle_from_evector_body_rad,
    unit_axis_body,
    unit_evector_body,
    unit_polarizer_frame_body,
)
from .quaternions import (
    body_quat_from_camera_attitude,
    camera_attitude_from_body_quat,
    matrix_to_quat,
    quat_to_matrix,
    QuaternionError,
    R_BODY_CAM_DEFAULT,
    R_enu_body_from_camera_attitude,
    validate_quaternion,
    yaw_enu_quaternion,
)
from .rotations import (
    attitude_from_R_enu_cam,
    CameraAttitude,
    R_enu_cam_from_attitude,
    R_sun_cam_from_attitude,
    rot_x,
    rot_y,
    rot_z,
)

__all__ = [
    'wrap_180_deg',
    'wrap_360_deg',
    'fold_axial_deg',
    'fold_axial_rad',
    'fold_aop_rad',
    'wrap_180_deg_float',
    'wrap_360_deg_float',
    'fold_axial_rad_float',
    'rot_x',
    'rot_y',
    'rot_z',
    'R_sun_cam_from_attitude',
    'R_enu_cam_from_attitude',
    'attitude_from_R_enu_cam',
    'enu_direction',
    'azimuth_altitude_from_enu',
    'bearing_to_yaw_enu_deg',
    'yaw_enu_to_bearing_deg',
    'psi_to_bearing_deg',
    'bearing_to_psi_deg',
    'quat_to_matrix',
    'matrix_to_quat',
    'validate_quaternion',
    'QuaternionError',
    'R_BODY_CAM_DEFAULT',
    'aop_from_evector_cam_rad',
    'evector_cam_from_aop',
    'axial_mean_rad',
    'axial_difference_deg',
    'CameraAttitude',
    'camera_attitude_from_body_quat',
    'R_enu_body_from_camera_attitude',
    'body_quat_from_camera_attitude',
    'unit_axis_body',
    'unit_polarizer_frame_body',
    'unit_evector_body',
    'unit_angle_from_evector_body_rad',
    'ANGLE_ZEROS',
    'ANGLE_SENSES',
    'yaw_enu_quaternion',
]
