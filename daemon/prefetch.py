"""Run a decoding iterator ahead of its consumer in a producer thread, through a bounded queue.

A producer thread decodes the next items while the consumer works on the current ones; the queue's bound keeps at
most ``maxsize`` decoded items in memory (a revolution is ~1 MB) and makes the producer wait when it is that far
ahead. The replay uses it only when asked (``ReplayOptions.prefetch``): its tick loop decoding for itself measured
faster, since a Python decoder thread holds the interpreter lock the tracker then waits for (bench/replay_speed.py).

Order and content are the iterator's own, so a replay through it is exactly as deterministic as without it. An
exception in the producer is raised in the consumer at the point where the items ran out.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from typing import Generic, TypeVar

T = TypeVar("T")

_PUT_POLL_S = 0.1  # how soon a producer blocked on a full queue notices close()


class _End:
    def __init__(self, error: BaseException | None = None) -> None:
        self.error = error


class Prefetch(Generic[T]):
    """Iterate ``source`` in a daemon thread named ``prefetch-<name>``; iterate this object to consume.

    ``close()`` stops the producer (within about 0.1 s, or when its current item is decoded) and joins it; it is
    safe to call more than once and from a ``finally``. Use as a context manager to close on exit.
    """

    def __init__(self, name: str, source: Iterator[T], maxsize: int = 8) -> None:
        if maxsize < 1:
            raise ValueError(f"maxsize must be >= 1, got {maxsize}")
        self.name = name
        self._source = source
        self._queue: queue.Queue[T | _End] = queue.Queue(maxsize)
        self._stop = threading.Event()
        self._ended = False
        self.produced = 0  # items the producer has put so far (for tests and diagnostics)
        self.waits = 0  # times the consumer found the queue empty and had to wait for the decoder
        self._thread = threading.Thread(target=self._run, name=f"prefetch-{name}", daemon=True)
        self._thread.start()

    def _put(self, item: T | _End) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=_PUT_POLL_S)
                return True
            except queue.Full:
                continue
        return False

    def _run(self) -> None:
        end = _End()
        try:
            for item in self._source:
                if not self._put(item):
                    return
                self.produced += 1
        except BaseException as exc:  # handed to the consumer, which decides what it means
            end = _End(exc)
        finally:
            close = getattr(self._source, "close", None)
            if close is not None:
                close()  # a generator's finally (open files) runs here, in the thread that ran it
        self._put(end)

    def __iter__(self) -> Iterator[T]:
        return self

    def __next__(self) -> T:
        if self._ended:
            raise StopIteration
        try:
            item = self._queue.get_nowait()
        except queue.Empty:
            self.waits += 1
            item = self._queue.get()
        if isinstance(item, _End):
            self._ended = True
            self._thread.join()
            if item.error is not None:
                raise item.error
            raise StopIteration
        return item

    def close(self) -> None:
        self._stop.set()
        self._ended = True
        self._thread.join()

    def __enter__(self) -> Prefetch[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
