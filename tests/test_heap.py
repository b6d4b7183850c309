"""The live loop hands the C heap's free pages back to the system once per health interval (daemon.heap): glibc keeps
the pages of memory freed in the middle of its heap, which is how the soak's RSS rose by 40 MB over an hour."""

from __future__ import annotations

import ctypes
import gc
import os
import platform
import struct
import weakref
from pathlib import Path

import pytest

from daemon import heap
from daemon.config import load_config
from daemon.loop import DaemonLoop, LoopSettings, SensorInputs
from daemon.runner import pipeline_for

GLIBC = platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"
needs_glibc = pytest.mark.skipif(not GLIBC, reason="malloc_trim is glibc's (the boat's Debian/Ubuntu)")


def _rss_kb() -> int:
    with open("/proc/self/statm", encoding="ascii") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024


@needs_glibc
def test_glibc_trim_is_found() -> None:
    assert heap.AVAILABLE


@needs_glibc
def test_trim_hands_back_freed_heap_memory_that_free_keeps() -> None:
    """The soak's case in small: blocks under the mmap threshold come from the heap; freed between blocks still in
    use, they stay resident (free only returns the heap's top), until malloc_trim hands their pages back."""
    libc = ctypes.CDLL(None)
    libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
    libc.free.restype, libc.free.argtypes = None, [ctypes.c_void_p]
    block, n = 64 * 1024, 640  # 40 MB in blocks glibc never mmaps
    ptrs = [libc.malloc(block) for _ in range(n)]
    assert all(ptrs)
    try:
        for p in ptrs:
            ctypes.memset(p, 1, block)  # resident
        kept, freed = ptrs[9::10], [p for k, p in enumerate(ptrs) if k % 10 != 9]  # each freed run pinned
        before = _rss_kb()
        for p in freed:
            libc.free(p)
        after_free = _rss_kb()
        heap.release_free_memory()
        after_trim = _rss_kb()
    finally:
        for p in kept:
            libc.free(p)
    assert before - after_free < 8 * 1024, (before, after_free)  # 36 MB freed, (nearly) all still resident
    assert after_free - after_trim > 24 * 1024, (after_free, after_trim)  # handed back by the trim


def test_the_loop_trims_once_per_health_interval_after_its_line() -> None:
    loop = DaemonLoop(None, SensorInputs(), None, None, LoopSettings(health_interval_s=5.0))  # type: ignore[arg-type]
    assert loop.release_memory is heap.release_free_memory  # what the live daemon runs
    when: list[float] = []
    now = 0.0
    loop.release_memory = lambda: when.append(now)
    for now in [k * 0.1 for k in range(151)]:  # 15 s of ticks at 10 Hz
        loop.maybe_log_health(now)
    assert when == pytest.approx([0.0, 5.0, 10.0, 15.0])


HEAP_MAX = 64 << 20  # glibc's HEAP_MAX_SIZE on 64-bit: every thread arena's heap is a mapping this size, aligned to it


def thread_arenas(pid: int) -> int:
    """glibc thread arenas in process ``pid``: the 64 MB-aligned anonymous mappings of 64 MB (their used part
    read-write, the rest inaccessible) whose first bytes are the header of an arena's first heap. The shape alone
    overcounts: OpenBLAS's 64 MB buffer is sometimes mapped at such an address too (seen on a busy machine)."""
    lines = [line for line in Path(f"/proc/{pid}/maps").read_text().splitlines() if line.strip()]
    owners: set[int] = set()
    with open(f"/proc/{pid}/mem", "rb", buffering=0) as mem:
        for a, b in zip(lines, [*lines[1:], ""], strict=True):
            f, g = a.split(), b.split()
            start, end = (int(x, 16) for x in f[0].split("-"))
            if len(f) != 5 or f[1] != "rw-p" or start % HEAP_MAX:
                continue
            size = end - start
            if g and g[1] == "---p" and int(g[0].split("-")[0], 16) == end:
                size += int(g[0].split("-")[1], 16) - end
            if size != HEAP_MAX:
                continue
            mem.seek(start)
            ar_ptr, prev = struct.unpack("<QQ", mem.read(16))  # heap_info's first two fields
            if prev == 0 and start < ar_ptr < start + 4096:  # an arena's first heap holds the arena itself
                owners.add(ar_ptr)
    return len(owners)


ARENA_PROBE = """
import sys, threading, numpy as np
from daemon import heap
if LIMIT:
    assert heap.limit_arenas(2)
go = threading.Barrier(6)
def work():
    go.wait()  # all six alive at once: glibc gives each a new arena while under its cap
    keep = [np.ones(4096) for _ in range(200)]
    go.wait()
ts = [threading.Thread(target=work) for _ in range(6)]
for t in ts: t.start()
for t in ts: t.join()
print("ready", flush=True)
sys.stdin.readline()  # the arenas are counted from outside meanwhile
"""


@needs_glibc
@pytest.mark.parametrize("limit", [False, True])
def test_threads_share_one_arena_beside_the_main_heap_under_the_cap(limit: bool) -> None:
    """Six threads allocating at once: glibc's default gives each its own arena; under the daemon's cap of two
    (daemon.heap.limit_arenas) they share one beside the main heap."""
    import subprocess
    import sys

    code = ARENA_PROBE.replace("LIMIT", str(limit))
    probe = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert probe.stdout is not None and probe.stdout.readline() == "ready\n"
        arenas = thread_arenas(probe.pid)
    finally:
        probe.communicate("\n", timeout=60)
    assert probe.returncode == 0
    if limit:
        assert arenas <= 1
    else:
        assert arenas >= 4  # the default (8 per core) leaves six threads at least four of their own


class _Cycle:
    """Garbage that only the cyclic collector frees (it refers to itself)."""

    def __init__(self) -> None:
        self.me = self


def test_the_loop_collects_the_old_worlds_trackers_after_a_world_reset() -> None:
    # The soak grew 100 MB in 4 minutes of new worlds: the old trackers lay in reference cycles that CPython's full
    # collections, seldom in a long-lived process, left for minutes. Automatic collection off, so that only the
    # loop's own collection can free what is in a cycle.
    pipeline = pipeline_for(load_config(None, {}))
    loop = DaemonLoop(pipeline, SensorInputs(), None, None, LoopSettings())
    old = pipeline.radar_tracker
    old.held_by_itself = old  # the cycle the live path makes
    old_ref = weakref.ref(old)
    del old
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        loop.collect_old_world()  # no new world yet: nothing collected
        assert old_ref() is not None
        pipeline.reset_tracks()  # a failed cycle or a new world frame: the trackers made anew
        assert old_ref() is not None  # garbage, in a cycle
        loop.collect_old_world()
        assert old_ref() is None
        unrelated = _Cycle()
        unrelated_ref = weakref.ref(unrelated)
        del unrelated
        loop.collect_old_world()  # once per new world, not every tick
        assert unrelated_ref() is not None
    finally:
        if was_enabled:
            gc.enable()
        gc.collect()
