"""One reader thread per source: it turns a blocking driver iterator into items in a loop buffer.

A driver error (cable pulled, port vanished, decoder choking on bytes) must never take the daemon down: the thread
logs it (once per distinct message, so a dead cable does not flood the journal), counts it, waits and starts the
source again. The loop meanwhile sees the source go stale and reports "no data" for its bearings.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

log = logging.getLogger(__name__)

T = TypeVar("T")


class ReaderThread(threading.Thread, Generic[T]):
    def __init__(
        self,
        name: str,
        iterate: Callable[[threading.Event], Iterator[T]],
        put: Callable[[T, float], None],
        stop: threading.Event,
        clock: Callable[[], float] = time.monotonic,
        retry_s: float = 2.0,
    ) -> None:
        super().__init__(name=f"reader-{name}", daemon=True)
        self.source_name = name
        self._iterate = iterate
        self._put = put
        self._stop_event = stop
        self._clock = clock
        self._retry_s = retry_s
        self.items = 0
        self.errors = 0
        self.last_error = ""
        self.finished = False  # a finite source (capture file) reached its end

    def run(self) -> None:
        while not self._stop_event.is_set():
            try:
                for item in self._iterate(self._stop_event):
                    self._put(item, self._clock())
                    self.items += 1
                    if self._stop_event.is_set():
                        break
                else:
                    if not self._stop_event.is_set():
                        log.info("%s: source ended", self.source_name)
                        self.finished = True
                        return
            except Exception as exc:  # a driver bug or a device error: report, back off, try again
                self.errors += 1
                message = f"{type(exc).__name__}: {exc}"
                if message != self.last_error:
                    log.error("%s: %s (retrying every %.0f s)", self.source_name, message, self._retry_s)
                    if self.errors == 1:
                        log.debug("%s: traceback", self.source_name, exc_info=True)
                self.last_error = message
                self._stop_event.wait(self._retry_s)
