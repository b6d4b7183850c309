"""`usv-tracker evaluate` on the command line: output, and bad input as a message naming file and line, exit 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from daemon.cli import main
from tests.evaluation_fixtures import tick, track, two_boats, write_ticks, write_truth


def run(tmp_path: Path) -> tuple[Path, Path]:
    write_truth(tmp_path, two_boats(), 1.0)
    ticks = [tick(0.1 * k, [track(1, 10.0, 0.5), track(2, 0.0, 20.0)]) for k in range(10)]
    return tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks)


def test_text_and_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth, tracks = run(tmp_path)
    assert main(["evaluate", str(tracks), "--truth", str(truth)]) == 0
    text = capsys.readouterr().out
    assert "MOTA 100.0 %" in text and "MOTP 0.25 m" in text and "id switches 0" in text
    assert "bins: not scored" in text
    assert main(["evaluate", str(tracks), "--truth", str(truth / "truth.csv"), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["tracks"]["mota"] == 1.0 and data["tracks"]["motp_m"] == pytest.approx(0.25)
    assert data["tracks"]["objects"] == 20 and data["bins"] is None
    assert data["tracks"]["speed_error_mps"]["n"] == 20
    assert data["settings"]["match_distance_m"] == 2.0


def bad(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    out = capsys.readouterr()
    assert out.out == "" and "Traceback" not in out.err
    return out.err


def test_bad_inputs_exit_2_naming_file_and_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth, tracks = run(tmp_path)
    err = bad(capsys, ["evaluate", str(tracks), "--truth", str(tmp_path / "nowhere")])
    assert "nowhere: no such file or directory" in err
    err = bad(capsys, ["evaluate", str(tmp_path / "none.jsonl"), "--truth", str(truth)])
    assert "none.jsonl: cannot read the tracks file" in err

    lines = tracks.read_text().splitlines()
    tracks.write_text("\n".join([lines[0], lines[1][:-5], *lines[2:]]) + "\n")
    assert f"{tracks} line 2: not JSON" in bad(capsys, ["evaluate", str(tracks), "--truth", str(truth)])
    tracks.write_text("\n".join([lines[0], lines[1].replace('"t":', '"t": NaN, "x":', 1), *lines[2:]]) + "\n")
    assert f"{tracks} line 2: t must be a finite number" in bad(
        capsys, ["evaluate", str(tracks), "--truth", str(truth)]
    )
    tracks.write_text("\n".join([lines[1], lines[0], *lines[2:]]) + "\n")
    assert f"{tracks} line 2: t = 0.0 does not follow 0.1" in bad(
        capsys, ["evaluate", str(tracks), "--truth", str(truth)]
    )
    tracks.write_text("\n".join(lines) + "\n")

    csv_lines = (truth / "truth.csv").read_text().splitlines()
    fields = csv_lines[2].split(",")
    fields[3] = "nan"
    (truth / "truth.csv").write_text("\n".join([*csv_lines[:2], ",".join(fields), *csv_lines[3:]]) + "\n")
    err = bad(capsys, ["evaluate", str(tracks), "--truth", str(truth)])
    assert "truth.csv line 3: north is not a finite number" in err
    (truth / "truth.csv").write_text("\n".join([*csv_lines[:2], "0.1,1,b", *csv_lines[3:]]) + "\n")
    assert "truth CSV line 3: 3 fields, expected 22" in bad(capsys, ["evaluate", str(tracks), "--truth", str(truth)])

    gnss = tmp_path / "gnss.csv"
    gnss.write_text("time,lat,lon\n1.0,59.4,10.4\n2.0,591.4,10.4\n")
    assert f"{gnss} line 3: time 2.0, lat 591.4" in bad(capsys, ["evaluate", str(tracks), "--truth", str(gnss)])
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    assert "neither a simulator truth CSV" in bad(capsys, ["evaluate", str(tracks), "--truth", str(other)])


def test_bad_settings_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    truth, tracks = run(tmp_path)
    for flag, value in (("--match-distance", "0"), ("--max-distance", "nan"), ("--min-returns", "0")):
        assert "must be" in bad(capsys, ["evaluate", str(tracks), "--truth", str(truth), flag, value])


def test_missing_motmetrics_names_the_extra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    truth, tracks = run(tmp_path)
    monkeypatch.setitem(sys.modules, "motmetrics", None)  # what an environment without the extra looks like
    err = bad(capsys, ["evaluate", str(tracks), "--truth", str(truth)])
    assert "py-motmetrics" in err and "usv-tracker[eval]" in err


def test_daemon_commands_do_not_load_the_evaluation() -> None:
    """The boat's daemon shares the parser with `evaluate`: building it must not import pandas and the scorers."""
    code = (
        "import sys; from daemon.cli import build_parser; build_parser(); "
        "print(sorted(m for m in sys.modules if m.startswith(('evaluation.api', 'motmetrics', 'pandas'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
