"""Freed memory kept in the benches' process (glibc's malloc), so that a method's speed
does not depend on what ran before it.

By default glibc gives large blocks back to the system when they are freed (each one
``mmap``-ed, or the heap's top trimmed) and takes fresh pages at the next allocation.
Each fresh page is a page fault, and here (a virtual machine) a fault is several
microseconds. The paper's chain allocates tens of megabytes of temporaries a frame
(2048 x 1536 images and their float gradients): timed in a process of its own it took
28-30 ms a nominal frame, and 20-21 ms with the memory kept; that process took ~850 000
minor faults for 360 frames through the chain (~9 MB of fresh pages a frame). How often
the memory was given back depended on the allocations before (the "slow spells" of
`bench vision`'s paper chain in the tenth and eleventh passes). The default method
reuses its buffers and runs the same either way. Both are timed with the memory kept:
the comparison is then of the methods, not of the allocator's history.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

# mallopt(3) parameters
_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3
#: Blocks below this are taken from the heap, not ``mmap``-ed (glibc's largest setting
#: on 64-bit systems).
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
#: The heap grows by this much more than asked, and its top is never trimmed.
TOP_PAD_BYTES = 256 * 1024 * 1024
_NEVER_TRIM = 2**31 - 1


def keep_freed_memory() -> bool:
    """Ask glibc's malloc to keep freed memory in this process (for the rest of its
    life); whether it could (False elsewhere: another C library, another system)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    settings = (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES),
        (_M_TRIM_THRESHOLD, _NEVER_TRIM),
        (_M_TOP_PAD, TOP_PAD_BYTES),
    )
    return all([mallopt(param, value) == 1 for param, value in settings])
