"""The one place that loads pymavlink: MAVLink 2, dialect ardupilotmega, for every module of the project.

pymavlink picks its wire protocol from the MAVLINK20 environment variable at the moment the dialect module is
loaded; without it the v1 module is used and messages with ids > 255 (OBSTACLE_DISTANCE 330,
OBSTACLE_DISTANCE_3D 11037) cannot even be built. So every module that talks MAVLink imports ``mavutil`` and
``mavlink`` from here instead of from pymavlink directly. The dialect is a process-wide global in pymavlink:
nobody may pass another ``dialect=`` to ``mavlink_connection``.
"""

from __future__ import annotations

import hashlib
import os

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # must come after MAVLINK20 is set

DIALECT = "ardupilotmega"

# set_dialect re-reads MAVLINK20, so this also repairs the case where somebody imported mavutil first.
mavutil.set_dialect(DIALECT)
mavlink = mavutil.mavlink

if mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # pragma: no cover - only if pymavlink changes its rules
    raise ImportError(f"pymavlink loaded MAVLink {mavlink.WIRE_PROTOCOL_VERSION}, MAVLink 2 is required")


def signing_key_from_passphrase(passphrase: str) -> bytes:
    """32-byte MAVLink 2 signing key, MAVProxy's convention (SHA-256 of the passphrase's UTF-8 bytes)."""
    if not passphrase:
        raise ValueError("empty signing passphrase")
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


def open_connection(
    url: str, *, baud: int, source_system: int, source_component: int, autoreconnect: bool = False
) -> mavutil.mavfile:
    """pymavlink connection for ``url`` with the project's dialect; raises what pymavlink raises."""
    return mavutil.mavlink_connection(
        url,
        baud=baud,
        source_system=source_system,
        source_component=source_component,
        autoreconnect=autoreconnect,
        retries=0,  # tcp: one connect attempt; our own loop retries without blocking stop()
    )
