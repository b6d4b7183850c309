"""`--foxglove [HOST:PORT]` and `--mcap FILE`: the command line's side of the live view.

Kept free of foxglove imports: the parser is built on every command, and a daemon run without these options must
not load the SDK at all.
"""

from __future__ import annotations

import argparse
import logging
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from daemon.view.publisher import FoxgloveView

log = logging.getLogger("usv-tracker")

DEFAULT_HOST = "127.0.0.1"  # loopback unless told otherwise: the view is not for the boat's whole network
DEFAULT_PORT = 8765  # Foxglove's own default for a WebSocket connection
INSTALL_HINT = "pip install 'usv-tracker[view]'"


class ViewError(RuntimeError):
    """The view was asked for but cannot be had (foxglove-sdk missing, port taken, file not writable)."""


def host_port(text: str) -> tuple[str, int]:
    """HOST:PORT, :PORT or PORT (host 127.0.0.1); [V6ADDR]:PORT for IPv6. Port 0 lets the system choose."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = "", text
    host = host.strip("[]") or DEFAULT_HOST
    try:
        number = int(port)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected HOST:PORT, e.g. 127.0.0.1:{DEFAULT_PORT}, got {text!r} (a bare --foxglove goes after any "
            "positional argument such as the recording)"
        ) from None
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"port out of range: {number}")
    return host, number


def add_view_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--foxglove",
        nargs="?",
        const=(DEFAULT_HOST, DEFAULT_PORT),
        type=host_port,
        metavar="HOST:PORT",
        help=f"serve a live view over the Foxglove WebSocket protocol (default {DEFAULT_HOST}:{DEFAULT_PORT}; "
        "0.0.0.0:PORT to reach it from another machine); needs " + INSTALL_HINT,
    )
    p.add_argument(
        "--mcap",
        metavar="FILE",
        help="write the same view to this MCAP file (replaced if it exists), for Foxglove to open; needs "
        + INSTALL_HINT,
    )


def open_view(args: argparse.Namespace) -> FoxgloveView | None:
    """The view the options ask for, or None; ViewError says why it cannot be had."""
    address = getattr(args, "foxglove", None)
    mcap = getattr(args, "mcap", None)
    if address is None and mcap is None:
        return None
    try:
        from daemon.view.publisher import FoxgloveView
    except ImportError as exc:
        raise ViewError(
            f"--foxglove/--mcap need foxglove-sdk, which is not installed ({exc}): {INSTALL_HINT}"
        ) from None
    host, port = address if address is not None else (None, None)
    try:
        view = FoxgloveView(host, port, mcap)
    except Exception as exc:  # the SDK raises its own error types for a taken port or an unwritable file
        where = " and ".join(
            s for s in (f"ws://{host}:{port}" if host is not None else "", f"MCAP {mcap}" if mcap else "") if s
        )
        raise ViewError(f"cannot open the view ({where}): {exc}") from None
    if view.server is not None:
        log.info("foxglove view: ws://%s:%d (Foxglove: Open connection -> Foxglove WebSocket)", host, view.port or port)
    if mcap:
        log.info("foxglove view: writing %s", mcap)
    return view
