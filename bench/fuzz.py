"""Long fuzz runs of every parser the daemon feeds with outside bytes, far past what the property tests try.

    python bench/fuzz.py                                  # 1,000,000 inputs per parser (hours on one core)
    python bench/fuzz.py --inputs 200000 --time-limit 70  # about 10 minutes: what bench/results/fuzz.md reports
    python bench/fuzz.py --parsers pcap,cfg --inputs 50000
    python bench/fuzz.py --replay bench/results/fuzz-crashes/pcap-0001.bin   # re-run one saved crashing input

The parsers and the properties are tests/fuzz_targets.py's (the same the property tests check): VLP-16 data and
position packets, pcap/pcapng, the AWR1843 data stream in random read sizes, the AWR1843 CLI's answers, the TI cfg,
the TOML config and MAVLink into the daemon's own link. Each input is either random bytes or a mutation of a real
input: the project's fixtures and the public captures of shared/fixtures when they are there.

Each parser runs in its own process (a crash in native code, a hang or a runaway allocation cannot take the others
down), one after the other, with a 10 s budget per input and a 4 GiB address-space limit. Reported per parser:
inputs run, uncaught exceptions (each distinct one with its first inputs saved under bench/results/fuzz-crashes/),
the slowest input (goal: under 100 ms) and the growth of peak RSS over the run (a leak or a runaway buffer shows
there). Writes bench/results/fuzz.md and fuzz.json.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import multiprocessing as mp
import os
import random
import re
import resource
import signal
import sys
import time
import traceback
import warnings
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import RESULTS, save

CRASHES = RESULTS / "fuzz-crashes"
DEFAULT_INPUTS = 1_000_000
RANDOM_SHARE = 0.15  # the rest are mutations of real inputs
PER_INPUT_BUDGET_S = 10  # an input still running after this is a hang
ADDRESS_SPACE_LIMIT = 4 << 30  # an input that wants more is a runaway allocation (MemoryError, saved)
SAVED_PER_CRASH = 5  # inputs kept per distinct crash
SLOW_GOAL_MS = 100.0


class InputTimeoutError(Exception):
    """An input took longer than PER_INPUT_BUDGET_S."""


def _on_alarm(_signum: int, _frame: object) -> None:
    raise InputTimeoutError(f"input still running after {PER_INPUT_BUDGET_S} s")


def _rss_kib() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() // 1024


def _peak_kib() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux


def _signature(exc: BaseException) -> str:
    """Type, first line of the message without numbers that change per input, and the raising line."""
    frame = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    where = f"{Path(frame.filename).name}:{frame.lineno}" if frame else "?"
    message = re.sub(r"\d+", "#", str(exc).splitlines()[0][:120]) if str(exc) else ""
    return f"{type(exc).__name__}: {message} @ {where}"


def _next_input(target: Any, rng: random.Random) -> tuple[bytes, str]:
    from tests.fuzz_targets import mutate

    seeds = target.seeds("all")
    if rng.random() < RANDOM_SHARE:
        # mostly short: a parser's length checks sit at its first few fields
        size = min(
            target.max_len, int(rng.expovariate(1 / 200)) if rng.random() < 0.7 else rng.randrange(target.max_len)
        )
        return rng.randbytes(size), "random"
    return mutate(rng.choice(seeds), rng, seeds, target.max_len), "mutated"


def _save_crash(name: str, index: int, data: bytes, run_seed: int, exc: BaseException, signature: str) -> str:
    CRASHES.mkdir(parents=True, exist_ok=True)
    stem = CRASHES / f"{name}-{index:04d}"
    stem.with_suffix(".bin").write_bytes(data)
    stem.with_suffix(".json").write_text(
        json.dumps(
            {
                "parser": name,
                "run_seed": run_seed,
                "signature": signature,
                "traceback": "".join(traceback.format_exception(exc)),
            },
            indent=2,
        )
        + "\n"
    )
    return str(stem.with_suffix(".bin").relative_to(RESULTS.parent.parent))


class _Findings:
    """Uncaught exceptions of one parser's run, by signature, with the first few inputs of each saved."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.crashes: dict[str, dict[str, Any]] = {}

    def run(self, target: Any, data: bytes, run_seed: int) -> float:
        """Run one input under the per-input budget; its time in seconds."""
        t0 = time.perf_counter()
        signal.alarm(PER_INPUT_BUDGET_S)
        try:
            target.run(data, random.Random(run_seed))
        except Exception as exc:  # every escape is a finding (InputTimeoutError too); KeyboardInterrupt still stops
            signature = _signature(exc)
            entry = self.crashes.setdefault(signature, {"count": 0, "saved": []})
            entry["count"] += 1
            if len(entry["saved"]) < SAVED_PER_CRASH:
                index = sum(len(c["saved"]) for c in self.crashes.values()) + 1
                entry["saved"].append(_save_crash(self.name, index, data, run_seed, exc, signature))
        finally:
            signal.alarm(0)
        return time.perf_counter() - t0

    @property
    def count(self) -> int:
        return sum(c["count"] for c in self.crashes.values())


