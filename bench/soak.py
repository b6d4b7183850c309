"""Soak: one `usv-tracker run` process live for an hour against the simulator; does it hold its memory, descriptors
and threads?

    python bench/soak.py               # one hour of data, one hour of wall time (live)
    python bench/soak.py --quick       # 5 minutes, to try it
    python bench/soak.py --hours 0.5
    python bench/soak.py --trace --hours 0.25   # diagnostic: where the memory goes (tracemalloc), nothing saved

The daemon is the real entry point (`usv-tracker run`, a child process, so the RSS sampled is the daemon's alone)
on the live path systemd runs: VLP-16 UDP on 127.0.0.1, the AWR1843 over two ptys (the device emulator, cfg sent
and accepted), ArduPilot over MAVLink UDP (poses, TIMESYNC, rate requests, OBSTACLE_DISTANCE back), reader threads,
the 10 Hz loop, the health line every 5 s. Live rather than `run --fast` on a recording: the fast replay runs only
the pipeline on the main thread (no sockets, ptys, reader threads or autopilot link), so its descriptor and thread
counts could not grow whatever the live daemon does with them; live costs an hour of wall time for an hour of data.

The data: the simulator's random harbour scenes of the tuning seeds (random:1, random:2, ... 60 s each, seeds 1-100
only; bench/_scene_chain.py), one after another in the same daemon process, the last one random:1 again (see
``soak_scenes``). Every second the bench reads the
child's VmRSS and Threads from /proc/PID/status and counts /proc/PID/fd. Figures: RSS at 1 min and at the end, its
growth between (goal: < 5 MB over the hour), its maximum, descriptors and threads at the start, at 1 min, at the end
and their maximum (goal: no growth), the data seconds the daemon was fed and what the autopilot received.
Samples go to bench/results/soak.json (git-ignored), the figures to bench/results/soak.md.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import RESULTS, save
from bench._proc import ProcSample, Sampler, rss_windows, summarise
from bench._scene_chain import ChainSimulation, SceneChain
from daemon.demo import free_udp_port
from simulator.capture import mounts_toml

SCENE_S = 60.0
TUNING_SEEDS = range(1, 101)  # never the held-out 1001-1100
REFERENCE_S = 60.0  # growth is counted from here: start-up (imports, first tracks, caches) is over by then
GOAL_GROWTH_MB = 5.0
STOP_GRACE_S = 30.0


def daemon_command(trace_dir: Path | None) -> list[str]:
    """The installed `usv-tracker` console script (so the sampled process is exactly what systemd starts)."""
    if trace_dir is not None:
        return [sys.executable, "-m", "bench._traced_run", str(trace_dir)]
    script = Path(sys.executable).with_name("usv-tracker")
    return [str(script)] if script.exists() else [sys.executable, "-m", "daemon.cli"]


def daemon_toml(chain: SceneChain, position_port: int) -> str:
    """The scenes' mounts (all random scenes share them) and the position port."""
    first = chain.scenes[0]
    if any((s.lidar_mount, s.radar_mount) != (first.lidar_mount, first.radar_mount) for s in chain.scenes):
        raise ValueError("the scenes' sensor mounts differ: one daemon config cannot fit them all")
    return mounts_toml(first).replace("[lidar]\n", f"[lidar]\nposition_port = {position_port}\n", 1)


def soak_scenes(n: int) -> list[str]:
    """``n`` random tuning scenes, the last one the first again. What a process holds depends on the harbour it is
    in (how many vessels and tracks, how much quay in its maps): between two different scenes the RSS differs by a
    few MB with no leak at all. Ending on the scene it started with, the end sample sees the same harbour at the same
    moment as the 1-minute sample, so their difference is what the hour added."""
    names = [f"random:{TUNING_SEEDS[k % len(TUNING_SEEDS)]}" for k in range(n)]
    if n > 1:
        names[-1] = names[0]
    return names


