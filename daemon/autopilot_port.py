"""One pymavlink connection that survives the autopilot going away: open, read, write, reopen.

Owned by one reader thread (``service_open``, ``read``); any thread may ``send`` (one lock around the
pymavlink writer, whose sequence number and signing timestamp are not thread-safe). Failures never raise
out of here: they are counted, logged once per state change, and the port is reopened after
``reconnect_interval``. Opening runs in a short-lived helper thread, because a TCP connect to a dead host or
a serial open can block for far longer than the daemon's ``stop()`` may take.

pymavlink reports a closed TCP stream only by printing; here a socket that select() calls readable but that
yields no byte is treated as closed (``tcp:``: reopen; ``tcpin:``: drop the client and listen again).
"""

from __future__ import annotations

import logging
import struct
import threading
from collections.abc import Callable
from typing import Any

from daemon.autopilot_url import parse_autopilot_url
from daemon.change_notices import ChangeNotices
from daemon.mavlink_env import mavlink, mavutil, open_connection

log = logging.getLogger(__name__)

# ArduPilot accepts these unsigned even with signing on (a SiK radio cannot sign)
_UNSIGNED_OK = frozenset({mavlink.MAVLINK_MSG_ID_RADIO_STATUS, 166})  # 166 = RADIO
# An endpoint that connects and drops in a loop: its up/down said twice a minute at most, then what it settled in.
LINK_NOTICE_QUIET_S = 60.0
LINK_NOTICE_BURST = 2
MAX_MESSAGES_PER_READ = 1000  # bounded so the owner's periodic duties still run under a flood
# pymavlink keeps the last message of every type it has seen, per system. A message id outside the dialect carries
# no CRC it can check, so line noise makes up a new 'UNKNOWN_<id>' type (24-bit ids) every few bytes: unchecked,
# that table grows for as long as the noise lasts. The dialect has ~300 types; beyond this many, the made-up go.
MAX_REMEMBERED_TYPES = 1024

__all__ = ["MAX_MESSAGES_PER_READ", "MavlinkPort", "parse_autopilot_url"]


def _forget_made_up_types(conn: Any) -> None:
    """Keep pymavlink's table of last messages per type bounded (see MAX_REMEMBERED_TYPES); we never read it."""
    for state in getattr(conn, "sysid_state", {}).values():
        messages = state.messages
        if len(messages) > MAX_REMEMBERED_TYPES:
            for name in [k for k in messages if k.startswith("UNKNOWN_")]:
                del messages[name]
            if len(messages) > MAX_REMEMBERED_TYPES:  # instance-keyed copies of real types: start afresh
                messages.clear()


def _allow_unsigned(_mav: Any, msg_id: int) -> bool:
    return msg_id in _UNSIGNED_OK


def _close_quietly(conn: Any) -> None:
    try:
        conn.close()
    except Exception as exc:  # closing a port that already died
        log.debug("closing autopilot connection: %s", exc)


