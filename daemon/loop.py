"""The fixed-rate 10 Hz loop: take what the readers delivered, run the pipeline, publish, feed the watchdog.

Live, the loop ticks on time.monotonic() and sleeps to the next deadline (deadlines are absolute, so a slow tick
does not shift the phase of all later ones). Replay with --fast ticks on the data's own clock and never sleeps, so
the same capture always gives the same output, as fast as the CPU allows.
"""

from __future__ import annotations

import gc
import json
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO, Any, Protocol

import numpy as np

from daemon.ais import MMSI_BASE, ais_vessel
from daemon.buffers import BoundedQueue, LatestSlot
from daemon.change_notices import ChangeNotices
from daemon.health import CycleStats, RateCounter
from daemon.heap import release_free_memory
from daemon.sdnotify import SystemdNotifier
from drivers.frames import EgoPose, LidarScan, RadarFrame
from tracker.pipeline import EgoSource, PerceptionOutput, PerceptionPipeline

log = logging.getLogger(__name__)

MAV_DISTANCE_SENSOR_LASER = 0
MAV_STATE_ACTIVE = 4
MAV_STATE_CRITICAL = 5  # degraded: one of the expected sensors is down
MAV_STATE_EMERGENCY = 6  # no sensor at all: no obstacle output
PHASE_GAIN = 0.2  # share of the LiDAR phase error corrected per tick (run_live)
PHASE_MAX_STEP_S = 0.005  # s, the most one tick moves the next
MAX_FAILED_TICKS = 20  # cycles failing in a row (2 s) before the loop gives up and lets systemd restart it
STARTUP_GRACE_S = 3.0  # a sensor not heard from yet is only reported silent after this
# Up/down notices of one sensor (or of the feed): two within this many seconds, then the changes are counted and
# said when the next one may go (daemon.change_notices). A flapping link said each of its 14 changes in 10 s.
STATE_NOTICE_QUIET_S = 10.0
_DATA = "sensor data"
# The notices of the array withheld while the radar alone delivers without the own pose (radar_unplaced).
_PLACED = "radar placed"
MAV_SEVERITY_WARNING = 4
MAV_SEVERITY_INFO = 6


class ObstaclePublisher(Protocol):
    """The autopilot side as the loop sees it (daemon.autopilot.AutopilotLink provides it)."""

    def send_obstacle_distance(
        self, distances_cm: np.ndarray, min_cm: int, max_cm: int, sensor_type: int, time_usec: int | None
    ) -> None: ...

    def send_statustext(self, severity: int, text: str) -> None: ...

    def set_system_status(self, status: int) -> None: ...


@dataclass
class LoopSettings:
    rate_hz: float = 10.0
    min_distance_m: float = 0.5
    max_distance_m: float = 100.0
    no_data_timeout_s: float = 0.5
    health_interval_s: float = 5.0
    lidar_expected: bool = True
    radar_expected: bool = True
    ais_interval_s: float = 0.0  # AIS_VESSEL per confirmed track this often; 0 = never (daemon.ais)
    ais_max_tracks: int = 10
    ais_mmsi_base: int = MMSI_BASE
    # Live, the obstacle array must be ready this long after a tick starts: a tracker that would not fit is skipped
    # for that cycle (tracking degrades, the obstacles do not). 0 = never skip. Replays never skip.
    cycle_budget_s: float = 0.07


@dataclass
class SensorInputs:
    """What the readers fill; the loop only ever takes from these, never reads a device itself."""

    lidar: LatestSlot[LidarScan] = field(default_factory=LatestSlot)
    radar: BoundedQueue[RadarFrame] = field(default_factory=BoundedQueue)