def run_soak(seconds: float, trace_dir: Path | None, work: Path) -> dict[str, Any]:
    n = math.ceil(seconds / SCENE_S)
    names = soak_scenes(n)
    chain = SceneChain(names, SCENE_S)
    sim = ChainSimulation(chain, free_udp_port(), free_udp_port(), free_udp_port())
    toml = work / "usv-tracker.toml"
    toml.write_text(daemon_toml(chain, sim.position_port))
    log_path = work / "daemon.log"
    with sim, log_path.open("w") as log_file:
        args = [
            *daemon_command(trace_dir), "run", "--config", str(toml),
            "--lidar", sim.lidar_url,
            "--radar-cli", sim.radar_cli_url,
            "--radar-data", sim.radar_data_url,
            "--radar-profile", sim.radar_profile,
            "--mavlink", sim.daemon_mavlink_url,
            "--seconds", str(seconds + STOP_GRACE_S),  # a safety net: the bench stops it with SIGTERM
        ]  # fmt: skip
        sim_t0 = sim.sim_time()
        wall0 = time.monotonic()
        proc = subprocess.Popen(args, stdout=log_file, stderr=subprocess.STDOUT)
        sampler = Sampler(proc.pid, 1.0)
        sampler.start()
        # The simulator was already playing when the daemon started: sample times lag simulation time by ``lead``.
        # The reference sample is the one at the end of the first scene and the run stops at the end of the last,
        # the same scene (soak_scenes) at the same moment of it.
        lead = sim.sim_time(sampler.t0)
        reference_s = REFERENCE_S - lead
        ap = sim.autopilot
        assert ap is not None
        traced = 0
        try:
            next_report = 60.0
            load: list[float] = []  # the machine's 1-minute load average, once a minute: other work on the cores
            while (elapsed := time.monotonic() - sampler.t0) < seconds - lead:
                if proc.poll() is not None:
                    raise RuntimeError(f"the daemon exited early ({proc.returncode}); see its log")
                if trace_dir is not None and traced == 0 and elapsed >= reference_s:
                    traced = _snapshot(proc, trace_dir, 1)
                if elapsed >= next_report:
                    load.append(os.getloadavg()[0])
                    s = sampler.samples[-1]
                    print(
                        f"{elapsed / 60:5.1f} min  scene {names[sim.scene_now()]:<10} RSS {s.rss_kb / 1024:6.1f} MB  "
                        f"fds {s.fds}  threads {s.threads}  OBSTACLE_DISTANCE received {len(ap.obstacle_distances())}",
                        flush=True,
                    )
                    next_report += 60.0
                time.sleep(0.5)
            if trace_dir is not None:
                traced = _snapshot(proc, trace_dir, 2)
            sampler.stop()
            data_s = sim.sim_time() - sim_t0
            received = ap.obstacle_distances()
            t_term = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            rc = proc.wait(timeout=10.0)
            stop_s = time.monotonic() - t_term
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            sampler.stop()
        wall_s = time.monotonic() - wall0
        statustexts = [s.text for s in ap.statustexts()]
    log_text = log_path.read_text(errors="replace")
    return {
        "log_text": log_text,
        "seconds_asked": seconds,
        "scenes": names[: chain.at(data_s)[0] + 1],
        "data_seconds": data_s,
        "wall_seconds": wall_s,
        "obstacle_distance_received": len(received),
        "obstacle_distance_rate_hz": len(received) / data_s if data_s > 0 else math.nan,
        "lidar_packets_sent": sim.packets_sent,
        "exit_code": rc,
        "stop_seconds": stop_s,
        "statustexts": sorted(set(statustexts)),
        "log": _log_figures(log_text),
        "proc": summarise(sampler.samples, reference_s),
        "reference_s": reference_s,
        "samples": sampler.as_json(),
        "command": " ".join(args),
        "traced": traced,
        "loadavg": {"mean": sum(load) / len(load) if load else math.nan, "max": max(load, default=math.nan)},
    }


def _snapshot(proc: subprocess.Popen[bytes], trace_dir: Path, k: int) -> int:
    proc.send_signal(signal.SIGUSR1)
    done = trace_dir / f"snapshot-{k}.done"
    end = time.monotonic() + 120.0
    while not done.exists():
        if time.monotonic() > end or proc.poll() is not None:
            raise RuntimeError(f"no tracemalloc snapshot {k} from the daemon")
        time.sleep(0.2)
    return k


HEALTH = re.compile(
    r"health: lidar (?P<lidar>[\d.]+)/s \(dropped (?P<lidar_dropped>\d+)\) radar (?P<radar>[\d.]+)/s "
    r"\(dropped (?P<radar_dropped>\d+)\) sent (?P<sent>[\d.]+)/s withheld (?P<withheld>\d+) "
    r"(?:\(radar without pose (?P<unplaced>\d+)\) )?"
    r"cycle p50 (?P<p50>[\d.]+) ms p99 (?P<p99>[\d.]+) ms misses (?P<misses>\d+) tracks (?P<tracks>\d+)"
)


def _log_figures(text: str) -> dict[str, Any]:
    """What the daemon's own journal says: its last health line, and every WARNING/ERROR (distinct, counted)."""
    lines = text.splitlines()
    health = [m for m in (HEALTH.search(line) for line in lines) if m]
    problems: dict[str, int] = {}
    timed: list[str] = []  # the lines themselves, with their time of day, to place a silence in the run
    for line in lines:
        if " WARNING " in line or " ERROR " in line:
            if len(timed) < 500:
                timed.append(line)
            key = re.sub(r"^\S+ ", "", line)  # without the time of day
            key = re.sub(r"\d+(\.\d+)?", "N", key)  # counts and times vary; the message is what matters
            problems[key] = problems.get(key, 0) + 1
    return {
        "health_lines": len(health),
        "last_health": health[-1].groupdict() if health else None,
        "last_health_line": next((line for line in reversed(lines) if "health: " in line), ""),
        "max_p99_ms": max((float(m["p99"]) for m in health), default=math.nan),
        "problems": problems,
        "problem_lines": timed,
    }


