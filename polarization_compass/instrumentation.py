"""Counts of pipeline stages that ran, so tests can prove what was (not) computed.

Cheap by design: one dict increment per stage per frame, never per pixel.
"""
from __future__ import annotations

import threading
from collections import Counter
from contextlib import contextmanager

__all__ = ["stage", "counts", "reset", "count"]

_lock = threading.Lock()
_counts: Counter = Counter()


@contextmanager
def stage(name: str):
    """Mark one execution of pipeline stage ``name``."""
    with _lock:
        _counts[name] += 1
    yield


def count(name: str) -> None:
    with _lock:
        _counts[name] += 1


def counts() -> dict:
    """A snapshot {stage name: times run} since the last :func:`reset`."""
    with _lock:
        return dict(_counts)


def reset() -> None:
    with _lock:
        _counts.clear()