def _time_alone(target: Any, data: bytes, run_seed: int) -> float:
    """One more run of an input, for its time only (a crash in it has been counted already)."""
    t0 = time.perf_counter()
    with contextlib.suppress(Exception):
        target.run(data, random.Random(run_seed))
    return time.perf_counter() - t0


def fuzz_one(name: str, inputs: int, time_limit: float | None, seed: int) -> dict[str, Any]:
    """Worker: run one parser; the figures come back as a dict."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy loads: no per-thread arenas under the limit
    logging.disable(logging.CRITICAL)  # the parsers log every damaged frame; millions of lines say nothing here
    warnings.simplefilter("ignore")
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_LIMIT, ADDRESS_SPACE_LIMIT))
    signal.signal(signal.SIGALRM, _on_alarm)
    from tests.fuzz_targets import TARGETS

    target = TARGETS[name]
    rng = random.Random(f"{seed}:{name}")
    for old in CRASHES.glob(f"{name}-*"):  # a previous run's findings: this run saves its own
        old.unlink()
    findings = _Findings(name)
    seeds = target.seeds("all")
    for i, data in enumerate(seeds):  # the real inputs themselves first; also the warm-up (imports, caches, socket)
        findings.run(target, data, i)
    rss0, peak0 = _rss_kib(), _peak_kib()
    kinds = {"random": 0, "mutated": 0}
    slowest: tuple[float, bytes, int, str] = (0.0, b"", 0, "")
    rss_samples = [(0, rss0)]  # (inputs done, RSS KiB): a leak keeps climbing, a warmed-up heap levels off
    busy = 0.0
    start = time.monotonic()
    next_report = start + 15.0
    done = 0
    for done in range(1, inputs + 1):
        data, kind = _next_input(target, rng)
        kinds[kind] += 1
        run_seed = rng.getrandbits(64)
        elapsed = findings.run(target, data, run_seed)
        busy += elapsed
        if elapsed > slowest[0]:
            slowest = (elapsed, data, run_seed, kind)
        now = time.monotonic()
        if now >= next_report:
            next_report = now + 15.0
            rss_samples.append((done, _rss_kib()))
            print(f"  {name}: {done:,} inputs, {findings.count} uncaught", flush=True)
        if time_limit is not None and now - start >= time_limit:
            break
    wall = time.monotonic() - start
    rss_end = _rss_kib()
    half = min(rss_samples, key=lambda sample: abs(sample[0] - done / 2))
    # The machine is shared: a slowest time may be a moment the scheduler took away. Timed again, alone.
    retimed = min(_time_alone(target, slowest[1], slowest[2]) for _ in range(3)) if slowest[1] else 0.0
    return {
        "parser": name,
        "inputs": done,
        "random": kinds["random"],
        "mutated": kinds["mutated"],
        "seeds_own": len(target.seeds("own")),
        "seeds_public": len(target.seeds("public")),
        "stateful": target.stateful,
        "crashes": findings.crashes,
        "crashing_inputs": findings.count,
        "slowest_ms": slowest[0] * 1e3,
        "slowest_retimed_ms": retimed * 1e3,
        "slowest_input_bytes": len(slowest[1]),
        "slowest_input_kind": slowest[3],
        "mean_us": busy / max(done, 1) * 1e6,
        "wall_s": wall,
        "peak_rss_growth_mib": (_peak_kib() - peak0) / 1024,
        "rss_growth_mib": (rss_end - rss0) / 1024,
        "rss_growth_second_half_mib": (rss_end - half[1]) / 1024,
    }


def _run_isolated(name: str, inputs: int, time_limit: float | None, seed: int) -> dict[str, Any]:
    """One parser in a fresh process; a worker that dies (a native crash) is reported as such."""
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        job = pool.apply_async(fuzz_one, (name, inputs, time_limit, seed))
        wait = None if time_limit is None else time_limit + 600.0
        try:
            return job.get(wait)
        except Exception as exc:  # the worker died or never came back
            return {"parser": name, "inputs": 0, "worker_failed": f"{type(exc).__name__}: {exc}", "crashes": {}}


def replay(path: Path) -> int:
    """Run one saved input again with the run seed it crashed with; prints the traceback if it still crashes."""
    from tests.fuzz_targets import TARGETS

    meta = json.loads(path.with_suffix(".json").read_text())
    target = TARGETS[meta["parser"]]
    print(f"{meta['parser']}: {meta['signature']}")
    target.run(path.read_bytes(), random.Random(meta["run_seed"]))
    print("no longer crashes")
    return 0


def markdown(rows: list[dict[str, Any]], command: str) -> str:
    lines = [
        f"`{command}` (niceness {os.nice(0)}): each parser in its own process, one after the other, on a 2-core "
        f"machine shared with other jobs. Inputs: {RANDOM_SHARE:.0%} random bytes, the rest mutations of real "
        "inputs (seeds: the project's fixtures + the public captures). Goal for the slowest input: under "
        f"{SLOW_GOAL_MS:.0f} ms. The default run is {DEFAULT_INPUTS:,} inputs per parser.",
        "",
        "| parser | inputs | random / mutated | seeds own + public | uncaught exceptions | slowest input (timed again) "
        "| mean per input | peak RSS growth (of it in the 2nd half) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "worker_failed" in r:
            lines.append(f"| {r['parser']} | worker died: {r['worker_failed']} | | | | | | |")
            continue
        slow = (
            f"{r['slowest_ms']:.1f} ms ({r['slowest_retimed_ms']:.1f} ms; {r['slowest_input_bytes']:,} B, "
            f"{r['slowest_input_kind']})"
        )
        if r["slowest_retimed_ms"] >= SLOW_GOAL_MS:
            slow += " **over goal**"
        lines.append(
            f"| {r['parser']}{' (stream)' if r['stateful'] else ''} | {r['inputs']:,} | {r['random']:,} / "
            f"{r['mutated']:,} | {r['seeds_own']} + {r['seeds_public']} | {r['crashing_inputs']} "
            f"({len(r['crashes'])} distinct) | {slow} | {r['mean_us']:.0f} us | {r['peak_rss_growth_mib']:.1f} MiB "
            f"({r['rss_growth_second_half_mib']:.1f}) |"
        )
    found = [(r["parser"], sig, c) for r in rows for sig, c in r.get("crashes", {}).items()]
    lines.append("")
    if found:
        lines.append("Uncaught exceptions (inputs under bench/results/fuzz-crashes/, `--replay FILE` re-runs one):")
        lines += [f"- {parser}: `{sig}` x{c['count']}, e.g. `{c['saved'][0]}`" for parser, sig, c in found]
    else:
        lines.append("No uncaught exception in any parser.")
    lines.append("")
    lines.append(
        "(stream): the MAVLink link keeps its parser's state from one input to the next, as it does on the boat. "
        "Slowest input: its time in the run, then the best of three runs of it alone afterwards (the goal applies "
        "to that: in the run, another job on the machine can stall any input). Peak RSS growth: from after the seeds "
        "(warm-up) to the end; in brackets the growth of RSS over the second half of the run, which a leak keeps "
        "climbing in and a warmed-up heap does not."
    )
    return "\n".join(lines)


def main() -> int:
    from tests.fuzz_targets import TARGETS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--inputs", type=int, default=DEFAULT_INPUTS, help=f"inputs per parser (default {DEFAULT_INPUTS:,})"
    )
    ap.add_argument("--time-limit", type=float, default=None, help="seconds per parser; stops it early")
    ap.add_argument("--parsers", default=",".join(TARGETS), help=f"comma-separated, of: {', '.join(TARGETS)}")
    ap.add_argument("--seed", type=int, default=1, help="seed of the input generator")
    ap.add_argument("--replay", type=Path, help="re-run one saved crashing input (its .bin file)")
    args = ap.parse_args()
    if args.replay is not None:
        return replay(args.replay)
    names = [n.strip() for n in args.parsers.split(",") if n.strip()]
    unknown = [n for n in names if n not in TARGETS]
    if unknown:
        ap.error(f"unknown parser(s) {', '.join(unknown)}; known: {', '.join(TARGETS)}")
    command = "python bench/fuzz.py " + " ".join(sys.argv[1:])
    rows = []
    for name in names:
        print(f"{name}: up to {args.inputs:,} inputs" + (f" or {args.time_limit:.0f} s" if args.time_limit else ""))
        row = _run_isolated(name, args.inputs, args.time_limit, args.seed)
        rows.append(row)
        if "worker_failed" in row:
            print(f"  {name}: worker died: {row['worker_failed']}")
            continue
        print(
            f"  {name}: {row['inputs']:,} inputs in {row['wall_s']:.0f} s, {row['crashing_inputs']} uncaught "
            f"({len(row['crashes'])} distinct), slowest {row['slowest_ms']:.1f} ms ({row['slowest_retimed_ms']:.1f} ms "
            f"again), peak RSS +{row['peak_rss_growth_mib']:.1f} MiB ({row['rss_growth_second_half_mib']:+.1f} in the "
            "second half)"
        )
    save("fuzz", {"command": command, "parsers": rows}, markdown(rows, command))
    return 1 if any(r.get("crashes") or "worker_failed" in r for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
