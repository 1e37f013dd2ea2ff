"""Process-wide heap settings for code that handles full-resolution images (ROS-free).

Used by every node (:func:`polarization_compass.nodes.runner.run_node`) and by the offline replay's
processes (:func:`polarization_compass.replay.replay_bag`), which read 10 MB image messages from a bag.
"""
from __future__ import annotations

__all__ = ["keep_large_buffers_in_heap"]

#: glibc ``mallopt`` parameters (malloc.h) and the values the nodes use.
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
#: Largest block glibc accepts as mmap threshold on 64-bit (``DEFAULT_MMAP_THRESHOLD_MAX``, 32 MiB):
#: covers a 10 MB mono16 and a 20 MB 32FC1 full-resolution mosaic.
MMAP_THRESHOLD_BYTES = 32 << 20
TRIM_THRESHOLD_BYTES = 1 << 30
TOP_PAD_BYTES = 64 << 20


def keep_large_buffers_in_heap() -> bool:
    """Make glibc serve and keep large blocks (images) in the heap instead of a fresh ``mmap`` each.

    Each image message passes through three buffers of its size (the middleware's, the C message's and
    Python's). Above glibc's mmap threshold each is a new mapping that the kernel zero-fills page by
    page and unmaps on free; with the threshold raised and trimming deferred, freed image buffers are
    reused. Returns True when applied; False (no change) where the C library is not glibc."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return all(mallopt(opt, val) == 1 for opt, val in ((_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES),
                                                        (_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
                                                        (_M_TOP_PAD, TOP_PAD_BYTES)))
