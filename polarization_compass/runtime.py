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
Performance plumbing of the process (ROS-free), kept out of the physics modules.

- :func:`keep_large_buffers_in_heap`: glibc heap settings (``mallopt``) for processes that handle
  full-resolution images: every node (:func:`polarization_compass.nodes.runner.run_node`) and the
  offline replay (:func:`polarization_compass.replay.replay_bag`), which read 10 MB image messages.
- :func:`openblas_handles` and :class:`single_threaded_kernels`: numba and OpenBLAS on the calling
  thread only, for the replay's method threads.
"""

from __future__ import annotations

__all__ = ['keep_large_buffers_in_heap', 'openblas_handles', 'single_threaded_kernels']

#: glibc ``mallopt`` parameters (malloc.h) and the values the nodes use.
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
#: Largest block glibc accepts as mmap threshold on 64-bit (``DEFAULT_MMAP_THRESHOLD_MAX``, 32
#: MiB): covers a 10 MB mono16 and a 20 MB 32FC1 full-resolution mosaic.
MMAP_THRESHOLD_BYTES = 32 << 20
TRIM_THRESHOLD_BYTES = 1 << 30
TOP_PAD_BYTES = 64 << 20


def keep_large_buffers_in_heap() -> bool:
    """
    Make glibc serve and keep large blocks (images) in the heap instead of a fresh ``mmap`` each.

    Each image message passes through three buffers of its size (the middleware's, the C message's
    and Python's). Above glibc's mmap threshold each is a new mapping that the kernel zero-fills
    page by page and unmaps on free; with the threshold raised and trimming deferred, freed image
    buffers are reused. Returns True when applied; False (no change) where the C library is not
    glibc.

    Returns
    -------
    bool
        True when glibc's ``mallopt`` accepted all three settings (``M_MMAP_THRESHOLD`` 32 MiB,
        ``M_TRIM_THRESHOLD`` 1 GiB, ``M_TOP_PAD`` 64 MiB);
        False when the C library has no ``mallopt`` or refused one.

    """
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6')
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return all(
        mallopt(opt, val) == 1
        for opt, val in (
            (_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES),
            (_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
            (_M_TOP_PAD, TOP_PAD_BYTES),
        )
    )


def openblas_handles():
    """
    Return the thread-count setter and getter of every OpenBLAS loaded in this process.

    The libraries are found in ``/proc/self/maps`` (numpy's and scipy's, each with its symbol
    prefix and suffix) and opened with ctypes.

    Returns
    -------
    list of tuple
        ``(set_num_threads, get_num_threads)`` ctypes functions, one pair per library; empty
        where ``/proc`` cannot be read or no OpenBLAS is loaded.

    """
    import ctypes

    out = []
    try:
        with open('/proc/self/maps') as f:
            paths = {line.split()[-1] for line in f if 'openblas' in line and '.so' in line}
    except OSError:
        return out
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in ('scipy_openblas', 'openblas'):
            for suffix in ('64_', '_64_', ''):
                try:
                    setter = getattr(lib, f'{prefix}_set_num_threads{suffix}')
                    getter = getattr(lib, f'{prefix}_get_num_threads{suffix}')
                except AttributeError:
                    continue
                out.append((setter, getter))
                break
            else:
                continue
            break
    return out


class single_threaded_kernels:
    """
    Run numba kernels and BLAS on the calling thread only while replaying.

    After subsampling, a frame's kernels take 0.1-3 ms; waking a pool of threads for them costs
    more than it saves on a 2-core machine, and under load a parallel call waits ~20 ms for its
    threads (measured: a 0.1 ms demosaic took 20 ms with 2 numba threads while other work ran).
    numba's thread count is per calling thread; OpenBLAS's is process-wide and restored afterwards.
    """

    def __enter__(self):
        import numba

        self._numba = numba.get_num_threads()
        numba.set_num_threads(1)
        self._blas = [(s, int(g())) for s, g in openblas_handles()]
        for s, _ in self._blas:
            s(1)
        return self

    def __exit__(self, *exc):
        import numba

        numba.set_num_threads(self._numba)
        for s, n in self._blas:
            s(n)


# ------------------------------------------------------------------------------------------------
# The whole bag
