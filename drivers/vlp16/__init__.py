"""Velodyne VLP-16 driver: UDP/pcap packets -> one body-frame ``LidarScan`` per revolution.

packet.py      packet layout, header checks, encoder (simulator, tests) and position-packet decoder
pcap.py        pcap/pcapng reader and classic-pcap writer
decoder.py     ScanAssembler: packets -> revolutions via velodyne-decoder, clocks, frame conversion
udp_source.py  live UDP source          pcap_source.py  capture replay (same interface)
inspect.py     per-revolution summary of a capture (``usv-tracker decode``)
"""

from __future__ import annotations
