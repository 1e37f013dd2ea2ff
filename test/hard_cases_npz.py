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
Corrupt-.npz checks shared by the hard-case tests of every .npz loader.

For the loaders of frame files and error maps: a truncated archive, a .npy saved under an .npz
name, and no file handle leaked on the error path. Each check takes the loader and the error class
it must raise.
"""

from __future__ import annotations

import gc
import warnings

import numpy as np
import pytest


def truncate_half(path):
    """
    Cut the file at ``path`` to its first half and return the path.

    As a download or copy that stopped would leave it.
    """
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def npy_named_npz(path):
    """Write a plain .npy array under the (.npz) name ``path``; return the path."""
    with open(path, 'wb') as fh:
        np.save(fh, np.zeros(3))
    return path


def assert_refused(load, path, error, match=None):
    """
    Assert that ``load(path)`` raises ``error``.

    A leaked handle is ignored here: :func:`assert_no_leaked_handle` is that check.
    """
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', ResourceWarning)
        with pytest.raises(error, match=match):
            load(path)
        gc.collect()


def assert_no_leaked_handle(load, path, error):
    """
    Assert that ``load(path)`` fails with ``error`` and leaves no open file behind.

    No ResourceWarning is raised once it is collected.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        try:
            load(path)
        except error:
            pass
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)]
