"""An autopilot endpoint that accepts the link's TCP connection and drops it at once, over and over (a bridge
restarting, a busy MAVProxy): the link keeps reconnecting, but the log says its up/down twice, not at every turn."""

from __future__ import annotations

import logging
import socket
import threading
import time

import pytest

from daemon.autopilot import AutopilotLink
from simulator.autopilot import wait_until


def dropping_server(stop: threading.Event) -> tuple[int, threading.Thread]:
    """A TCP endpoint on loopback that accepts each connection and closes it 50 ms later, until ``stop``; then it
    closes its socket and every connect is refused. Its port and its thread (started)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(50)
    server.settimeout(0.1)

    def accept_and_drop() -> None:
        while not stop.is_set():
            try:
                client, _ = server.accept()
            except OSError:
                continue
            time.sleep(0.05)
            client.close()
        server.close()

    thread = threading.Thread(target=accept_and_drop, daemon=True)
    thread.start()
    return server.getsockname()[1], thread


def port_lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    """What the link's port has logged so far."""
    return [r.getMessage() for r in caplog.records if r.name == "daemon.autopilot_port"]


def test_a_link_dropped_at_every_connect_logs_twice_and_keeps_trying(caplog: pytest.LogCaptureFixture) -> None:
    stop = threading.Event()
    port, _ = dropping_server(stop)
    link = AutopilotLink(f"tcp:127.0.0.1:{port}", reconnect_interval=0.05)
    with caplog.at_level(logging.INFO, logger="daemon.autopilot_port"):
        link.start()
        try:
            assert wait_until(lambda: link.counters.get("link_failures", 0) >= 8, 20.0)
        finally:
            link.stop()
            stop.set()
    said = port_lines(caplog)
    assert said[0] == f"autopilot link: opened tcp:127.0.0.1:{port}"
    assert said[1].startswith(f"autopilot link: link to tcp:127.0.0.1:{port} lost")
    assert len(said) == 2, said  # 8 or more opens and losses, two lines (the rest wait a minute)


def test_the_state_a_flapping_link_settles_in_is_said_after_the_quiet_time(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("daemon.autopilot_port.LINK_NOTICE_QUIET_S", 1.0)  # a minute in the daemon
    stop = threading.Event()
    port, serving = dropping_server(stop)
    link = AutopilotLink(f"tcp:127.0.0.1:{port}", reconnect_interval=0.05)
    with caplog.at_level(logging.INFO, logger="daemon.autopilot_port"):
        link.start()
        try:
            assert wait_until(lambda: link.counters.get("link_failures", 0) >= 4, 20.0)
            stop.set()  # from here every connect is refused: the link stays down
            serving.join(2.0)
            # down for good: said once the quiet time is over, with the changes it did not say
            settled = f"autopilot link: link to tcp:127.0.0.1:{port} lost"
            assert wait_until(
                lambda: any(
                    m.startswith(settled) and m.endswith("more up/down changes not logged)") for m in port_lines(caplog)
                ),
                10.0,
            )
        finally:
            link.stop()
    assert len(port_lines(caplog)) <= 2 + 2 * 12  # two a quiet second at most over the flapping and the settling
