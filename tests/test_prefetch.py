"""Prefetch: a decoder run ahead in a real producer thread, through a bounded queue."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from daemon.prefetch import Prefetch
from simulator.autopilot import wait_until


def test_items_arrive_in_order_and_all_of_them() -> None:
    with Prefetch("numbers", iter(range(1000)), maxsize=4) as p:
        assert list(p) == list(range(1000))
        assert p.produced == 1000
        assert list(p) == []  # ended stays ended


def test_the_producer_stops_when_the_queue_is_full() -> None:
    pulled = []

    def source() -> Iterator[int]:
        for k in range(100):
            pulled.append(k)
            yield k

    p = Prefetch("bounded", source(), maxsize=3)
    try:
        # 3 in the queue and a 4th decoded, waiting for room; never more however long the consumer dawdles
        assert wait_until(lambda: len(pulled) == 4, timeout=5.0)
        time.sleep(0.3)
        assert len(pulled) == 4 and p.produced == 3
        assert next(p) == 0
        assert wait_until(lambda: len(pulled) == 5, timeout=5.0)
        time.sleep(0.3)
        assert len(pulled) == 5
    finally:
        p.close()


def test_a_decoder_error_is_raised_in_the_consumer_after_the_good_items() -> None:
    def source() -> Iterator[int]:
        yield 1
        yield 2
        raise ValueError("torn capture")

    with Prefetch("failing", source()) as p:
        assert next(p) == 1
        assert next(p) == 2
        with pytest.raises(ValueError, match="torn capture"):
            next(p)
        with pytest.raises(StopIteration):
            next(p)


def test_close_stops_a_blocked_producer_and_closes_its_generator() -> None:
    closed = threading.Event()

    def endless() -> Iterator[int]:
        try:
            k = 0
            while True:
                yield k
                k += 1
        finally:
            closed.set()  # where a source closes its file

    p = Prefetch("endless", endless(), maxsize=2)
    assert next(p) == 0
    assert wait_until(lambda: p.produced >= 2, timeout=5.0)
    t0 = time.monotonic()
    p.close()
    assert time.monotonic() - t0 < 2.0  # the producer polls every 0.1 s while the queue is full
    assert closed.is_set()
    assert not [t for t in threading.enumerate() if t.name == "prefetch-endless"]
    with pytest.raises(StopIteration):
        next(p)


def test_maxsize_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="maxsize"):
        Prefetch("none", iter(()), maxsize=0)
