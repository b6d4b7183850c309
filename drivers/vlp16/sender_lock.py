"""Which sender a VLP-16 source takes packets from: the configured address, else the first that looks like a VLP-16.

Every Velodyne sends to port 2368 (on factory settings as a broadcast), so a source that takes "any sender" mixes a
second sensor's packets into its revolutions: its returns land at the wrong bearings, and its empty firings cover
sectors the own sensor did not see, which the coverage then calls clear. The lock is kept by address (IP and port),
never by what a packet says: once locked, another sender stays dropped even if it sends perfect VLP-16 packets,
because a second VLP-16 on the same boat network is the common case.

With ``accept_ip`` configured, that IP (any port) is the sender and nothing else qualifies. Otherwise a sender takes
the lock with ``lock_packets`` consecutive data packets that each look like the configured model:

* a well-formed 1206-byte data packet (block flags, azimuths, return mode, timestamp: ``data_packet_problem``);
* a product byte of the model: 0x22 for a VLP-16, or 0x21 too when the model is forced to VLP16, because early
  VLP-16 firmware reports the HDL-32E code (spec section 2);
* the sensor's cadence: the device timestamp advanced by one VLP-16 packet period since the sender's previous
  packet (1327.104 us, 663.552 us in dual return), within 5 %. This is what tells an early VLP-16 from an HDL-32E
  sending the same product byte every 553 us, and a VLP-16 from a VLP-32C (663.552 us, product 0x28). Cadence is
  judged on the sensor's own clock, not on arrival times: the reader drains the socket in 30 ms batches, so arrival
  times are bunched and say nothing per packet.

With the model "auto" (trust the product byte) any known Velodyne product qualifies, and the cadence check is only
that the stamps advance by at most two VLP-16 periods: a stream, not a trickle. The qualifying packets are held and
handed over with the lock, so the winner loses none of them; position packets that arrive before a lock are held
too, and only the winner's are then taken.

A locked sender that falls silent for ``timeout_s`` releases the lock (the source decides when: only right after it
has read everything queued, so a stalled reader cannot take a backlog for silence), and the next sender that qualifies
takes it: a sensor that was re-addressed or swapped is picked up without a restart. Default 2 s: that is 1500 packets
in a row missing (no burst loss or switch hiccup lasts that long), the same time after which the source already logs
the sensor silent, and four times the 0.5 s after which the output already reports its bearings unknown, so moving
the lock never hides a gap. Releasing sooner would let two sensors that both stutter take turns.

Every dropped datagram is counted in the source's stats; another sender appearing is logged at once (at most once a
minute), and the drops are summed up in one log line a minute, never one per packet.
"""

from __future__ import annotations

import logging
import math
import struct
from dataclasses import dataclass, field

from drivers.vlp16.packet import (
    DATA_PACKET_SIZE,
    DATA_PORT,
    MICROSECONDS_PER_HOUR,
    PACKET_PERIOD_US,
    PRODUCT_HDL32E,
    PRODUCT_MODELS,
    PRODUCT_VLP16,
    RETURN_MODE_DUAL,
    data_packet_problem,
)
from drivers.vlp16.source_stats import LidarSourceStats

log = logging.getLogger(__name__)

Address = tuple[str, int]

LOCK_PACKETS = 5  # 6.6 ms of a VLP-16's data; a chance match of 4 cadence steps by another device is not credible
LOCK_TIMEOUT_S = 2.0
CADENCE_TOLERANCE = 0.05  # of the period: stamps are whole microseconds (1327 or 1328); other models' are half or less
REPORT_INTERVAL_S = 60.0
_MAX_STEP_US = 2 * PACKET_PERIOD_US  # model "auto": a stream, not packets seconds apart
_MAX_CANDIDATES = 16  # senders qualifying at once; beyond, a spray of addresses, not sensors
_MAX_HELD_POSITIONS = 8  # per IP before a lock: a VLP-16 sends one every ~8 ms, a lock takes ~7 ms
_MAX_OTHERS = 64  # other senders remembered for "appeared" messages
_TAIL = struct.Struct("<IBB")  # timestamp, return mode, product id at offset 1200


@dataclass
class _Candidate:
    product: int
    timestamp_us: int
    streak: int = 0  # qualifying packets in a row
    packets: list[tuple[float, bytes]] = field(default_factory=list)  # (arrival time, payload), held for the lock


