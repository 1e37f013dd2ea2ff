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
An image is paired with the camera_info of its own stamp, not the latest to arrive (issue 24).

A hostile camera_info arriving between a good one and its image spoiled that image; the state now
remembers the last camera_info messages by stamp.
"""

from polarization_compass.camera import CameraModel
from polarization_compass.pipeline import CameraInfoState, PipelineError
import pytest

GOOD = CameraModel('pinhole', 64, 48, 3.0, 3.45, 3.45)
OTHER = CameraModel('pinhole', 64, 48, 4.0, 3.45, 3.45)


def test_an_image_gets_its_own_camera_info_despite_a_hostile_one_after_it():
    s = CameraInfoState()
    s.accept(GOOD, stamp_ns=1_000)
    s.reject('fx out of bounds', stamp_ns=2_000)  # arrives before the image of stamp 1000
    assert s.camera(1_000) is GOOD
    with pytest.raises(PipelineError, match="this image's camera_info was rejected"):
        s.camera(2_000)
    with pytest.raises(PipelineError, match='latest camera_info was rejected'):
        s.camera(3_000)  # no camera_info of its stamp: the latest decides
    s.accept(OTHER, stamp_ns=3_000)
    assert s.camera(3_000) is OTHER and s.camera(1_000) is GOOD and s.camera() is OTHER


def test_only_the_last_stamps_are_remembered():
    s = CameraInfoState()
    s.accept(GOOD, stamp_ns=0)
    for k in range(1, CameraInfoState.STAMPS_KEPT + 1):
        s.reject('bad', stamp_ns=k)
    s.accept(OTHER)  # without a stamp: the latest only
    assert s.camera(0) is OTHER  # stamp 0 was forgotten: the latest decides
    with pytest.raises(PipelineError):
        s.camera(CameraInfoState.STAMPS_KEPT)