class DaemonLoop:
    def __init__(
        self,
        pipeline: PerceptionPipeline,
        inputs: SensorInputs,
        publisher: ObstaclePublisher | None,
        poses: EgoSource | None,
        settings: LoopSettings,
        notifier: SystemdNotifier | None = None,
        tracks_out: IO[str] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.pipeline = pipeline
        self.inputs = inputs
        self.publisher = publisher
        self.poses = poses
        self.s = settings
        self.notifier = notifier or SystemdNotifier("")
        self.tracks_out = tracks_out
        self.tracks_out_failed: str | None = None  # why the tracks file stopped being written, once it has
        self.clock = clock
        self.stats = CycleStats(period_s=1.0 / settings.rate_hz)
        self.sent = 0
        self.withheld = 0
        self.unplaced = 0  # of the withheld ticks, those whose radar alone delivered without the own pose (_PLACED)
        self.ais_sent = 0
        self.failed_ticks = 0
        self._failed_in_a_row = 0
        self.degraded_ticks = 0  # ticks that skipped a tracker to keep the obstacle array on time
        self._degraded_logged = -math.inf
        self._last_ais = -math.inf
        self._publishing: bool | None = None
        self._waiting_for_first_data = False  # no data since start-up, within STARTUP_GRACE_S so far
        self._sensor_state: dict[str, bool] = {}
        self._notices = ChangeNotices(STATE_NOTICE_QUIET_S)
        self._status: int | None = None
        self._first_tick: float | None = None
        self._last_health = -math.inf
        self._rates = {"lidar": RateCounter(), "radar": RateCounter(), "sent": RateCounter()}
        self.last_output: PerceptionOutput | None = None
        self.on_output: Callable[[PerceptionOutput], None] | None = None
        self.status_text: Callable[[], str] | None = None
        # Called once a tick with its time: STATUSTEXT (severity, text) the sources have news for (source_alerts.py).
        self.alerts: Callable[[float], list[tuple[int, str]]] | None = None
        # World NED -> (lat, lon, alt) or None; a replay with the recording's poses sets it, live uses the publisher's.
        self.world_to_geodetic: Callable[[np.ndarray], tuple[Any, Any, Any] | None] | None = None
        # Once per health interval, after the health line: the C heap's free pages back to the system (daemon.heap).
        self.release_memory: Callable[[], object] | None = release_free_memory
        self._collected_resets = 0  # pipeline.world_resets at the last collect_old_world

    # ---- one cycle -------------------------------------------------------------------------------------------
    def tick(self, t: float, deadline: float | None = None) -> PerceptionOutput:
        """One cycle at time ``t``; ``deadline`` (time.perf_counter()) is when the obstacle array must be ready."""
        t0 = time.perf_counter()
        scan = self.inputs.lidar.take()
        frames = self.inputs.radar.take_all()
        out = self.pipeline.step(t, scan, frames, self.poses, deadline=deadline)
        if out.tracking_skipped:
            self._on_degraded(t, out.tracking_skipped)
        t_pub = time.perf_counter()
        self._publish(out)
        if self.alerts is not None:
            for severity, text in self.alerts(t):
                self._statustext(severity, text)
        stages = dict(out.timings_ms)
        stages["publish"] = (time.perf_counter() - t_pub) * 1e3
        self.stats.record((time.perf_counter() - t0) * 1e3, stages)
        self.last_output = out
        if self.on_output is not None:
            self.on_output(out)
        return out

    def _on_degraded(self, t: float, skipped: tuple[str, ...]) -> None:
        self.degraded_ticks += 1
        if t - self._degraded_logged >= 60.0:
            self._degraded_logged = t
            log.warning(
                "cycle over its %.0f ms budget: %s tracking skipped to send the obstacles on time (%d cycles so far; "
                "the machine is overloaded or the scene is extreme)",
                self.s.cycle_budget_s * 1e3,
                " and ".join(skipped),
                self.degraded_ticks,
            )

    def _publish(self, out: PerceptionOutput) -> None:
        has_data = out.lidar_fresh or out.radar_fresh
        unplaced = radar_unplaced(out)  # sent, its all-unknown array reads as "sensor Good, nothing around" (spec)
        send = sendable(out)
        self._check_sensors(out, unplaced)
        if has_data != self._publishing:
            self._on_data_state_change(has_data, unplaced)
        elif not has_data and self._waiting_for_first_data and not self._in_grace(out.t):
            self._waiting_for_first_data = False
            self._notices.start(_DATA, False)
            self._report_no_data(f"since start-up ({STARTUP_GRACE_S:.0f} s)")
        self._say_data_state(has_data, unplaced, out.t)
        if not has_data:
            # said afresh when data returns: the radar back without the pose is withheld again, and said so
            self._notices.assume(_PLACED, True)
        elif not self._in_grace(out.t):  # the first poses may come a moment after the radar's first frames
            self._say_placed(not unplaced, out.t)
        if send:
            if self.publisher is not None:
                self.publisher.send_obstacle_distance(
                    out.distances_cm,
                    max(round(self.s.min_distance_m * 100), 1),
                    round(self.s.max_distance_m * 100),
                    MAV_DISTANCE_SENSOR_LASER,
                    None,  # the link's Unix time: the autopilot's GPS time where it has one, never a guess
                )
            self.sent += 1
            self._maybe_send_ais(out)
            self.notifier.watchdog()
        else:
            self.withheld += 1
            self.unplaced += unplaced
            # The loop itself is healthy; systemd must not restart us because a cable is out.
            self.notifier.watchdog()
        if self.tracks_out is not None:
            own = self.poses.at(out.t) if self.poses is not None and out.ego_available else None
            origin = self._world_origin() if own is not None else None
            record = tick_record(out, sent=send, own=own, world_origin=origin, max_distance_m=self.s.max_distance_m)
            try:
                self.tracks_out.write(json.dumps(record, separators=(",", ":")) + "\n")
            except OSError as exc:
                # A full or failing disk costs the run its record, never the autopilot its obstacles: said once,
                # and no more lines are tried (each would fail the same way).
                self.tracks_out_failed = exc.strerror or str(exc)
                log.error("tracks file: %s; no more tracks are written this run", self.tracks_out_failed)
                self.tracks_out = None

    def _world_origin(self) -> tuple[float, float] | None:
        """Latitude and longitude (deg) of the world frame's origin, when the autopilot link has anchored it."""
        to_geodetic = self.world_to_geodetic or getattr(self.publisher, "world_to_geodetic", None)
        geo = to_geodetic(np.zeros(3)) if to_geodetic is not None else None
        if geo is None or not (math.isfinite(geo[0]) and math.isfinite(geo[1])):
            return None
        return float(geo[0]), float(geo[1])

    def _maybe_send_ais(self, out: PerceptionOutput) -> None:
        """The nearest confirmed tracks as AIS_VESSEL, every ais_interval_s, once the world has a lat/lon anchor."""
        s = self.s
        if s.ais_interval_s <= 0 or self.publisher is None or out.t - self._last_ais < s.ais_interval_s:
            return
        # a replay into a live autopilot tracks in the recording's world: its anchor, not the live autopilot's
        to_geodetic = self.world_to_geodetic or getattr(self.publisher, "world_to_geodetic", None)
        send = getattr(self.publisher, "send_ais_vessel", None)
        if to_geodetic is None or send is None:
            return
        self._last_ais = out.t
        tracks = [tr for tr in out.tracks if tr.confirmed and np.all(np.isfinite(tr.position))]
        if not tracks:
            return
        own = self.poses.at(out.t) if self.poses is not None else None
        if own is not None:
            tracks.sort(key=lambda tr: float(np.hypot(*(tr.position - np.asarray(own.position)[:2]))))
        tracks = tracks[: s.ais_max_tracks]
        ned = np.array([[tr.position[0], tr.position[1], 0.0] for tr in tracks])
        geo = to_geodetic(ned)
        if geo is None:  # no autopilot fix yet, or no ego pose at all: no place on the map
            return
        lat, lon, _ = geo
        for tr, la, lo in zip(tracks, np.atleast_1d(lat), np.atleast_1d(lon), strict=True):
            if math.isfinite(la) and math.isfinite(lo):
                self.ais_sent += bool(send(ais_vessel(tr, float(la), float(lo), s.ais_mmsi_base)))

    def _check_sensors(self, out: PerceptionOutput, unplaced: bool) -> None:
        """Per-sensor up/down transitions: a log line and a STATUSTEXT each, and the heartbeat's system_status.

        A sensor not heard from yet is not "down" during the first STARTUP_GRACE_S: a radar takes a second or two to
        deliver after its cfg is accepted.
        """
        in_grace = self._in_grace(out.t)
        fresh = {}
        if self.s.lidar_expected:
            fresh["LiDAR"] = out.lidar_fresh
        if self.s.radar_expected:
            fresh["radar"] = out.radar_fresh
        for name, ok in fresh.items():
            was = self._sensor_state.get(name)
            if was is None and not ok and in_grace:
                continue
            if was is None and ok:
                self._sensor_state[name] = True
                self._notices.start(name, True)
                continue
            if was is None:  # not heard from by the end of the grace: said silent now
                self._notices.start(name, True)
            self._sensor_state[name] = ok
            said = self._change_to_say(name, ok, out.t)
            if said is None:
                continue
            journal, radio = said
            if ok:
                self._tell(logging.INFO, f"{name} delivering again{journal}", f"usv-tracker: {name} back{radio}")
            else:
                self._tell(
                    logging.ERROR,
                    f"{name} silent for more than {self.s.no_data_timeout_s:.1f} s: its bearings are reported "
                    f"unknown{journal}",
                    f"usv-tracker: {name} silent{radio}",
                )
        up = sum(1 for ok in fresh.values() if ok)
        status = MAV_STATE_ACTIVE if up == len(fresh) else MAV_STATE_CRITICAL if up else MAV_STATE_EMERGENCY
        if unplaced:  # the radar delivers but cannot be placed: no obstacle output, as with no sensor at all
            status = MAV_STATE_EMERGENCY
        if status != self._status:
            self._status = status
            self._set_status(status)

    def _in_grace(self, t: float) -> bool:
        if self._first_tick is None:
            self._first_tick = t
        return t - self._first_tick < STARTUP_GRACE_S

    def _on_data_state_change(self, has_data: bool, unplaced: bool) -> None:
        first = self._publishing is None
        self._publishing = has_data
        if has_data:
            if first or self._waiting_for_first_data:
                self._notices.start(_DATA, True)
            if self._waiting_for_first_data:
                self._waiting_for_first_data = False
                log.info(
                    "first sensor data: %s",
                    "OBSTACLE_DISTANCE withheld until the own pose places the radar's frames"
                    if unplaced
                    else "sending OBSTACLE_DISTANCE",
                )
        elif first:
            # Sensors take a moment after start-up (a radar a second or two after its cfg); not an error yet.
            self._waiting_for_first_data = True
            log.info("waiting for sensor data: OBSTACLE_DISTANCE starts with it")

    def _say_data_state(self, has_data: bool, unplaced: bool, t: float) -> None:
        """The feed's stops and restarts, said when they happen but at most once per quiet time (ChangeNotices)."""
        if self._waiting_for_first_data or not self._notices.known(_DATA):
            return
        said = self._change_to_say(_DATA, has_data, t)
        if said is None:
            return
        journal, radio = said
        if has_data:
            self._tell(
                logging.INFO,
                "sensor data is back: "
                + (
                    "the radar alone, without the own pose: still withheld"
                    if unplaced
                    else "sending OBSTACLE_DISTANCE again"
                )
                + journal,
                f"usv-tracker: sensor data back{radio}",
            )
        else:
            self._report_no_data(f"for {self.s.no_data_timeout_s:.1f} s", journal)

    def _say_placed(self, placed: bool, t: float) -> None:
        """While data comes: whether the array can be sent, which it cannot while the radar alone delivers and its
        frames cannot be placed (the own pose lost); said when that changes (ChangeNotices)."""
        if not self._notices.known(_PLACED):
            self._notices.start(_PLACED, True)
        said = self._change_to_say(_PLACED, placed, t)
        if said is None:
            return
        journal, radio = said
        if placed:
            self._tell(
                logging.INFO,
                f"OBSTACLE_DISTANCE sent again: the own pose is back or the LiDAR delivers{journal}",
                f"usv-tracker: obstacles sent again{radio}",
            )
        else:
            self._tell(
                logging.WARNING,
                "the radar delivers but the own pose is lost, so its frames cannot be placed: OBSTACLE_DISTANCE "
                f"withheld so the autopilot reports No Data{journal}",
                "usv-tracker: no pose, obstacles withheld",
            )

    def _change_to_say(self, key: str, state: bool, t: float) -> tuple[str, str] | None:
        """When the change of ``key`` to ``state`` at ``t`` is to be said now (ChangeNotices): what the journal line
        and the STATUSTEXT add about the changes before it that were not said; None when it is not to be said."""
        unsaid = self._notices.note(key, state, t)
        if unsaid is None:
            return None
        return _unsteady(unsaid, self._notices.quiet_s), ", unsteady" if unsaid else ""

    def _tell(self, level: int, journal: str, radio: str) -> None:
        """A journal line at ``level`` and the same news as a STATUSTEXT (warning from WARNING up, else info)."""
        log.log(level, "%s", journal)
        self._statustext(MAV_SEVERITY_WARNING if level >= logging.WARNING else MAV_SEVERITY_INFO, radio)

    def _report_no_data(self, how_long: str, unsteady: str = "") -> None:
        log.error(
            "no sensor has delivered %s: OBSTACLE_DISTANCE withheld so the autopilot reports No Data%s",
            how_long,
            unsteady,
        )
        self._statustext(MAV_SEVERITY_WARNING, "usv-tracker: no sensor data, obstacles withheld")

    def _statustext(self, severity: int, text: str) -> None:
        if self.publisher is not None:
            self.publisher.send_statustext(severity, text)

    def _set_status(self, status: int) -> None:
        if self.publisher is not None:
            self.publisher.set_system_status(status)

    # ---- health ----------------------------------------------------------------------------------------------
    def health_line(self, t: float) -> str:
        p50, p99 = self.stats.percentiles()
        li, ra = self.inputs.lidar.stats, self.inputs.radar.stats
        out = self.last_output
        n_tracks = sum(1 for tr in out.tracks if tr.confirmed) if out else 0
        lidar_rate = self._rates["lidar"].rate(li.received, t)
        radar_rate = self._rates["radar"].rate(ra.received, t)
        line = (
            (f"lidar {lidar_rate:.1f}/s (dropped {li.dropped}) " if self.s.lidar_expected else "lidar off ")
            + (f"radar {radar_rate:.1f}/s (dropped {ra.dropped}) " if self.s.radar_expected else "radar off ")
            + f"sent {self._rates['sent'].rate(self.sent, t):.1f}/s withheld {self.withheld} "
            + (f"(radar without pose {self.unplaced}) " if self.unplaced else "")
            + f"cycle p50 {p50:.1f} ms p99 {p99:.1f} ms misses {self.stats.deadline_misses} tracks {n_tracks} "
            "(stage p50 " + " ".join(f"{k} {v:.1f}" for k, v in self.stats.stage_p50().items()) + " ms)"
        )
        if self.degraded_ticks:
            skipped = self.pipeline.tracking_skipped
            line += (
                f" degraded {self.degraded_ticks} (tracking skipped lidar {skipped['lidar']} radar {skipped['radar']})"
            )
        if self.failed_ticks:
            line += f" failed cycles {self.failed_ticks}"
        if self.status_text is not None:
            line += " " + self.status_text()
        return line

    def maybe_log_health(self, t: float) -> None:
        if t - self._last_health >= self.s.health_interval_s:
            if self._last_health > -math.inf:
                line = self.health_line(t)
                log.info("health: %s", line)
                self.notifier.status(line[:200])
            else:
                self.health_line(t)  # prime the rate counters
            self._last_health = t
            if self.release_memory is not None:
                self.release_memory()

    # ---- drivers of the loop -----------------------------------------------------------------------------------
    def run_live(self, stop: threading.Event, duration_s: float | None = None) -> None:
        period = 1.0 / self.s.rate_hz
        start = self.clock()
        schedule = TickSchedule(period, start + period)
        lock = LidarPhaseLock(period)
        while not stop.is_set():
            now = self.clock()
            if duration_s is not None and now - start >= duration_s:
                break
            lidar = self.inputs.lidar.stats
            shift = lock.shift(now, lidar.last_put, lidar.received) if self.s.lidar_expected else 0.0
            budget = self.s.cycle_budget_s
            self.guarded_tick(now, time.perf_counter() + budget if budget > 0 else None)
            self.collect_old_world()
            self.maybe_log_health(now)
            stop.wait(schedule.after_tick(self.clock(), shift))

    def collect_old_world(self) -> None:
        """After a tick whose pipeline made its trackers anew, a full garbage collection, once the obstacles are out.

        On the live path the old trackers end up in reference cycles, which only the cyclic collector frees, and its
        full collections come seldom in a long-lived process (CPython runs one only once the objects that survived
        into its oldest generation have grown by a quarter); a radar tracker's maps alone are some 12 MB. The soak,
        whose scene changes are position and heading jumps and so new worlds (3 a minute), grew 100 MB in 4 minutes
        without this and stayed flat with it. A world changes rarely at sea (an EKF reset, an autopilot reboot), and
        the collection walks only what was made since start-up (runner.freeze_startup_objects)."""
        resets = self.pipeline.world_resets
        if resets != self._collected_resets:
            self._collected_resets = resets
            gc.collect()

    def guarded_tick(self, t: float, deadline: float | None = None) -> PerceptionOutput | None:
        """A tick that survives a failing cycle: logged with its traceback, tracks restarted, the next tick runs.

        A bug met by one odd frame must not leave the autopilot without obstacles until systemd's watchdog restarts
        the whole daemon (5 s and more). Only MAX_FAILED_TICKS failures in a row end the loop: then something is
        broken for good, and the exception goes up so that the service fails and is restarted.
        """
        try:
            out = self.tick(t, deadline)
        except Exception:
            self.failed_ticks += 1
            self._failed_in_a_row += 1
            log.exception("cycle failed (%d so far): tracks restarted", self.failed_ticks)
            if self._failed_in_a_row >= MAX_FAILED_TICKS:
                raise
            self.pipeline.reset_tracks()
            return None
        self._failed_in_a_row = 0
        return out


class TickSchedule:
    """Deadlines of a fixed-rate loop: one every ``period`` s, each movable by a small phase shift."""

    def __init__(self, period: float, first_deadline: float) -> None:
        self.period = period
        self.next_deadline = first_deadline

    def after_tick(self, now: float, shift: float = 0.0) -> float:
        """A tick finished at ``now``: seconds to wait for the next one."""
        if now > self.next_deadline + self.period:
            # More than a whole period late (e.g. the machine was suspended): re-phase instead of bursting.
            self.next_deadline = now
        self.next_deadline += shift
        wait = max(0.0, self.next_deadline - now)
        self.next_deadline += self.period
        return wait


class LidarPhaseLock:
    """Locks the loop's phase to the LiDAR's (lidar_phase_shift), but only while the LiDAR delivers at the loop's
    own rate: at 1200 rpm, or with the loop set below 10 Hz, every tick would see a revolution "just arrived" and be
    pushed later each time, slowing the loop down."""

    def __init__(self, period: float) -> None:
        self.period = period
        self.interval: float | None = None  # s between revolutions, smoothed
        self._last: tuple[float, int] | None = None  # (arrival time, count) when last seen changing

    def shift(self, now: float, last_put: float, received: int) -> float:
        """The shift for the next tick, from the newest arrival time and the count of revolutions so far."""
        if not math.isfinite(last_put):
            return 0.0
        if self._last is not None and received > self._last[1]:
            step = (last_put - self._last[0]) / (received - self._last[1])
            self.interval = step if self.interval is None else 0.8 * self.interval + 0.2 * step
        if self._last is None or received != self._last[1]:
            self._last = (last_put, received)
        if self.interval is None or abs(self.interval - self.period) > 0.1 * self.period:
            return 0.0
        return lidar_phase_shift(now - last_put, self.period)


def lidar_phase_shift(age: float, period: float) -> float:
    """How far (s) to move the next tick so that ticks fall half a period after the LiDAR's revolutions arrive;
    ``age``: time since the newest revolution arrived, at this tick.

    Both run at 10 Hz on different clocks. A tick that falls right where revolutions arrive sees none, then two,
    and the older is dropped (the loop takes the newest): up to every other revolution for as long as the phases
    stay together, minutes with a real sensor's clock drift. Halfway between arrivals, a revolution may come up to
    half a period early or late and still meet exactly one tick. The rate stays fixed; the phase follows the sensor
    slowly (PHASE_GAIN of the error per tick, at most PHASE_MAX_STEP_S), so a single late revolution does not shake
    it.
    """
    if not 0.0 <= age < period:
        return 0.0  # none this period (or no LiDAR): nothing to lock to
    return float(np.clip(-PHASE_GAIN * (age - period / 2), -PHASE_MAX_STEP_S, PHASE_MAX_STEP_S))


def tick_record(
    out: PerceptionOutput,
    sent: bool,
    own: EgoPose | None = None,
    world_origin: tuple[float, float] | None = None,
    max_distance_m: float | None = None,
) -> dict[str, Any]:
    """One --tracks-out line: time, tracks and the 72 bins (as sent, or null when withheld).

    ``own`` is the own boat's pose the tick used, in the same world frame as the tracks (null in "no ego pose" mode
    or while the pose is unknown: the tracks are then in no frame a reference can be put in); ``world_origin`` the
    latitude/longitude of that frame's origin, when the autopilot has given one, so that a GNSS track can be brought
    into the tracks' frame (usv-tracker evaluate); ``max_distance_m`` the [output] max_distance_m the bins were sent
    with ("clear" is that plus 1 cm), so that the evaluator judges them against the same.
    """

    def f(x: float) -> float | None:
        return None if not math.isfinite(x) else round(float(x), 3)

    return {
        "t": round(out.t, 4),
        "tracks": [
            {
                "id": tr.id,
                "source": tr.source,
                "confirmed": tr.confirmed,
                "position_ne": [f(v) for v in tr.position],
                "velocity_ne": [f(v) for v in tr.velocity],
                "heading_deg": f(math.degrees(tr.heading)),
                "yaw_rate_dps": f(math.degrees(tr.yaw_rate)),
                "length": f(tr.length),
                "width": f(tr.width),
                "height": f(tr.height),
                "shape": tr.shape.value,
                "motion": tr.motion.value if tr.motion else None,
            }
            for tr in out.tracks
        ],
        "obstacle_distance_cm": out.distances_cm.tolist() if sent else None,
        # per bin, how far out the live sensors vouched that a 0.5 m solid would have been returned (m, 0: nowhere)
        "clear_to_m": [round(float(x), 1) for x in out.clear_to_m],
        # bins whose obstacle was held from an earlier sweep (the obstacle memory), not returned in this one
        "held_bins": np.flatnonzero(out.held_bins).tolist() if sent else None,
        "lidar_fresh": out.lidar_fresh,
        "radar_fresh": out.radar_fresh,
        "own": None
        if own is None
        else {"position_ne": [f(own.position[0]), f(own.position[1])], "yaw_deg": f(math.degrees(own.yaw))},
        "world_origin_lat_lon": None
        if world_origin is None
        else [round(world_origin[0], 8), round(world_origin[1], 8)],
        **({} if max_distance_m is None else {"max_distance_m": max_distance_m}),
    }


def radar_unplaced(out: PerceptionOutput) -> bool:
    """Only the radar delivers and the own pose is lost: its frames cannot be placed, every bin is unknown, and the
    array is withheld (no valid input, as the spec means it; with the LiDAR delivering, its returns go into the array
    in the boat's frame, which needs no pose)."""
    return out.radar_fresh and not out.lidar_fresh and not out.pose_known


def sendable(out: PerceptionOutput) -> bool:
    """Whether the tick's obstacle array goes to the autopilot: some sensor delivers, and not the radar unplaced."""
    return (out.lidar_fresh or out.radar_fresh) and not radar_unplaced(out)


def _unsteady(unsaid: int, quiet_s: float) -> str:
    """What a notice adds about the changes it follows that were not said (ChangeNotices)."""
    if unsaid <= 0:
        return ""
    return f" (unsteady: {unsaid} more change(s) since the last notice, not said to keep within 2 per {quiet_s:.0f} s)"
