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
Counts of pipeline stages that ran, so tests can prove what was (not) computed.

Cheap by design: one dict increment per stage per frame, never per pixel.
"""

from __future__ import annotations

from collections import Counter
from contextlib import contextmanager
import threading

__all__ = ['stage', 'counts', 'reset', 'count']

_lock = threading.Lock()
_counts: Counter = Counter()


@contextmanager
def stage(name: str):
    """
    Mark one execution of pipeline stage ``name`` (a context manager).

    The count is taken on entry, so a stage that raises still counts as run.

    Parameters
    ----------
    name : str
        Stage name, e.g. ``"demosaic"``.

    Yields
    ------
    None
        Control to the ``with`` body.

    """
    with _lock:
        _counts[name] += 1
    yield


def count(name: str) -> None:
    """
    Count one execution of pipeline stage ``name`` (the non-context form of :func:`stage`).

    Parameters
    ----------
    name : str
        Stage name.

    """
    with _lock:
        _counts[name] += 1


def counts() -> dict:
    """
    Return a snapshot of the stage counts since the last :func:`reset`.

    Returns
    -------
    dict
        ``{stage name: times run}``; a copy, safe to keep.

    """
    with _lock:
        return dict(_counts)


def reset() -> None:
    """Forget every stage count (thread-safe)."""
    with _lock:
        _counts.clear()
