"""Give the C heap's free pages back to the system, from the live loop once per health interval.

glibc's malloc raises its mmap threshold to the size of the largest mmapped block freed so far (up to 32 MB) and
its trim threshold to twice that; from then on every numpy array under that size is carved from the main heap, and
the heap keeps the pages of what is freed in its middle. The soak (bench/soak.py, issue #14) found the radar static
map's 11 MB grids, made anew at every shift, doing exactly that: the main arena at 66-98 MB with up to 36 MB of it
free, the RSS stepping by 20-30 MB with the scenes. The grids now shift in place (tracker/grid_shift.py), which
removed the steps; the trim is the bound for whatever else leaves free memory in the heap (trackers made anew after
a world-frame change drop their grids in it). Measured on the soak: 0.5 ms median, 6 ms p99, every 5 s.

Arenas: glibc gives every thread that allocates its own arena (up to 8 per core), each with its own free lists,
top and high-water mark, and trims only what lies free at whole pages. The demo ran with 8 thread arenas beside the
main heap, one of them holding 17.5 MB; the readers' decoding and the loop's arrays then fragment eight heaps
instead of two. ``limit_arenas`` caps them (glibc's ``mallopt(M_ARENA_MAX)``, as ``MALLOC_ARENA_MAX`` would), before
the daemon starts its threads. Threads past the cap share an arena under its lock; with the GIL held for nearly
every allocation they rarely wait.

``malloc_trim(0)`` returns the free top of every arena and the whole free pages inside them (madvise): nothing in
use moves, so the loop's output is the same. Without glibc (musl, macOS: no ``malloc_trim``) it is a no-op.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable


def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim`` from the process's own C library, or None where there is none."""
    try:
        fn = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):  # no dlopen(NULL) (Windows), or a libc without it (musl, macOS)
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn  # type: ignore[no-any-return]


_TRIM = _malloc_trim()
AVAILABLE = _TRIM is not None

M_ARENA_MAX = -8  # glibc's malloc.h
ARENA_MAX = 2  # the main heap and one for the threads


def limit_arenas(n: int = ARENA_MAX) -> bool:
    """Cap glibc's malloc arenas at ``n`` for threads started from now on; True if the C library took it (always
    False without glibc)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_ARENA_MAX, n))


def release_free_memory() -> bool:
    """Hand the C heap's free pages back to the system; True if any were (always False without glibc)."""
    return bool(_TRIM(0)) if _TRIM is not None else False
