"""``summarise_pcap`` (behind ``usv-tracker decode FILE``): per-revolution dicts and the file summary."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from drivers.vlp16.inspect import NoLidarDataError, summarise_pcap
from drivers.vlp16.packet import encode_position_packet
from drivers.vlp16.pcap import NotAPcapError, PcapWriter
from tests.conftest import OWN_FIXTURES
from tests.test_vlp16_decoder import sweep


def test_early_firmware_capture_summary_and_hint(shared_fixtures: Path) -> None:
    path = shared_fixtures / "vlp16" / "veloview_vlp-16-test-90deg-1-50-frames.pcap"
    summary = summarise_pcap(path)
    revolutions = list(summary)
    assert len(revolutions) == 51
    first = revolutions[0]
    assert set(first) >= {"index", "stamp", "points", "packets", "packets_missing", "return_mode", "model", "pps"}
    assert (first["index"], first["packets"], first["packets_missing"]) == (0, 35, 0)
    assert (first["return_mode"], first["model"], first["pps"]) == ("strongest", "HDL32E", "absent")
    t = summary.totals
    assert t is not None
    assert (t["revolutions"], t["points"], t["data_packets"], t["position_packets"]) == (51, 700_400, 1902, 367)
    assert (t["product_ids"], t["packet_cadence_us"], t["pps"]) == ({"0x21": 1902}, 1327, "absent")
    assert t["rpm"] == pytest.approx(1200, abs=5)
    assert t["device_minus_host_s"] == pytest.approx(-1430.58, abs=0.01)
    assert "early VLP-16 firmware" in t["hint"]
    # Forced to VLP-16: no hint, VLP-16 geometry.
    forced = summarise_pcap(path, model="VLP16")
    assert [r["model"] for r in forced][:1] == ["VLP16"]
    assert forced.totals is not None and forced.totals["hint"] == "" and forced.totals["model"] == "VLP16"


def test_cut_angle_and_counts(shared_fixtures: Path) -> None:
    path = shared_fixtures / "vlp16" / "rlu_velodyne_example.pcap"
    assert [r["points"] for r in summarise_pcap(path)] == [24_144, 7_486]  # default cut: astern
    assert [r["points"] for r in summarise_pcap(path, cut_angle=0.0)] == [9_895, 21_735]
    summary = summarise_pcap(path, cut_angle=math.pi / 2)
    assert sum(r["points"] for r in summary) == 31_630


def test_synthetic_pcapng_summary_counts_the_clutter() -> None:
    summary = summarise_pcap(OWN_FIXTURES / "vlp16_synthetic.pcapng", model="VLP16")
    (revolution,) = list(summary)
    assert revolution["points"] == len(sweep(8).device_time)
    assert revolution["pps"] == "locked"
    t = summary.totals
    assert t is not None
    assert (t["format"], t["data_packets"], t["wrong_size"], t["fragments"], t["non_udp"]) == ("pcapng", 8, 1, 1, 2)
    assert t["other_udp_ports"] == {9999: 1}
    assert t["senders"] == {"192.168.1.201": 8}
    assert t["nmea"].startswith("$GPRMC") and t["device_minus_host_s"] == pytest.approx(-0.25, abs=1e-6)


def test_not_a_capture_and_no_lidar_data(tmp_path: Path) -> None:
    text = tmp_path / "config.toml"
    text.write_text("[lidar]\n")
    with pytest.raises(NotAPcapError, match="not a pcap"):
        summarise_pcap(text)
    # A capture with only position packets, a radar on 7502 and a short datagram on 2368.
    path = tmp_path / "no_data.pcap"
    with PcapWriter(path) as w:
        w.write_udp(1.0, encode_position_packet(1000), dst_port=8308, src_port=8308)
        w.write_udp(1.1, b"\x02\x01" * 20, dst_port=7502, src_port=7502)
        w.write_udp(1.2, b"\0" * 100, dst_port=2368)
    with pytest.raises(NoLidarDataError, match=r"no VLP-16 data packets.*1 payloads of the wrong size.*7502 \(1\)"):
        list(summarise_pcap(path))
