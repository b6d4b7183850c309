"""Asking the autopilot for its pose stream: MAV_CMD_SET_MESSAGE_INTERVAL, one request at a time.

COMMAND_ACK names the command (511) but not the message the interval was for, so with several requests in
flight an ACK cannot be matched. The requests therefore go out one after another: send, wait for the ACK (or
a timeout, then resend with ``confirmation`` + 1), next. ArduPilot applies intervals per link and forgets
them at reboot, so the whole round is restarted whenever the autopilot reappears or reboots.
Pure state machine: the link feeds it the clock and the ACKs and sends what it returns.
"""

from __future__ import annotations

import logging

from daemon.mavlink_env import mavlink

log = logging.getLogger(__name__)

MAV_RESULT_IN_PROGRESS = 5

ACCEPTED = "accepted"
PENDING = "pending"
NO_ACK = "no-ack"


def _msg_name(msg_id: int) -> str:
    cls = mavlink.mavlink_map.get(msg_id)
    return cls.msgname if cls is not None else str(msg_id)


def _result_name(result: int) -> str:
    entry = mavlink.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else str(result)


class IntervalRequester:
    """Sequential SET_MESSAGE_INTERVAL requests; ``status[msg_id]`` is accepted / pending / no-ack / refused:..."""

    def __init__(self, rates_hz: dict[int, float], ack_timeout: float = 0.5, max_attempts: int = 3) -> None:
        for msg_id, hz in rates_hz.items():
            if not hz > 0:
                raise ValueError(f"rate for {_msg_name(msg_id)} must be > 0 Hz, got {hz}")
        self.rates_hz = dict(rates_hz)
        self.ack_timeout = ack_timeout
        self.max_attempts = max_attempts
        self.status: dict[int, str] = {m: PENDING for m in self.rates_hz}
        self._queue: list[int] = []
        self._pending: int | None = None
        self._sent_at = 0.0
        self._attempts = 0
        self.rounds = 0

    @property
    def busy(self) -> bool:
        return self._pending is not None or bool(self._queue)

    def restart(self) -> None:
        """Request every rate again from the start (autopilot (re)appeared or rebooted)."""
        self._queue = list(self.rates_hz)
        self._pending = None
        self.status = {m: PENDING for m in self.rates_hz}
        self.rounds += 1

    def stop(self) -> None:
        self._queue = []
        self._pending = None

    def poll(self, now: float) -> tuple[int, int, int] | None:
        """(msg_id, interval_us, confirmation) to send now, or None."""
        if self._pending is not None:
            if now - self._sent_at < self.ack_timeout:
                return None
            if self._attempts >= self.max_attempts:
                msg_id = self._pending
                self.status[msg_id] = NO_ACK
                log.warning(
                    "no COMMAND_ACK for SET_MESSAGE_INTERVAL(%s) after %d tries", _msg_name(msg_id), self._attempts
                )
                self._pending = None
            else:
                return self._send(self._pending, now)
        if not self._queue:
            return None
        self._attempts = 0
        return self._send(self._queue.pop(0), now)

    def _send(self, msg_id: int, now: float) -> tuple[int, int, int]:
        self._pending = msg_id
        self._sent_at = now
        confirmation = self._attempts
        self._attempts += 1
        return msg_id, round(1e6 / self.rates_hz[msg_id]), confirmation

    def on_ack(self, result: int) -> int | None:
        """A COMMAND_ACK for command 511: the message id it settles, or None if nothing was waiting."""
        msg_id = self._pending
        if msg_id is None or result == MAV_RESULT_IN_PROGRESS:
            return None
        self._pending = None
        if result == mavlink.MAV_RESULT_ACCEPTED:
            self.status[msg_id] = ACCEPTED
        else:
            self.status[msg_id] = f"refused:{_result_name(result)}"
            log.warning("autopilot refused SET_MESSAGE_INTERVAL(%s): %s", _msg_name(msg_id), _result_name(result))
        return msg_id
