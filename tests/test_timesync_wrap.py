"""time_boot_ms is a uint32 of milliseconds: it wraps after 49.7 days up, while TIMESYNC's clock (64-bit ns) runs on.
Taken for a reboot, each wrap restarted the world frame, and every message after it again: the own pose was lost
for good on an autopilot up that long."""

from __future__ import annotations

import itertools

import pytest

from daemon.timesync import BOOT_MS_WRAP, NS_PER_MS, NS_PER_S, TimeSync


def _synced(boot_ms_at_50s: int) -> TimeSync:
    """Synced to an autopilot whose boot clock reads ``boot_ms_at_50s`` (unwrapped) at host time 50 s."""
    ts = TimeSync(min_samples=1)
    rx = 50 * NS_PER_S
    _tc1, ts1 = ts.make_request(rx - 200_000)
    assert ts.on_reply(boot_ms_at_50s * NS_PER_MS - 100_000, ts1, rx)  # the autopilot stamped it mid-way
    return ts


def test_a_wrap_of_the_boot_time_is_no_reboot_and_the_stamps_run_on() -> None:
    ts = _synced(BOOT_MS_WRAP - 4_000)
    hosts = []
    for k in range(400):  # 8 s at 50 Hz across the wrap, 4 s after the sync
        unwrapped = BOOT_MS_WRAP - 4_000 + 20 * k
        rx = 50 * NS_PER_S + 20 * k * NS_PER_MS + 300_000
        assert not ts.check_boot_time(unwrapped % BOOT_MS_WRAP, rx)
        hosts.append(ts.to_host_ns(unwrapped % BOOT_MS_WRAP, rx))
    assert ts.resets == 0 and ts.synced
    steps = {b - a for a, b in itertools.pairwise(hosts)}
    assert steps == {20 * NS_PER_MS}  # one clock throughout, the wrap included
    assert ts.check_boot_time(1_500, 60 * NS_PER_S)  # a reboot after it is still one
    assert "reboot" in ts.last_reset_reason or "off" in ts.last_reset_reason


def test_an_autopilot_up_for_sixty_days_syncs_without_resets() -> None:
    up_ms = 60 * 86_400_000  # past one wrap: its messages carry up_ms - 2**32
    ts = _synced(up_ms)
    for k in range(100):
        assert not ts.check_boot_time((up_ms + 20 * k) % BOOT_MS_WRAP, 50 * NS_PER_S + 20 * k * NS_PER_MS)
    assert ts.resets == 0
    assert ts.to_host((up_ms + 1_000) % BOOT_MS_WRAP, 51.0) == pytest.approx(51.0, abs=1e-3)


def test_a_wrap_before_the_clocks_are_synced_is_counted_on() -> None:
    ts = TimeSync(min_samples=1)
    for k in range(100):
        unwrapped = BOOT_MS_WRAP - 1_000 + 20 * k
        assert not ts.check_boot_time(unwrapped % BOOT_MS_WRAP, (10 + 0.02 * k) * NS_PER_S)
    assert ts.resets == 0
    # the last message read 980 ms past the wrap; one reading 100 ms fell back within the new range: a reboot
    assert ts.check_boot_time(100, 20 * NS_PER_S)
