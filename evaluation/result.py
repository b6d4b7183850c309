"""What an evaluation returns: one object with ``to_dict()`` (JSON-ready: NaN becomes null) and ``to_text()``."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from evaluation.bins import BinScores
from evaluation.hota import HotaScores
from evaluation.tracking import ErrorStats, TrackScores


def _plain(x: Any) -> Any:
    """Dataclasses (with their derived-rate properties), dicts and numpy scalars -> JSON types; NaN -> None."""
    if isinstance(x, HotaScores):
        return _plain(x.to_dict())
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        d = {f.name: _plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        for name, attr in vars(type(x)).items():
            if isinstance(attr, property):
                d[name] = _plain(getattr(x, name))
        return d
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if hasattr(x, "item"):  # numpy scalars
        return _plain(x.item())
    return x


@dataclass(frozen=True)
class EvaluationResult:
    truth_kind: str  # "simulator" or "gnss"
    inputs: dict[str, str | None]
    settings: dict[str, float | int | None]
    alignment: dict[str, Any]
    tracks: TrackScores
    visibility: dict[str, Any]
    bins: BinScores | None
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "truth_kind": self.truth_kind,
            "inputs": dict(self.inputs),
            "settings": _plain(self.settings),
            "alignment": _plain(self.alignment),
            "tracks": _plain(self.tracks),
            "visibility": _plain(self.visibility),
            "bins": _plain(self.bins) if self.bins is not None else None,
            "notes": list(self.notes),
        }

    def to_text(self) -> str:
        return format_text(self)


def _pct(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{100 * x:.1f} %"


def _num(x: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def _err_row(name: str, e: ErrorStats, unit: str) -> str:
    return f"  {name:<18} {_num(e.mean):>8} {_num(e.median):>8} {_num(e.p95):>8} {e.n:>7}  {unit}"


def format_text(r: EvaluationResult) -> str:
    t, a, v = r.tracks, r.alignment, r.visibility
    s = r.settings
    lines = [
        f"truth: {r.inputs['truth']} ({r.truth_kind})",
        f"tracks: {r.inputs['tracks']}",
        f"returns: {r.inputs.get('returns') or 'none'}",
        f"time: truth = tick t {a['time_offset_s']:+.3f} s ({a['method']}); "
        f"{a['ticks_in_file']} ticks, {a['ticks_scored']} scored, {a['ticks_outside_truth']} outside the truth, "
        f"{a['ticks_without_pose']} without an own pose, {a['ticks_in_warmup']} in the warm-up",
        f"matching: track centre within {s['match_distance_m']:g} m of the hull footprint; "
        + (
            f"a vessel is to be tracked with >= {s['min_returns']} returns in a reference window"
            if r.inputs.get("returns")
            else "every vessel in range is to be tracked (no record of what the sensors returned)"
        ),
        "",
        "tracks (confirmed)",
        f"  MOTA {_pct(t.mota)}   MOTP {_num(t.motp_m)} m   IDF1 {_pct(t.idf1)}   HOTA {_pct(t.hota.hota)} "
        f"(DetA {_pct(t.hota.det_a)}, AssA {_pct(t.hota.ass_a)})",
        f"  objects {t.objects}   matched {t.matches}   missed {t.misses}   false positives {t.false_positives}   "
        f"id switches {t.id_switches}   fragmentations {t.fragmentations}",
        f"  precision {_pct(t.precision)}   recall {_pct(t.recall)}   mostly tracked {t.mostly_tracked} "
        f"of {t.unique_objects}   velocity published on {_pct(t.velocity_coverage)} of matched pairs",
        f"  {'error of matched':<18} {'mean':>8} {'median':>8} {'p95':>8} {'pairs':>7}",
        _err_row("position", t.position_error_m, "m (centre to centre)"),
        _err_row("speed", t.speed_error_mps, "m/s"),
        _err_row("heading", t.heading_error_deg, "deg"),
        _err_row("heading axis", t.heading_axis_error_deg, "deg (bow or stern, either way)"),
        _err_row("length", t.length_error_m, "m"),
        _err_row("width", t.width_error_m, "m"),
        "",
        "visibility (vessel-ticks)",
        f"  to be tracked {v['vessel_ticks_to_track']}   in range but not returned (sensor limit) "
        f"{v['vessel_ticks_sensor_limit']}   out of range {v['vessel_ticks_out_of_range']}   "
        f"not in the returns record {v['vessel_ticks_without_record']}   "
        f"tracks on unreturned vessels, not scored {v['tracks_on_unreturned_vessels']}",
    ]
    if v.get("per_vessel"):
        lines.append(
            f"  {'id':>4} {'name':<16} {'to track':>9} {'matched':>8} {'missed':>7} {'switches':>9} {'limit':>6}"
        )
        for vid, row in sorted(v["per_vessel"].items(), key=lambda kv: int(kv[0])):
            lines.append(
                f"  {vid:>4} {row['name']:<16} {row['to_track']:>9} {row['matched']:>8} {row['missed']:>7} "
                f"{row['switches']:>9} {row['sensor_limit']:>6}"
            )
    lines.append("")
    b = r.bins
    if b is None:
        lines.append(f"bins: not scored ({r.visibility.get('bins_note', 'no returns record')})")
    else:
        lines += [
            f"bins (OBSTACLE_DISTANCE, max_distance {s['max_distance_m']:g} m)",
            f"  ticks sent {b.ticks_sent} (scored {b.ticks_scored}, no reference {b.ticks_without_reference})   "
            f"withheld {b.ticks_withheld} ({b.ticks_withheld_with_solid} with a solid in range)",
            f"  bins scored {b.bins_scored}: obstacle {b.obstacle_bins}, clear {b.clear_bins}, "
            f"unknown {b.unknown_bins}",
            f"  false clear {b.false_clear} of {b.bins_with_solid} bins with a solid ({_pct(b.false_clear_rate)}; "
            f"sent clear {b.false_clear_sent_clear}, unknown {b.false_clear_sent_unknown})",
            f"  false obstacle {b.false_obstacle} of {b.obstacle_bins} obstacle bins ({_pct(b.false_obstacle_rate)}); "
            f"on a solid there but not returned in the reference windows (held or estimated): {b.obstacle_unreturned}",
            f"  too far {b.too_far} (an obstacle sent beyond a solid returned nearer throughout, by the tolerance)",
            f"  obstacle bins within max(0.5 m, 5 %) of the nearest returned solid: {_pct(b.within_tolerance_share)}",
        ]
    for note in r.notes:
        lines.append(f"note: {note}")
    return "\n".join(lines)
