"""Errors of the AWR1843 driver, each carrying what an operator needs to fix the problem."""

from __future__ import annotations


class RadarProfileError(ValueError):
    """A ``.cfg`` file that cannot describe a usable chirp design (names the file and line)."""

    def __init__(self, message: str, source: str = "", line_number: int | None = None, line: str = "") -> None:
        self.source = source
        self.line_number = line_number
        self.line = line
        where = source
        if line_number is not None:
            where = f"{source}:{line_number}" if source else f"line {line_number}"
        text = f"{where}: {message}" if where else message
        if line:
            text += f" (line: {line!r})"
        super().__init__(text)


class RadarConfigError(RuntimeError):
    """The device refused a configuration line, or did not answer it in time."""

    def __init__(
        self, message: str, line_number: int | None = None, line: str = "", reply: str = "", silent: bool = False
    ) -> None:
        self.line_number = line_number
        self.line = line
        self.reply = reply
        # The device gave no prompt (not powered, still booting, another port) or heard our line garbled: that can
        # mend itself; a line it answered with an error or did not know will not.
        self.silent = silent
        parts = [message]
        if line:
            where = f"cfg line {line_number}" if line_number is not None else "command"
            parts.append(f"{where}: {line!r}")
        parts.append(f"device answered: {reply!r}" if reply else "device answered nothing")
        super().__init__("; ".join(parts))


class RadarPortError(OSError):
    """A serial port that is missing, busy, or not accessible to this user."""
