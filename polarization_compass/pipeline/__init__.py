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
Per-frame processing behind the nodes, ROS-free.

Mosaic -> observation -> heading (:mod:`.front_end`), the IMU history the tilt and the ambiguity
prior come from (:mod:`.attitude`, :mod:`.prior`), the sun per stamp (:mod:`.sun`), the camera
intrinsics in use (:mod:`.camera_info`), the watches on the live stream (:mod:`.monitors`) and
the rules every result passes before it is published (:mod:`.rules`, node and replay alike); the
principal point's uncertainty in every heading's sigma (:mod:`.optical_centre`).

The node classes in :mod:`polarization_compass.nodes` only move messages in and out of these
objects, so the same code runs wherever frames come from (a live camera, a bag, a test).

Frames: the IMU orientation is the body's (REP-103 base_link) in ENU; the camera is mounted by
``R_body_cam`` (default :data:`~polarization_compass.conventions.R_BODY_CAM_DEFAULT`: looking up,
camera +y = body +x), so the camera attitude of eq 21 is ``attitude_from_R_enu_cam(R_enu_body @
R_body_cam)`` and, with the default mounting, the REP-103 yaw of the body is ``90 deg - bearing``.
"""

from .attitude import AttitudeBuffer, CameraTilt
from .camera_info import CameraInfoState
from .errors import PipelineError
from .front_end import HeadingFrontEnd, warm_up
from .monitors import ImageLossWatch, PolarizerMonitor
from .prior import check_prior_agreement, FrameInputs, PRIOR_DISAGREES_N_SIGMA, TiltAndPrior
from .rules import apply_rules, SensorReadout
from .sampling import decimated_blocks, whole_sky_sample
from .sun import SunSource

__all__ = [
    'AttitudeBuffer',
    'CameraTilt',
    'SunSource',
    'HeadingFrontEnd',
    'PipelineError',
    'warm_up',
    'TiltAndPrior',
    'FrameInputs',
    'CameraInfoState',
    'check_prior_agreement',
    'PRIOR_DISAGREES_N_SIGMA',
    'ImageLossWatch',
    'PolarizerMonitor',
    'apply_rules',
    'SensorReadout',
    'decimated_blocks',
    'whole_sky_sample',
]