class MavlinkPort:
    """A self-reopening pymavlink connection; see the module docstring."""

    def __init__(
        self,
        url: str,
        baud: int,
        system_id: int,
        component_id: int,
        signing_key: bytes | None,
        reconnect_interval: float,
        clock: Callable[[], float],
        count: Callable[[str], None],
    ) -> None:
        self.url = url
        self.device, self.baud = parse_autopilot_url(url, baud)
        self.system_id = system_id
        self.component_id = component_id
        self.signing_key = signing_key
        self.reconnect_interval = reconnect_interval
        self.clock = clock
        self._count = count
        self._tx_lock = threading.Lock()
        self._conn: Any = None  # pymavlink mavfile; replaced only by the owner thread, under _tx_lock
        self._tx_failed = False
        self._unpackable: set[str] = set()  # messages said once not to pack
        self._state = "closed"
        self._state_message = ""
        self._notices = ChangeNotices(quiet_s=LINK_NOTICE_QUIET_S, burst=LINK_NOTICE_BURST)
        self._notices.start("open", False)
        self._closing = False
        self._opener: threading.Thread | None = None
        self._opened: list[Any] = []  # the opener's result slot: [conn] or [exception]
        self._next_open = 0.0
        self._signing_timestamp = 0

    @property
    def is_open(self) -> bool:
        return self._conn is not None

    # ------------------------------------------------------------------ owner thread
    def service_open(self) -> bool:
        """Start or collect a pending open; True when the port has just been (re)opened."""
        self._say_state()  # a state left unsaid by the rate limit, once its quiet time is over
        if self._opener is not None:
            if self._opener.is_alive():
                return False
            self._opener = None
            result = self._opened.pop() if self._opened else OSError("opener returned nothing")
            if isinstance(result, Exception):
                self._count("link_open_failures")
                self._set_state("failed", f"cannot open {self.url}: {result}")
                self._next_open = self.clock() + self.reconnect_interval
                return False
            with self._tx_lock:
                self._conn = result
                self._tx_failed = False
            self._count("link_opens")
            self._set_state("open", f"opened {self.url}")
            return True
        if self.clock() >= self._next_open:
            self._closing = False
            self._opened = []
            self._opener = threading.Thread(target=self._open, args=(self._opened,), name="autopilot-open", daemon=True)
            self._opener.start()
        return False

    def _open(self, slot: list[Any]) -> None:
        """Helper thread. A result nobody will collect (``close()`` came first) is closed here."""
        try:
            conn = open_connection(
                self.device, baud=self.baud, source_system=self.system_id, source_component=self.component_id
            )
            if self.signing_key is not None:
                conn.setup_signing(self.signing_key, sign_outgoing=True, allow_unsigned_callback=_allow_unsigned)
                # per-stream timestamps must grow across reopen, or the autopilot takes us for a replay
                conn.mav.signing.timestamp = max(conn.mav.signing.timestamp, self._signing_timestamp + 1)
        except Exception as exc:
            slot.append(exc)
            return
        slot.append(conn)
        if self._closing:
            _close_quietly(conn)

    def read(self, handle: Callable[[Any], None], timeout: float) -> bool:
        """Wait up to ``timeout`` for data and pass every parsed message to ``handle``; False if the port
        failed (it is then closed and will be reopened by ``service_open``)."""
        conn = self._conn
        self._say_state()  # a state left unsaid by the rate limit, once its quiet time is over
        if conn is None:
            return False
        try:
            self._read(conn, handle, timeout)
            if self._tx_failed or getattr(conn, "portdead", False):
                raise OSError("port reported dead on write")
        except Exception as exc:  # OSError, SerialException, select on a closed fd...
            self._count("link_failures")
            self._close_conn()
            self._set_state("failed", f"link to {self.url} lost: {exc}")
            self._next_open = self.clock() + self.reconnect_interval
            return False
        return True

    def _read(self, conn: Any, handle: Callable[[Any], None], timeout: float) -> None:
        readable = conn.select(timeout)
        before = conn.mav.total_bytes_received
        client_before = conn.port if isinstance(conn, mavutil.mavtcpin) else None
        for _ in range(MAX_MESSAGES_PER_READ):
            msg = conn.recv_msg()
            if msg is None:
                break
            handle(msg)
        _forget_made_up_types(conn)
        if not readable or conn.mav.total_bytes_received != before:
            return
        if isinstance(conn, mavutil.mavtcp):
            raise OSError("TCP connection closed by the autopilot side")
        if client_before is not None and conn.port is client_before:
            client_before.close()
            conn.port = None
            conn.fd = conn.listen.fileno()
            self._count("tcp_client_disconnects")

    # ------------------------------------------------------------------ any thread
    def send(self, what: str, fn: Callable[[Any], None]) -> bool:
        """Run ``fn(mav)`` under the writer lock; False (counted, never raised) when the link is down."""
        with self._tx_lock:
            conn = self._conn
            if conn is None:
                failed = True
                self._count("tx_dropped_no_link")
            else:
                try:
                    fn(conn.mav)
                    failed = bool(getattr(conn, "portdead", False))
                except (struct.error, OverflowError) as exc:
                    # a field out of its range: the message is wrong, not the port (closing it for this would drop
                    # the link every time the message is tried)
                    self._count(f"tx_unpackable_{what}")
                    if what not in self._unpackable:
                        self._unpackable.add(what)
                        log.error("autopilot link: %s cannot be packed (%s); not sent", what, exc)
                    return False
                except Exception as exc:  # a dying port raises anything from OSError to SerialException
                    failed = True
                    if not self._tx_failed:
                        log.warning("autopilot link: send of %s failed: %s", what, exc)
                if failed and conn is not None:
                    self._tx_failed = True
                    self._count("tx_errors")
        if not failed:
            self._count(f"tx_{what}")
        return not failed

    def close(self) -> None:
        """Close the connection and any connection still being opened."""
        self._closing = True
        self._close_conn()
        opener = self._opener
        if opener is not None:
            opener.join(0.1)  # usually done; a connect still hanging closes its own result (_closing)
        if opener is not None and not opener.is_alive():
            self._opener = None
            if self._opened and not isinstance(self._opened[-1], Exception):
                _close_quietly(self._opened.pop())
        self._state = "closed"

    def _close_conn(self) -> None:
        with self._tx_lock:
            conn, self._conn = self._conn, None
            if conn is not None and self.signing_key is not None:
                self._signing_timestamp = max(self._signing_timestamp, conn.mav.signing.timestamp)
        if conn is not None:
            _close_quietly(conn)

    def _set_state(self, state: str, message: str) -> None:
        if state == self._state:
            log.debug("autopilot link: %s", message)
            return
        flip = (state == "open") != (self._state == "open")
        self._state, self._state_message = state, message
        if not flip:  # closed -> failed: the first word on a link that never opened
            log.warning("autopilot link: %s", message)
            return
        self._say_state()

    def _say_state(self) -> None:
        """The link's up/down, said at most LINK_NOTICE_BURST times a LINK_NOTICE_QUIET_S: an endpoint that accepts
        and drops at once would log two lines a reconnect (170,000 a day at the 1 s default). The state it settles
        in is said once the quiet time is over, with the count of changes left unsaid."""
        up = self._state == "open"
        unsaid = self._notices.note("open", up, self.clock())
        if unsaid is None:
            return
        more = f" ({unsaid} more up/down changes not logged)" if unsaid else ""
        (log.info if up else log.warning)("autopilot link: %s%s", self._state_message, more)
