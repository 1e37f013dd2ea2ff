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
The project's error base class.

Every error meant for a user derives from :class:`CompassError`
(a ``ValueError``): the CLI prints it as one line and exits 2; nodes log, count and drop.
"""


class CompassError(ValueError):
    """Bad input or configuration, with a message that says what is wrong and what to do."""


class MissingDependencyError(CompassError):
    """
    An optional ROS piece (launch, tf2_ros, rosbag2_py, ...) is not installed here.

    Parameters
    ----------
    what : str
        The missing piece, e.g. ``"tf2_ros"``.
    install : str
        How to install it, e.g. ``"ros-jazzy-tf2-ros"``; both end up in the message and as
        attributes of the same names.

    """

    def __init__(self, what: str, install: str):
        super().__init__(f'{what} is not available: install {install}')
        self.what = what
        self.install = install
