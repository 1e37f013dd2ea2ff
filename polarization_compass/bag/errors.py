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

"""Errors of the bag package: a bag or mapping that cannot be used, one unusable message."""

from __future__ import annotations

from ..errors import CompassError

__all__ = [
    'BagError',
    'MessageError',
]


class BagError(CompassError):
    """An unreadable rosbag2, a bad topic mapping, or a bag that cannot be written."""


class MessageError(CompassError):
    """One message that cannot be used. ``reason`` is a short tag for the skip summary."""

    def __init__(self, reason: str, detail: str):
        super().__init__(f'{reason}: {detail}')
        self.reason = reason
        self.detail = detail


def _one_line(exc) -> str:
    s = str(exc).strip().splitlines()
    return f'{type(exc).__name__}: {s[0]}' if s else type(exc).__name__