def trace_report(trace_dir: Path, top: int = 10) -> str:
    """The top allocation sites by growth between the snapshot at 1 minute and the one at the end."""
    filters = [
        tracemalloc.Filter(False, tracemalloc.__file__),
        tracemalloc.Filter(False, "<frozen importlib._bootstrap>"),
        tracemalloc.Filter(False, "<frozen importlib._bootstrap_external>"),
        tracemalloc.Filter(False, "<unknown>"),
    ]
    first, last = (
        tracemalloc.Snapshot.load(str(trace_dir / f"snapshot-{k}.pickle")).filter_traces(filters) for k in (1, 2)
    )
    lines = [f"top {top} allocation sites by growth, minute 1 -> end (size, count):"]
    for stat in last.compare_to(first, "lineno")[:top]:
        frame = stat.traceback[0]
        lines.append(
            f"  {stat.size_diff / 1024:+9.1f} KiB {stat.count_diff:+8d} blocks  now {stat.size / 1024:9.1f} KiB  "
            f"{frame.filename}:{frame.lineno}"
        )
    lines.append("the three largest by whole call stack:")
    for stat in last.compare_to(first, "traceback")[:3]:
        lines.append(f"  {stat.size_diff / 1024:+9.1f} KiB {stat.count_diff:+8d} blocks")
        lines += [f"      {f.filename}:{f.lineno}" for f in stat.traceback if not f.filename.startswith("<frozen")]
    total = sum(s.size for s in last.statistics("filename")) - sum(s.size for s in first.statistics("filename"))
    lines.append(f"traced total {total / 1024:+.1f} KiB")
    return "\n".join(lines)


def _scene_span(names: list[str]) -> str:
    if len(names) > 2 and names[-1] == names[0]:
        return f"{names[0]} .. {names[-2]}, then {names[-1]} again"
    return f"{names[0]} .. {names[-1]}"


