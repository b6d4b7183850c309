"""Opening the radar's serial ports with errors that say what to do about them."""

from __future__ import annotations

import errno
import glob
import logging
import os

import serial

from drivers.awr1843.errors import RadarPortError

log = logging.getLogger(__name__)

_MISSING = {errno.ENOENT, errno.ENODEV, errno.ENXIO}
_DENIED = {errno.EACCES, errno.EPERM}
_BUSY = {errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK}


def describe_port(path: str) -> str:
    """``/dev/serial/by-id/...`` names are stable; the ttyACM they point to is what the kernel logs name."""
    if not path:
        return "(none)"
    try:
        real = os.path.realpath(path)
    except OSError:  # a by-id link removed between its lstat and readlink: the cable was pulled just then
        return f"{path} (gone)"
    return path if real == path else f"{path} -> {real}"


def open_serial(path: str, baudrate: int, *, role: str, timeout: float = 0.05) -> serial.Serial:
    """Open ``path`` 8N1 without flow control, exclusively (a second reader would steal bytes)."""
    try:
        port = serial.Serial(port=path, baudrate=baudrate, timeout=timeout, write_timeout=2.0, exclusive=True)
    except serial.SerialException as exc:
        raise port_error(path, role, exc) from exc
    except OSError as exc:  # some platforms raise the bare OSError
        raise port_error(path, role, exc) from exc
    log.info("AWR1843 %s port %s open at %d baud", role, describe_port(path), baudrate)
    return port


def port_error(path: str, role: str, exc: OSError) -> RadarPortError:
    """Turn an open() failure into an operator-facing message naming the port and its role."""
    code = exc.errno
    name = f"AWR1843 {role} port {describe_port(path)}"
    if code in _MISSING or (code is None and not os.path.exists(path)):
        present = sorted(glob.glob("/dev/serial/by-id/*")) or sorted(
            glob.glob("/dev/ttyACM*") + glob.glob("/dev/ttyUSB*")
        )
        hint = f"present: {', '.join(present)}" if present else "no serial devices present: is the board plugged in?"
        return RadarPortError(code or errno.ENOENT, f"{name} does not exist ({hint})", path)
    if code in _DENIED:
        return RadarPortError(
            code,
            f"{name}: permission denied; add the service user to the 'dialout' group "
            "(sudo usermod -aG dialout USER, then log in again)",
            path,
        )
    if code in _BUSY:
        return RadarPortError(
            code,
            f"{name} is busy: another program has it open (mmWave Visualizer, minicom, screen, "
            "ModemManager: stop it or mark the device ID_MM_DEVICE_IGNORE in udev)",
            path,
        )
    return RadarPortError(code or errno.EIO, f"{name}: {exc}", path)
