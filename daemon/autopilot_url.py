"""The autopilot connection string: pymavlink's own forms and ``serial://PATH?baud=N``, checked without pymavlink.

Kept apart from the link itself so that ``check-config`` can name a bad string without loading pymavlink.
"""

from __future__ import annotations

_LOG_SUFFIXES = (".tlog", ".bin", ".log", ".mavlink", ".raw", ".px4log")
_STREAM_SCHEMES = ("udpin:", "udpout:", "udp:", "udpbcast:", "tcp:", "tcpin:")


def _decimal(text: str) -> bool:
    # str.isdigit() also accepts digits such as '²' that int() refuses; 4301 digits make int() itself refuse
    return text.isascii() and text.isdigit() and len(text) <= 10


def _baud(url: str, text: str) -> int:
    if not _decimal(text) or int(text) <= 0:
        raise ValueError(f"'{url}': baud '{text}' is not a positive whole number")
    return int(text)


def parse_autopilot_url(url: str, baud: int) -> tuple[str, int]:
    """(pymavlink device string, baud). Accepts pymavlink's own forms and ``serial://PATH?baud=N``.

    pymavlink strings: ``udpin:HOST:PORT``, ``udpout:HOST:PORT``, ``udp:``, ``udpbcast:``, ``tcp:HOST:PORT``,
    ``tcpin:HOST:PORT``, a serial device path (``/dev/ttyAMA0``, optionally ``/dev/ttyAMA0,921600``).
    """
    url = url.strip()
    if not url:
        raise ValueError("empty autopilot URL")
    if url.lower().endswith(_LOG_SUFFIXES):
        raise ValueError(f"'{url}' is a log file: replay it through the replay source, not a live link")
    if url.startswith("serial://"):
        path, _, query = url[len("serial://") :].partition("?")
        for item in filter(None, query.split("&")):
            key, _, value = item.partition("=")
            if key == "baud":
                baud = _baud(url, value)
        if not path:
            raise ValueError(f"'{url}': no device path")
        return path, baud
    if url.startswith(_STREAM_SCHEMES):
        host, sep, port = url.split(":", 1)[1].rpartition(":")
        if not sep or not host or not _decimal(port) or not 0 < int(port) < 65536:
            raise ValueError(f"'{url}': expected SCHEME:HOST:PORT, e.g. udpout:127.0.0.1:14550")
        return url, baud
    if url.startswith("/"):
        path, sep, b = url.rpartition(",")
        if sep:
            return path, _baud(url, b)
        return url, baud
    raise ValueError(
        f"'{url}' is not an autopilot connection (udpin:/udpout:/tcp:/tcpin:HOST:PORT, a serial path, "
        "or serial://PATH?baud=N)"
    )