def markdown(r: dict[str, Any], cli: str) -> str:
    p, lg = r["proc"], r["log"]
    h = lg["last_health"] or {}
    growth_ok = p["rss_growth_mb"] < GOAL_GROWTH_MB * r["data_seconds"] / 3600.0
    fd, th = p["fds"], p["threads"]
    lines = [
        f"`{cli}`: one `usv-tracker run` process live for {r['data_seconds'] / 60:.1f} min "
        f"({len(r['scenes'])} random scenes of the tuning seeds, {_scene_span(r['scenes'])}, 60 s each; "
        "VLP-16 over UDP, AWR1843 over ptys, ArduPilot over MAVLink UDP, all on 127.0.0.1). "
        f"Sampled every second from /proc ({p['samples']} samples). Machine: 2 cores, shared; the simulator runs on "
        "the same cores"
        + (
            f", and the 1-minute load average over the run was {r['loadavg']['mean']:.1f} on average "
            f"(max {r['loadavg']['max']:.1f})."
            if "loadavg" in r  # not recorded by the first runs
            else "."
        ),
        "",
        "| figure | value | goal |",
        "|---|---|---|",
        f"| RSS at 1 min (the end of the first scene, {p['rss_ref_t_s']:.0f} s after exec) / at the end (the end of "
        f"the last scene, the first one again) | {p['rss_ref_mb']:.1f} / {p['rss_end_mb']:.1f} MB | |",
        "| RSS growth after the first minute: end sample - 1 min sample (the same scene) | "
        f"{p['rss_growth_mb']:+.1f} MB | < 5 MB over the hour: {'met' if growth_ok else '**not met**'} |",
        f"| the same from minute-long windows (minute 2 / the last minute): median, minimum | "
        f"{p['rss_ref_window_median_mb']:.1f} -> {p['rss_end_window_median_mb']:.1f} MB "
        f"({p['rss_end_window_median_mb'] - p['rss_ref_window_median_mb']:+.1f}), "
        f"{p['rss_ref_window_min_mb']:.1f} -> {p['rss_end_window_min_mb']:.1f} MB "
        f"({p['rss_end_window_min_mb'] - p['rss_ref_window_min_mb']:+.1f}) | |",
        f"| RSS slope fitted over every sample after 1 min | {p['rss_slope_mb_per_h']:+.1f} MB/h | |",
        f"| RSS max | {p['rss_max_mb']:.1f} MB | |",
        "| RSS by sixths of the run (after the first minute): floor / median | "
        + ", ".join(
            f"{a / 60:.0f}-{b / 60:.0f} min {lo:.0f} / {med:.0f}"
            for a, b, lo, med in rss_windows([ProcSample(**x) for x in r["samples"] if x["t"] >= r["reference_s"]])
        )
        + " MB | |",
        f"| open descriptors at exec / 1 min / end / max | {fd['first']} / {fd['ref']} / {fd['last']} / {fd['max']} "
        f"| no growth: {'met' if fd['last'] <= fd['ref'] and fd['max'] <= fd['ref'] else '**not met**'} |",
        f"| threads at exec / 1 min / end / max | {th['first']} / {th['ref']} / {th['last']} / {th['max']} "
        f"| no growth: {'met' if th['last'] <= th['ref'] and th['max'] <= th['ref'] else '**not met**'} |",
        f"| data processed | {r['data_seconds']:.0f} s live in {r['wall_seconds']:.0f} s of wall time "
        f"({r['lidar_packets_sent']:,} VLP-16 data packets sent) | |",
        f"| OBSTACLE_DISTANCE the autopilot received | {r['obstacle_distance_received']} "
        f"({r['obstacle_distance_rate_hz']:.2f}/s) | 10/s |",
        f"| last health line: cycle p50 / p99 over its last minute, deadline misses since start | "
        f"{h.get('p50', '-')} / {h.get('p99', '-')} ms, {h.get('misses', '-')} | |",
        f"| SIGTERM to exit | {r['stop_seconds']:.2f} s, exit code {r['exit_code']} | < 1 s, 0 |",
        "",
        "The daemon's WARNING and ERROR lines over the run (numbers as N): "
        + (
            "; ".join(f"{n} x `{k}`" for k, n in sorted(lg["problems"].items(), key=lambda kv: -kv[1]))
            if lg["problems"]
            else "none"
        )
        + ".",
        "",
        f"Last health line: `{lg['last_health_line'].split('health: ', 1)[-1]}`",
    ]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0, help="hours of data, live (default 1)")
    ap.add_argument("--quick", action="store_true", help="5 minutes, printed only")
    ap.add_argument("--trace", action="store_true", help="tracemalloc the daemon; print where memory grew; no save")
    args = ap.parse_args()
    seconds = 300.0 if args.quick else args.hours * 3600.0
    if seconds < 2 * REFERENCE_S:
        ap.error(f"the soak needs more than {2 * REFERENCE_S:.0f} s: growth is counted after the first minute")
    cli = "python bench/soak.py" + (" --quick" if args.quick else f" --hours {args.hours:g}" * (args.hours != 1.0))
    with tempfile.TemporaryDirectory(prefix="soak-") as tmp:
        work = Path(tmp)
        trace_dir = work / "trace" if args.trace else None
        trial = args.quick or args.trace
        kept = RESULTS / ("soak-trial.log" if trial else "soak.log")
        print(f"soak: {seconds / 60:.0f} min live; the daemon's log goes to {kept}", flush=True)
        RESULTS.mkdir(parents=True, exist_ok=True)
        try:
            r = run_soak(seconds, trace_dir, work)
        except Exception:
            if (work / "daemon.log").exists():
                kept.write_text((work / "daemon.log").read_text(errors="replace"))
            raise
        if trace_dir is not None:
            print(trace_report(trace_dir))
    p = r["proc"]
    print(
        f"RSS {p['rss_ref_mb']:.1f} MB at 1 min, {p['rss_end_mb']:.1f} MB at the end ({p['rss_growth_mb']:+.1f} MB, "
        f"slope {p['rss_slope_mb_per_h']:+.1f} MB/h; minute medians {p['rss_ref_window_median_mb']:.1f} -> "
        f"{p['rss_end_window_median_mb']:.1f}, minima {p['rss_ref_window_min_mb']:.1f} -> "
        f"{p['rss_end_window_min_mb']:.1f}), max {p['rss_max_mb']:.1f} MB; fds {p['fds']}; "
        f"threads {p['threads']}; {r['data_seconds']:.0f} s of data in {r['wall_seconds']:.0f} s; "
        f"OBSTACLE_DISTANCE {r['obstacle_distance_received']} ({r['obstacle_distance_rate_hz']:.2f}/s); "
        f"exit {r['exit_code']} {r['stop_seconds']:.2f} s after SIGTERM"
    )
    print(f"daemon WARNING/ERROR lines: {r['log']['problems'] or 'none'}")
    kept.write_text(r.pop("log_text"))  # git-ignored like the json: where a silence or a stall fell in the run
    if not trial:
        save("soak", r, markdown(r, cli))


if __name__ == "__main__":
    main()
