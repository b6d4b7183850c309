"""Per-revolution summary of a VLP-16 capture, for ``usv-tracker decode FILE``.

Runs the capture through the driver's own ``ScanAssembler`` (so what it prints is what the daemon would
see) and collects what a person needs when a capture decodes to nothing or to nonsense: which ports and
senders were in it, wrong sizes, the product byte, the packet cadence, the PPS status.
"""

from __future__ import annotations

import math
import os
import statistics
from collections import Counter
from collections.abc import Iterator
from typing import Any

from drivers.vlp16.decoder import ScanAssembler, normalise_model
from drivers.vlp16.packet import (
    AZIMUTH_UNITS,
    DATA_PACKET_SIZE,
    DATA_PORT,
    PACKET_PERIOD_US,
    POSITION_PORT,
    PRODUCT_HDL32E,
    PRODUCT_MODELS,
    RETURN_MODE_NAMES,
    data_packet_problem,
    read_data_header,
)
from drivers.vlp16.pcap import PcapReader
from drivers.vlp16.source_stats import LidarSourceStats


class NoLidarDataError(ValueError):
    """The capture holds no usable VLP-16 data packets; the message says what it does hold."""


class PcapSummary:
    """Iterator of one dict per revolution; ``totals`` holds the file summary once iteration has ended.

    Revolution dict keys: index, stamp (capture time of the last firing, Unix s), stamp_device, points,
    packets, packets_missing, return_mode, model, pps (PPS status name at that time: absent, synchronizing,
    locked, error, unknown = no position packets).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        model: str | None = None,
        cut_angle: float | None = None,
        port: int = DATA_PORT,
        position_port: int = POSITION_PORT,
    ) -> None:
        self.path = os.fspath(path)
        self.reader = PcapReader(self.path)  # NotAPcapError here, before any output
        self.port = port
        self.position_port = position_port
        self.model = normalise_model(model)
        self.cut_angle = math.pi if cut_angle is None else cut_angle
        self.assembler = ScanAssembler(cut_angle=self.cut_angle, model=self.model)
        self.stats = LidarSourceStats()
        self.totals: dict[str, Any] | None = None
        self._iterator = self._run()

    def __iter__(self) -> PcapSummary:
        return self

    def __next__(self) -> dict[str, Any]:
        return next(self._iterator)

    def _run(self) -> Iterator[dict[str, Any]]:
        index = 0
        other_ports: Counter[int] = Counter()
        senders: Counter[str] = Counter()
        products: Counter[int] = Counter()
        modes: Counter[int] = Counter()
        cadence_us: list[int] = []
        rate_cdeg_per_us: list[float] = []
        previous: tuple[int, int] | None = None  # (timestamp us, last azimuth) of the previous good packet
        first_time = last_time = None

        for datagram in self.reader:
            t = datagram.timestamp_s
            first_time = t if first_time is None else first_time
            last_time = t
            if datagram.dst_port == self.position_port:
                self.stats.take_position(t, datagram.payload, self.assembler)
                continue
            if datagram.dst_port != self.port:
                other_ports[datagram.dst_port] += 1
                continue
            if len(datagram.payload) != DATA_PACKET_SIZE:
                self.stats.wrong_size += 1
                continue
            if data_packet_problem(datagram.payload) is None:
                header = read_data_header(datagram.payload)
                senders[datagram.src_ip] += 1
                products[header.product_id] += 1
                modes[header.return_mode] += 1
                if previous is not None:
                    dt = (header.timestamp_us - previous[0]) % 3_600_000_000
                    if 0 < dt < 10 * PACKET_PERIOD_US:
                        cadence_us.append(dt)
                        rate_cdeg_per_us.append(((header.last_azimuth_cdeg - previous[1]) % AZIMUTH_UNITS) / dt)
                previous = (header.timestamp_us, header.last_azimuth_cdeg)
            self.stats.packets += 1
            self.stats.bytes += len(datagram.payload)
            for scan in self.assembler.push(t, datagram.payload):
                yield self._revolution(index, scan)
                index += 1
            self.stats.take_assembler(self.assembler)
        for scan in self.assembler.flush():
            yield self._revolution(index, scan)
            index += 1
        self.stats.take_assembler(self.assembler)
        # Sensor clock minus capture clock: ~0 with GPS/PPS, tens of minutes for a free-running sensor.
        device_minus_host = -self.assembler.clock.offset if self.assembler.clock.last_device_time is not None else None

        good = self.stats.packets - self.stats.malformed - self.assembler.stats.wrong_product
        if good <= 0:
            raise NoLidarDataError(self._nothing_message(other_ports))

        cadence = statistics.median(cadence_us) if cadence_us else None
        rpm = statistics.median(rate_cdeg_per_us) * 1e6 * 60 / AZIMUTH_UNITS if rate_cdeg_per_us else None
        hint = ""
        if (
            self.model is None
            and products.get(PRODUCT_HDL32E)
            and cadence is not None
            and abs(cadence - PACKET_PERIOD_US) < 5
        ):
            hint = (
                "product byte 0x21 (HDL-32E) but a 1327 us packet cadence (VLP-16): early VLP-16 firmware; "
                'decode with --model VLP16 (or set [lidar] model = "VLP16") for the right geometry'
            )
        self.totals = {
            "file": self.path,
            "format": "pcapng" if self.reader.format == "pcapng" else "pcap",
            "revolutions": index,
            "points": self.stats.points,
            "duration_s": (last_time - first_time) if first_time is not None and last_time is not None else 0.0,
            "data_packets": self.stats.packets,
            "wrong_size": self.stats.wrong_size,
            "malformed": self.stats.malformed,
            "wrong_product": self.assembler.stats.wrong_product,
            "packets_missing": self.stats.missing,
            "out_of_order": self.stats.out_of_order,
            "senders": dict(senders),
            "other_udp_ports": dict(other_ports),
            "non_udp": self.reader.stats.not_ipv4 + self.reader.stats.not_udp,
            "fragments": self.reader.stats.fragments,
            "truncated": self.reader.stats.truncated + int(self.reader.stats.torn_tail),
            "bad_blocks": self.reader.stats.bad_blocks,
            "stopped_at": self.reader.stats.stop_reason,
            "product_ids": {f"0x{k:02X}": v for k, v in products.items()},
            "return_modes": {RETURN_MODE_NAMES.get(k, f"0x{k:02X}"): v for k, v in modes.items()},
            "model": self.model or (PRODUCT_MODELS.get(products.most_common(1)[0][0]) if products else None),
            "packet_cadence_us": cadence,
            "rpm": rpm,
            "device_minus_host_s": device_minus_host,
            "position_packets": self.stats.position_packets,
            "position_wrong_size": self.stats.position_wrong_size,
            "pps": self.stats.pps_name,
            "nmea": self.stats.nmea,
            "hint": hint,
        }

    def _revolution(self, index: int, scan: Any) -> dict[str, Any]:
        return {
            "index": index,
            "stamp": scan.stamp,
            "stamp_device": scan.stamp_device,
            "points": scan.n_points,
            "packets": scan.packets,
            "packets_missing": scan.packets_missing,
            "return_mode": scan.return_mode,
            "model": scan.model,
            "pps": self.stats.pps_name,
        }

    def _nothing_message(self, other_ports: Counter[int]) -> str:
        parts = [f"{self.path}: no VLP-16 data packets (1206-byte UDP payloads to port {self.port})"]
        if self.stats.wrong_size:
            parts.append(f"{self.stats.wrong_size} payloads of the wrong size on port {self.port}")
        if self.stats.malformed:
            parts.append(f"{self.stats.malformed} 1206-byte payloads that are not VLP-16 packets")
        if self.assembler.stats.wrong_product:
            parts.append(
                f"{self.assembler.stats.wrong_product} packets with an unknown product byte (try --model VLP16)"
            )
        if other_ports:
            ports = ", ".join(f"{p} ({n})" for p, n in other_ports.most_common(5))
            parts.append(f"UDP to other ports: {ports}")
        if self.reader.stats.udp == 0:
            parts.append(f"{self.reader.stats.records} frames, none IPv4/UDP")
        if self.reader.stats.bad_blocks:
            parts.append(f"{self.reader.stats.bad_blocks} pcapng blocks too short for their fields")
        if self.reader.stats.stop_reason:
            parts.append(f"reading stopped at a {self.reader.stats.stop_reason}")
        return "; ".join(parts)


def summarise_pcap(
    path: str | os.PathLike[str], model: str | None = None, cut_angle: float | None = None
) -> PcapSummary:
    """One dict per revolution of a VLP-16 capture; ``.totals`` after the iteration has finished.

    ``model`` None/"auto" trusts the product byte, "VLP16" forces VLP-16 geometry. ``cut_angle`` None
    uses the driver's default cut (pi, astern). Raises ``NotAPcapError`` at once for a file that is not
    a capture and ``NoLidarDataError`` (at the end of iteration) when it holds no VLP-16 data packets.
    """
    return PcapSummary(path, model=model, cut_angle=cut_angle)