class SenderLock:
    """The sender a VLP-16 source takes data from; counts and logs everything it drops in ``stats``.

    ``model`` is the assembler's normalised model ("VLP16", or None to trust the product byte). Not thread-safe: the
    source's reader thread owns it.
    """

    def __init__(
        self,
        stats: LidarSourceStats,
        model: str | None = "VLP16",
        accept_ip: str | None = None,
        timeout_s: float = LOCK_TIMEOUT_S,
        lock_packets: int = LOCK_PACKETS,
        port: int = DATA_PORT,
    ) -> None:
        self.stats = stats
        self.model = model
        self.accept_ip = accept_ip or None
        self.timeout_s = timeout_s
        self.lock_packets = lock_packets
        self.port = port  # only for messages
        self._products = {PRODUCT_VLP16, PRODUCT_HDL32E} if model == "VLP16" else set(PRODUCT_MODELS)
        self._ip: str | None = self.accept_ip
        self._port: int | None = None  # None: any port of _ip
        self.last_heard = -math.inf  # host time of the locked sender's last data packet (the source keeps it)
        self._previous = ""  # the sender of the last lock, for "moved" messages
        self._candidates: dict[Address, _Candidate] = {}
        # IP -> (arrival time, payload, sender) of position packets held before a lock
        self._positions: dict[str, list[tuple[float, bytes, Address]]] = {}
        self.held_positions: list[tuple[float, bytes, Address]] = []  # the winner's, for the source to take
        self._others: dict[object, float] = {}  # another sender -> when last heard
        self._last_appearance_log = -math.inf
        self._window_start: float | None = None  # of the drops the next summary sums up
        self._reported = 0
        if self.accept_ip is not None:
            stats.sender = self.accept_ip

    # --- the hot path -----------------------------------------------------------------------------------------------
    def owns(self, address: Address) -> bool:
        """A data datagram from the locked sender (two comparisons: it runs for every packet)."""
        return address[0] == self._ip and (self._port is None or address[1] == self._port)

    def owns_host(self, address: Address) -> bool:
        """A position datagram from the locked sensor, which sends those from another port than its data."""
        return self._ip is not None and address[0] == self._ip

    # --- everything else ----------------------------------------------------------------------------------------------
    @property
    def locked(self) -> bool:
        return self._ip is not None

    @property
    def pending(self) -> int:
        """Datagrams held while no sender is locked (neither taken nor counted as dropped yet)."""
        return sum(len(c.packets) for c in self._candidates.values()) + sum(len(q) for q in self._positions.values())

    def describe(self) -> str:
        """The sender in words, for messages about the source."""
        if self._ip is not None:
            return self.stats.sender
        waiting = "any sender that looks like a VLP-16"
        return f"{waiting} (last {self._previous})" if self._previous else waiting

    def offer(self, address: Address, payload: bytes, now: float) -> list[tuple[float, bytes]]:
        """A data datagram from a sender the lock does not own. Returns the packets to take, oldest first: none,
        unless this one completed a sender's qualification, then all of that sender's held packets."""
        if self._ip is not None:
            self.reject(address, now)
            return []
        candidate = self._candidates.get(address)
        if (
            candidate is not None
            and len(payload) != DATA_PACKET_SIZE
            and len(candidate.packets) < 4 * self.lock_packets
        ):
            # A truncated or merged datagram says nothing against the sender: held with its streak, and counted as
            # wrong-size by the source if the sender wins (as it would be from a locked sender).
            candidate.packets.append((now, payload))
            return []
        verdict = self._judge(payload, candidate)
        if verdict is None:  # not a packet of the configured sensor: it and the sender's streak are dropped
            self._drop_candidate(address)
            self._count_drop(address, 1)
            return []
        timestamp, product, continues = verdict
        if candidate is None or not continues:
            # A fine packet off the beat (a lost packet, a clock step) starts a new streak rather than being wasted.
            self._drop_candidate(address)
            if len(self._candidates) >= _MAX_CANDIDATES:
                for other in list(self._candidates):
                    self._drop_candidate(other)
            candidate = self._candidates[address] = _Candidate(product, timestamp)
        candidate.timestamp_us = timestamp
        candidate.streak += 1
        candidate.packets.append((now, payload))
        if candidate.streak < self.lock_packets:
            return []
        del self._candidates[address]
        for other in list(self._candidates):
            self._drop_candidate(other)
        self._take(address, now)
        return candidate.packets

    def offer_position(self, address: Address, payload: bytes, now: float) -> None:
        """A position datagram from a sender the lock does not own: held while there is no lock (the sensor that will
        take it has sent some already), dropped otherwise."""
        if self._ip is not None:
            self.reject(address, now)
            return
        queue = self._positions.get(address[0])
        if queue is None:
            if len(self._positions) >= _MAX_CANDIDATES:
                self._drop_positions()
            queue = self._positions[address[0]] = []
        elif len(queue) >= _MAX_HELD_POSITIONS:
            del queue[0]  # only the newest PPS state matters
            self._count_drop(address, 1)
        queue.append((now, payload, address))

    def reject(self, address: Address, now: float) -> None:
        """Count a datagram (either port) from a sender other than the locked one; say so when a sender appears."""
        st = self.stats
        st.foreign_source += 1
        st.last_foreign_ip = address[0]
        st.last_foreign = f"{address[0]}:{address[1]}"
        if self._ip is None:
            return  # no lock yet: there is no "second" sender
        # One sensor sends data and position packets from two ports: known by its IP, unless it shares ours.
        key: object = address if address[0] == self._ip else address[0]
        seen = self._others.get(key)
        self._others[key] = now
        if seen is not None and now - seen < REPORT_INTERVAL_S:
            return
        st.other_senders += 1
        if len(self._others) > _MAX_OTHERS:
            self._forget_others(now)
        if now - self._last_appearance_log >= REPORT_INTERVAL_S:
            self._last_appearance_log = now
            log.warning(
                "VLP-16 port %d: another sender, %s, is ignored: data is taken from %s only%s",
                self.port,
                st.last_foreign,
                st.sender,
                "" if self.accept_ip else " (the first that looked like a VLP-16; set lidar.accept_ip to choose)",
            )

    def expire(self, now: float) -> bool:
        """Release the lock if its sender has been silent for ``timeout_s``; True if it was released now. Call it only
        when every datagram queued before ``now`` has been read."""
        if self.accept_ip is not None or self._ip is None or now - self.last_heard < self.timeout_s:
            return False
        self._previous = self.stats.sender
        log.warning(
            "VLP-16 port %d: %s silent for %.1f s: lock released, the next sender that looks like a VLP-16 takes it",
            self.port,
            self._previous,
            now - self.last_heard,
        )
        self._ip = self._port = None
        self.stats.sender = ""
        return True

    def report(self, now: float) -> None:
        """Once a minute, one line for the datagrams dropped since the last (the per-packet path never logs)."""
        if self._window_start is None:
            self._window_start = now
            return
        if now - self._window_start < REPORT_INTERVAL_S:
            return
        st = self.stats
        dropped = st.foreign_source - self._reported
        if dropped:
            heard = sum(1 for t in self._others.values() if t >= self._window_start)
            # Expected on a boat with two sensors once accept_ip names ours; a finding while the lock chose by itself.
            log.log(
                logging.INFO if self.accept_ip else logging.WARNING,
                "VLP-16 port %d: %d datagrams from other senders dropped in the last %.0f s (%d sender(s), last %s); "
                "data taken from %s",
                self.port,
                dropped,
                now - self._window_start,
                heard,
                st.last_foreign,
                st.sender or "nobody (no sender qualified)",
            )
        self._reported = st.foreign_source
        self._window_start = now

    # --- internals ----------------------------------------------------------------------------------------------------
    def _judge(self, payload: bytes, candidate: _Candidate | None) -> tuple[int, int, bool] | None:
        """(timestamp, product, continues the candidate's streak), or None if not a packet of the configured model."""
        if len(payload) != DATA_PACKET_SIZE or data_packet_problem(payload) is not None:
            return None
        timestamp, mode, product = _TAIL.unpack_from(payload, 1200)
        if product not in self._products:
            return None
        if candidate is None or product != candidate.product:
            return timestamp, product, False
        step = (timestamp - candidate.timestamp_us) % MICROSECONDS_PER_HOUR
        if self.model != "VLP16":
            return timestamp, product, 0 < step <= _MAX_STEP_US
        period = PACKET_PERIOD_US / 2 if mode == RETURN_MODE_DUAL else PACKET_PERIOD_US
        return timestamp, product, abs(step - period) <= CADENCE_TOLERANCE * period

    def _take(self, address: Address, now: float) -> None:
        sender = f"{address[0]}:{address[1]}"
        self._ip, self._port = address
        self.last_heard = now
        self._others.clear()
        self.held_positions = self._positions.pop(address[0], [])
        self._drop_positions()
        self.stats.sender = sender
        if self._previous and self._previous != sender:
            self.stats.lock_moves += 1
            log.warning(
                "VLP-16 port %d: lock moved from %s to %s (%d packets at a VLP-16's cadence)",
                self.port,
                self._previous,
                sender,
                self.lock_packets,
            )
        else:
            log.info(
                "VLP-16 port %d: locked onto %s (%d packets at a VLP-16's cadence); any other sender is dropped",
                self.port,
                sender,
                self.lock_packets,
            )

    def _drop_candidate(self, address: Address) -> None:
        candidate = self._candidates.pop(address, None)
        if candidate is not None and candidate.packets:
            self._count_drop(address, len(candidate.packets))

    def _drop_positions(self) -> None:
        for queue in self._positions.values():
            if queue:
                self._count_drop(queue[-1][2], len(queue))
        self._positions.clear()

    def _count_drop(self, address: Address, n: int) -> None:
        st = self.stats
        st.foreign_source += n
        st.last_foreign_ip = address[0]
        st.last_foreign = f"{address[0]}:{address[1]}"

    def _forget_others(self, now: float) -> None:
        for key in [k for k, t in self._others.items() if now - t >= REPORT_INTERVAL_S]:
            del self._others[key]
        if len(self._others) > _MAX_OTHERS:  # a spray of addresses: start over rather than grow
            self._others.clear()
