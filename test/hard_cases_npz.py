"""Corrupt-.npz checks shared by the hard-case tests of every loader that reads .npz files (frame
files, error maps): a truncated archive, a .npy saved under an .npz name, and no file handle leaked
on the error path. Each check takes the loader and the error class it must raise."""
from __future__ import annotations

import gc
import warnings

import numpy as np
import pytest


def truncate_half(path):
    """Cut the file at ``path`` to its first half (a download or copy that stopped); returns the path."""
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def npy_named_npz(path):
    """A plain .npy array written under the (.npz) name ``path``; returns the path."""
    with open(path, "wb") as fh:
        np.save(fh, np.zeros(3))
    return path


def assert_refused(load, path, error, match=None):
    """``load(path)`` raises ``error`` (a leaked handle is ignored here: :func:`assert_no_leaked_handle`
    is that check)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        with pytest.raises(error, match=match):
            load(path)
        gc.collect()


def assert_no_leaked_handle(load, path, error):
    """``load(path)`` fails with ``error`` and leaves no open file behind (no ResourceWarning once collected)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            load(path)
        except error:
            pass
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)]
