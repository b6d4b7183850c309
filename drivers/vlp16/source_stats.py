"""Counters and position-packet state shared by the live and the replay VLP-16 sources.

Written only by the source's reader thread and read by others (health log, ``decode`` summary): plain
attributes, no locks, a reader may see one counter a packet ahead of another.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import POSITION_PACKET_SIZE, PPS_STATUS_NAMES, PacketError, decode_position_packet

log = logging.getLogger(__name__)


@dataclass
class LidarSourceStats:
    packets: int = 0  # data packets received from the accepted source with the right size
    bytes: int = 0  # payload bytes of those packets
    wrong_size: int = 0  # data-port payloads from the sender the source takes data from that were not 1206 bytes
    # Datagrams on either port not taken from the sender the source locked onto (sender_lock.py), dropped: other
    # senders', and before a lock those that do not look like the configured sensor or lost the race for the lock.
    foreign_source: int = 0
    last_foreign_ip: str = ""  # a sensor re-addressed by someone shows up here
    last_foreign: str = ""  # "ip:port" of the last dropped sender
    sender: str = ""  # "ip:port" the data comes from ("ip" when lidar.accept_ip chose it); "" while unlocked
    other_senders: int = 0  # appearances of another sender while locked (one that was quiet for a minute counts again)
    lock_moves: int = 0  # times the lock went over to a different sender after its own fell silent
    malformed: int = 0  # 1206 bytes but not a VLP-16 packet (flags, mode, timestamp)
    out_of_order: int = 0
    missing: int = 0  # packets lost, from gaps in the device clock
    decode_errors: int = 0
    scans: int = 0
    points: int = 0
    position_packets: int = 0
    position_wrong_size: int = 0
    pps_status: int | None = None  # latest position packet: 0 absent, 1 synchronizing, 2 locked, 3 error
    nmea: str = ""  # latest non-empty NMEA sentence
    last_packet_time: float | None = None  # host clock, last accepted data packet
    last_position_time: float | None = None
    silent: bool = False  # no data packet for silence_timeout_s (live source only)

    @property
    def pps_name(self) -> str:
        return "unknown" if self.pps_status is None else PPS_STATUS_NAMES.get(self.pps_status, str(self.pps_status))

    def take_assembler(self, assembler: ScanAssembler) -> None:
        a = assembler.stats
        self.malformed = a.malformed
        self.out_of_order = a.out_of_order
        self.missing = a.missing
        self.decode_errors = a.decode_errors
        self.scans = a.scans
        self.points = a.points

    def take_position(self, host_time: float, payload: bytes, assembler: ScanAssembler) -> None:
        """Record a position packet; its PPS status decides whether scans claim a locked device clock."""
        if len(payload) != POSITION_PACKET_SIZE:
            self.position_wrong_size += 1
            return
        try:
            position = decode_position_packet(payload)
        except PacketError:  # pragma: no cover - the length was checked above
            self.position_wrong_size += 1
            return
        if position.pps_status != self.pps_status:
            log.info("VLP-16 PPS status: %s", position.pps_name)
        self.position_packets += 1
        self.pps_status = position.pps_status
        if position.nmea:
            self.nmea = position.nmea
        self.last_position_time = host_time
        assembler.pps_locked = position.pps_locked

    def forget_position(self) -> None:
        """Another sensor's stream starts (the source locked onto a new sender): the old PPS state is not its."""
        self.pps_status = None
        self.nmea = ""
        self.last_position_time = None

    def position_stale(self, host_now: float, timeout_s: float, assembler: ScanAssembler) -> None:
        """Position packets stopped: a PPS lock reported long ago is no longer a lock."""
        if self.last_position_time is not None and host_now - self.last_position_time > timeout_s:
            assembler.pps_locked = False
