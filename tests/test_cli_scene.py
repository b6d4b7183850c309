"""`usv-tracker simulate|demo --scene NAME`: the issue's flag, the old `--scenario` kept, drawn scenes described,
and what cannot run refused with a message before anything starts."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from daemon.cli import _scene_ready, build_parser, main
from simulator.scenarios import get_scenario
from simulator.truth import read_truth_csv


@pytest.mark.parametrize("command", ["simulate", "demo"])
def test_scene_and_scenario_name_the_same_setting(command: str) -> None:
    parser = build_parser()
    assert parser.parse_args([command]).scenario == "harbour"
    assert parser.parse_args([command, "--scene", "random:1001"]).scenario == "random:1001"
    assert parser.parse_args([command, "--scenario", "radar_paper:high"]).scenario == "radar_paper:high"


def test_simulate_writes_a_drawn_scene_and_says_what_it_holds(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "captures"
    assert main(["simulate", "--scene", "random:2", "--seconds", "0.3", "--write", str(out)]) == 0
    printed = capsys.readouterr().out
    scene = get_scenario("random:2")
    assert printed.startswith(scene.description)
    assert (out / "lidar.pcap").stat().st_size > 100_000  # 0.3 s of a VLP-16: about 226 packets of 1206 bytes
    truth = read_truth_csv(out / "truth.csv")
    assert list(truth["name"][: scene.n_vessels]) == [v.name for v in scene.vessels]


def test_a_bad_drawn_scene_name_is_refused_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "none"
    assert main(["simulate", "--scene", "random:two", "--seconds", "0.3", "--write", str(out)]) == 2
    assert not out.exists()


def test_running_past_a_drawn_scene_warns(caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="usv-tracker"):
        assert _scene_ready("random:2:20", 30.0, None)
        assert _scene_ready("random:2:20", 20.0, None)
        assert _scene_ready("harbour", 300.0, None)  # named scenes are not drawn: nothing to say
    assert [r.getMessage() for r in caplog.records] == [
        "random:2:20 is drawn collision-free for 20 s; after that vessels hold their last leg and may meet "
        "(random:SEED:SECONDS draws it for longer)"
    ]
    assert capsys.readouterr().out.count("random:2, 20 s") == 2


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["demo", "--scene", "bogus"], "unknown scenario 'bogus'; known: container, crew_boat"),
        (["simulate", "--scene", "radar_paper:foo"], "radar_paper speed must be one of"),
        (["demo", "--seconds", "0"], "--seconds 0.0: must be a positive number of seconds"),
        (["simulate", "--seconds", "-1"], "--seconds -1.0: must be a positive number of seconds"),
        (["simulate", "--seconds", "nan"], "--seconds nan: must be a positive number of seconds"),
    ],
)
def test_what_cannot_run_is_named_not_a_traceback(
    argv: list[str], message: str, caplog: pytest.LogCaptureFixture, tmp_path: Path
) -> None:
    with caplog.at_level(logging.ERROR, logger="usv-tracker"):
        assert main([*argv, "--quiet"] if argv[0] == "demo" else [*argv, "--write", str(tmp_path / "w")]) == 2
    assert any(r.getMessage().startswith(message) for r in caplog.records), caplog.text
    assert not (tmp_path / "w").exists()


@pytest.mark.parametrize("command", ["simulate", "demo"])
def test_an_output_that_cannot_be_written_is_named(
    command: str, caplog: pytest.LogCaptureFixture, tmp_path: Path
) -> None:
    taken = tmp_path / "truth.csv"
    taken.write_text("a file, not a directory\n")
    flag = "--write" if command == "simulate" else "--out"
    with caplog.at_level(logging.ERROR, logger="usv-tracker"):
        assert main([command, "--seconds", "1", flag, str(taken)]) == 2
    assert f"cannot write to {taken}: File exists" in caplog.text
