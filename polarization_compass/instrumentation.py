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
    """Mark one execution of pipeline stage ``name`` (a context manager).

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
    """Count one execution of pipeline stage ``name`` (the non-context form of :func:`stage`).

    Parameters
    ----------
    name : str
        Stage name.
    """
    with _lock:
        _counts[name] += 1


def counts() -> dict:
    """Return a snapshot of the stage counts since the last :func:`reset`.

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
