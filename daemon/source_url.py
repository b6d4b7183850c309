"""Sensor sources named like URLs (after pyserial's serial_for_url): one string picks hardware, capture or simulator.

udp://0.0.0.0:2368            VLP-16 live          pcap://run.pcap          VLP-16 replay
serial:///dev/ttyACM1?baud=921600   radar port     file://run.dat           radar data-port dump replay

The simulator is not a source: `usv-tracker demo` (or `simulate --write DIR`, then `replay DIR`) runs the daemon
against it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from urllib.parse import parse_qsl, urlsplit

SCHEMES = {"udp", "pcap", "serial", "file"}


class SourceUrlError(ValueError):
    pass


@dataclass(frozen=True)
class SourceUrl:
    scheme: str
    host: str = ""
    port: int | None = None
    path: str = ""
    params: dict[str, str] = field(default_factory=dict)
    text: str = ""

    def __str__(self) -> str:
        return self.text


def parse_source_url(text: str, allowed: set[str] | None = None) -> SourceUrl:
    """Parse and check a source URL; the error says what was expected."""
    allowed = allowed or SCHEMES
    expected = ", ".join(f"{s}://" for s in sorted(allowed))
    if "://" not in text:
        raise SourceUrlError(f"'{text}' is not a source URL (expected one of {expected})")
    try:
        parts = urlsplit(text)
    except ValueError as exc:  # an unclosed '[' of an IPv6 address, for one
        raise SourceUrlError(f"'{text}': not a valid URL ({exc})") from None
    scheme = parts.scheme.lower()
    if scheme == "sim":
        raise SourceUrlError(
            f"'{text}': the simulator is not a sensor source; `usv-tracker demo --scene NAME` runs the daemon against"
            " it (or `usv-tracker simulate --scene NAME --write DIR`, then `usv-tracker replay DIR`)"
        )
    if scheme not in allowed:
        raise SourceUrlError(f"'{text}': scheme '{scheme}://' is not usable here (expected one of {expected})")
    params = dict(parse_qsl(parts.query))
    if scheme == "udp":
        try:
            port = parts.port
        except ValueError as exc:
            raise SourceUrlError(f"'{text}': bad port ({exc})") from None
        if port is None:
            raise SourceUrlError(f"'{text}': a UDP source needs a port, e.g. udp://0.0.0.0:2368")
        return SourceUrl(scheme, parts.hostname or "0.0.0.0", port, "", params, text)
    # pcap://, file://, serial://: everything after the scheme is a path (relative or absolute)
    path = parts.netloc + parts.path
    if not path:
        raise SourceUrlError(f"'{text}': no path given")
    if scheme == "serial" and "baud" in params:
        baud = params["baud"]
        if not (baud.isascii() and baud.isdigit() and len(baud) <= 10 and int(baud) > 0):
            raise SourceUrlError(f"'{text}': baud '{baud}' is not a positive whole number, e.g. ?baud=921600")
    return SourceUrl(scheme, "", None, path, params, text)
