"""The OOB demo's text CLI (UART-A, 115200 8N1): configure the radar line by line.

Protocol facts that shape this code (spec section 3): the device echoes each character, answers
``Done`` / ``Error -N`` / ``'<word>' is not recognized as a CLI command`` (with no Done after it) /
``Skipped``, and then prints the prompt ``mmwDemo:/>`` WITHOUT a newline. Sending the next line before
the prompt loses characters, so exactly one line is in flight. The first line after power-up often
arrives garbled, hence the bare-newline wake-up with retries and one retry of a line that came back
"not recognized" under a garbled name.
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType

import serial

from drivers.awr1843.errors import RadarConfigError
from drivers.awr1843.ports import describe_port, open_serial
from drivers.awr1843.profile import RadarProfile

log = logging.getLogger(__name__)

PROMPT = "mmwDemo:/>"
CLI_BAUDRATE = 115200
# These wait for the RF front end: sensorStop finishes the current frame, sensorStart runs RF calibration.
SLOW_COMMANDS = frozenset({"sensorStart", "sensorStop"})

_ERROR_CODE = re.compile(r"^Error\s+(-?\d+)\s*$")
_NOT_RECOGNIZED = re.compile(r"'(.*)' is not recognized as a CLI command")
_PROMPT_AT_END = re.compile(re.escape(PROMPT) + r"\s*$")


@dataclass(frozen=True)
class CliReply:
    """The device's answer to one line, echo and prompt removed."""

    command: str
    lines: tuple[str, ...]
    status: str  # done | ignored | skipped | empty | unclassified

    @property
    def text(self) -> str:
        return " | ".join(self.lines)


