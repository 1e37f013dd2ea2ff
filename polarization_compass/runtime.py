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
- :class:`single_threaded_kernels`: numba and BLAS on the calling thread only, for the replay's
  method threads and the error-map sweep's workers (BLAS through ``threadpoolctl``).
- :func:`kernel_array`: an input array in the one form (C-contiguous, read-only) the compiled
  estimator kernels and the render's sky, radiance, cloud and skyline kernels are compiled for.
"""

from __future__ import annotations

__all__ = ['keep_large_buffers_in_heap', 'kernel_array', 'single_threaded_kernels']

import numpy as np

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


class single_threaded_kernels:
    """
    Run numba kernels and BLAS on the calling thread only while replaying.

    After subsampling, a frame's kernels take 0.1-3 ms; waking a pool of threads for them costs
    more than it saves on a 2-core machine, and under load a parallel call waits ~20 ms for its
    threads (measured: a 0.1 ms demosaic took 20 ms with 2 numba threads while other work ran).
    numba's thread count is per calling thread; BLAS's (every BLAS loaded, numpy's and scipy's
    OpenBLAS, found by ``threadpoolctl`` when entering) is process-wide and restored afterwards.
    """

    def __enter__(self):
        import numba
        from threadpoolctl import threadpool_limits

        self._numba = numba.get_num_threads()
        numba.set_num_threads(1)
        self._blas = threadpool_limits(limits=1, user_api='blas')
        return self

    def __exit__(self, *exc):
        import numba

        numba.set_num_threads(self._numba)
        self._blas.restore_original_limits()


# ------------------------------------------------------------------------------------------------
# Arguments of the compiled kernels


def kernel_array(a, dtype=None) -> np.ndarray:
    """
    Return an array as the compiled kernels read it: C-contiguous and read-only.

    numba compiles a kernel once per argument type, and an array's type includes its layout
    (C/F/A) and whether it is writeable: the same kernel fed a C writeable, a C read-only and an F
    array is compiled three times (5-30 s each), also in a node whose warm-up compiled one of them
    when its first message brings another. The inputs the estimators pass (rays, pixel
    coordinates, block indices) and the rays of the render's per-pixel kernels (the renderer's
    cached rays, the ground's mirror rays, a caller's own) are therefore all given in one form,
    read-only because the camera's cached rays and coordinates (the node's full-frame path)
    already are: a writeable C-contiguous array becomes a read-only view of itself (no copy); only
    another layout or dtype is copied.

    Parameters
    ----------
    a : array_like
        The array.
    dtype : numpy.dtype or None
        The dtype to convert to (copying only if it differs); None keeps the array's own.

    Returns
    -------
    numpy.ndarray
        ``a`` (itself when it is already C-contiguous and read-only), else a read-only
        C-contiguous view or copy of it.

    """
    out = np.ascontiguousarray(a, dtype=dtype)
    if out.flags.writeable:
        out = out.view()
        out.flags.writeable = False
    return out