class CliSession:
    """One open CLI port. Use as a context manager, or ``open()``/``close()``."""

    def __init__(
        self,
        port: str,
        baudrate: int = CLI_BAUDRATE,
        *,
        command_timeout: float = 1.0,
        slow_command_timeout: float = 3.0,
        wake_timeout: float = 0.5,
        wake_attempts: int = 5,
    ) -> None:
        self.port = port
        self.baudrate = baudrate
        self.command_timeout = command_timeout
        self.slow_command_timeout = slow_command_timeout
        self.wake_timeout = wake_timeout
        self.wake_attempts = wake_attempts
        self._serial: serial.Serial | None = None

    def __enter__(self) -> CliSession:
        self.open()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def open(self) -> None:
        if self._serial is None:
            self._serial = open_serial(self.port, self.baudrate, role="CLI", timeout=0.05)

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            finally:
                self._serial = None

    @property
    def serial(self) -> serial.Serial:
        if self._serial is None:
            raise RuntimeError("CLI session is not open")
        return self._serial

    # ------------------------------------------------------------------ session
    def wake(self) -> None:
        """Get a prompt: send a bare newline, drain, retry (boot banners and garbage come first)."""
        received = ""
        for attempt in range(1, self.wake_attempts + 1):
            self._drain()
            self._write("\n")
            text, got_prompt = self._read_until_prompt(self.wake_timeout)
            received += text
            if got_prompt:
                log.debug("AWR1843 CLI %s: prompt after %d attempt(s)", self.port, attempt)
                return
        raise RadarConfigError(
            f"no '{PROMPT}' prompt on {describe_port(self.port)} after {self.wake_attempts} newlines: "
            "wrong port (the data port never answers), wrong baud rate, board not running the OOB demo "
            "(SOP jumpers in flashing mode?) or no power",
            reply=received[-200:],
            silent=True,
        )

    def command(self, line: str, *, line_number: int | None = None, timeout: float | None = None) -> CliReply:
        """Send one line and classify the answer; raises ``RadarConfigError`` on refusal or silence."""
        line = " ".join(line.split())
        name = line.split()[0] if line else ""
        if timeout is None:
            timeout = self.slow_command_timeout if name in SLOW_COMMANDS else self.command_timeout
        try:
            line.encode("ascii")
        except UnicodeEncodeError:
            raise RadarConfigError("line is not ASCII", line_number, line) from None
        for attempt in (1, 2):
            self._drain()
            self._write(line + "\n")
            text, got_prompt = self._read_until_prompt(timeout, expect_text=bool(line))
            lines = _reply_lines(text, line)
            if not got_prompt:
                raise RadarConfigError(
                    f"no prompt within {timeout:.1f} s on {self.port}",
                    line_number,
                    line,
                    " | ".join(lines),
                    silent=True,
                )
            for reply_line in lines:
                m = _NOT_RECOGNIZED.search(reply_line)
                if m is None:
                    continue
                if m.group(1).strip() != name:
                    if attempt == 1:
                        # the device heard something else than we sent: garbled first contact, resend once
                        log.warning("AWR1843 CLI: %r arrived garbled as %r, resending", line, m.group(1))
                        break
                    # Garbled twice is the line, not the cfg: say it can mend, so the daemon keeps retrying.
                    raise RadarConfigError(
                        "the device heard the command garbled twice (noisy line or wrong baud rate)",
                        line_number,
                        line,
                        " | ".join(lines),
                        silent=True,
                    )
                raise RadarConfigError("command not recognized by the device", line_number, line, " | ".join(lines))
            else:
                return self._classify(line, lines, line_number)
            self.wake()
        raise AssertionError("unreachable")

    def configure(
        self,
        profile: RadarProfile,
        *,
        start: bool = True,
        after_stop: Callable[[], None] | None = None,
    ) -> list[CliReply]:
        """sensorStop, flushCfg, every cfg line in order, sensorStart (appended if the cfg lacks it).

        ``after_stop`` runs once the sensor has stopped (the source drains the data port there, so that
        frames of the old configuration are not taken for new ones). With ``start=False`` the cfg's own
        ``sensorStart`` is not sent.
        """
        self.wake()
        replies = [self.command("sensorStop"), self.command("flushCfg")]
        if after_stop is not None:
            after_stop()
        for cfg_line in profile.lines:
            if cfg_line.command == "sensorStart" and not start:
                continue
            replies.append(self.command(cfg_line.text, line_number=cfg_line.number))
        if start and not profile.sends_sensor_start:
            replies.append(self.command("sensorStart"))
        log.info("AWR1843 CLI %s: %d lines of %s accepted", self.port, len(replies), profile.source)
        return replies

    def stop_sensor(self) -> CliReply:
        self.wake()
        return self.command("sensorStop")

    # ------------------------------------------------------------------ bytes
    def _write(self, text: str) -> None:
        self.serial.write(text.encode("ascii"))
        self.serial.flush()

    def _drain(self) -> None:
        """Discard whatever the device said unasked (it is logged: it may be a measurement printout)."""
        ser = self.serial
        stale = b""
        while True:
            waiting = ser.in_waiting
            if not waiting:
                break
            stale += ser.read(waiting)
        if stale.strip():
            log.debug("AWR1843 CLI %s: unsolicited %r", self.port, stale[-200:])

    def _read_until_prompt(self, timeout: float, *, expect_text: bool = False) -> tuple[str, bool]:
        """Read until the text ends with the prompt. With ``expect_text`` a bare prompt (a late answer
        to an earlier newline) does not end the reply: the answer to a command always has its echo."""
        ser = self.serial
        deadline = time.monotonic() + timeout
        chunks: list[bytes] = []
        tail = ""
        while time.monotonic() < deadline:
            chunk = ser.read(max(1, ser.in_waiting))
            if not chunk:
                continue
            chunks.append(chunk)
            tail = (tail + chunk.decode("ascii", errors="replace"))[-64:]
            if _PROMPT_AT_END.search(tail):
                text = b"".join(chunks).decode("ascii", errors="replace")
                if expect_text and not _PROMPT_AT_END.sub("", text).strip():
                    chunks, tail = [], ""
                    continue
                return text, True
        return b"".join(chunks).decode("ascii", errors="replace"), False

    def _classify(self, line: str, lines: list[str], line_number: int | None) -> CliReply:
        for reply_line in lines:
            if _ERROR_CODE.match(reply_line):
                raise RadarConfigError("device refused the line", line_number, line, " | ".join(lines))
        if "Done" in lines:
            status = "ignored" if any(r.startswith("Ignored") for r in lines) else "done"
        elif "Skipped" in lines:
            status = "skipped"
        elif not lines:
            status = "empty"
        else:
            status = "unclassified"
            log.warning("AWR1843 CLI: %r answered %r without Done; carrying on", line, lines)
        if status == "ignored":
            log.info("AWR1843 CLI: %r -> %s", line, " | ".join(lines))
        return CliReply(line, tuple(lines), status)


def _reply_lines(text: str, sent: str) -> list[str]:
    """Lines of a reply without the echo of ``sent`` and without the closing prompt."""
    text = _PROMPT_AT_END.sub("", text)
    lines = [s.strip() for s in re.split(r"[\r\n]+", text)]
    lines = [s for s in lines if s]
    if lines and sent and lines[0].endswith(sent):  # echo, possibly behind a leftover prompt
        lines = lines[1:]
    return lines
