"""The live view (daemon/view): an MCAP written by a real replay, read back with the mcap reader, equals what the
daemon computed; a real WebSocket client receives /tracks from the live server; without the options the SDK is
never imported, and a failing view never stops the daemon."""

from __future__ import annotations

import asyncio
import base64
import json
import logging
import math
import os
import struct
import subprocess
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove")
mcap_reader = pytest.importorskip("mcap.reader")
mcap_protobuf = pytest.importorskip("mcap_protobuf.decoder")

from daemon.cli import main  # noqa: E402
from daemon.replay import ReplayOptions, recording_config, replay  # noqa: E402
from daemon.view import frames  # noqa: E402
from daemon.view.options import host_port  # noqa: E402
from daemon.view.publisher import FoxgloveView  # noqa: E402
from simulator.capture import write_captures  # noqa: E402
from simulator.scenarios import get_scenario  # noqa: E402
from tracker.lidar.preprocess import REASON_NAMES  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SECONDS = 3.0
EVERY_TICK = ("/tf", "/own_boat", "/lidar/points", "/lidar/clusters", "/tracks", "/obstacles", "/obstacles/outline")
TOPICS = {*EVERY_TICK, "/radar/points", "/health"}


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("view") / "run"
    write_captures("harbour", d, SECONDS, seed=0, scene=get_scenario("harbour"))
    return d


def read_mcap(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """topic -> [(log_time ns, decoded message)], protobuf through the schema in the file, JSON as JSON."""
    factory = mcap_protobuf.DecoderFactory()
    out: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    with path.open("rb") as f:
        for schema, channel, message in mcap_reader.make_reader(f).iter_messages():
            if channel.message_encoding == "json":
                decoded = json.loads(message.data)
            else:
                decoded = factory.decoder_for(channel.message_encoding, schema)(message.data)
            out[channel.topic].append((message.log_time, decoded))
    return out


def cloud(msg: Any) -> np.ndarray:
    """A PointCloud's packed data as a numpy structured array, from the fields it declares."""
    kinds = {1: "u1", 3: "<u2", 5: "<u4", 7: "<f4", 8: "<f8"}
    dtype = np.dtype(
        {
            "names": [f.name for f in msg.fields],
            "formats": [kinds[f.type] for f in msg.fields],
            "offsets": [f.offset for f in msg.fields],
            "itemsize": msg.point_stride,
        }
    )
    return np.frombuffer(msg.data, dtype=dtype)


@pytest.fixture(scope="module")
def replayed(recording: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[list[dict[str, Any]], dict]:
    d = tmp_path_factory.mktemp("view-out")
    tracks, mcap = d / "tracks.jsonl", d / "view.mcap"
    assert main(["replay", str(recording), "--fast", "--quiet", "--tracks-out", str(tracks), "--mcap", str(mcap)]) == 0
    rows = [json.loads(line) for line in tracks.read_text().splitlines()]
    return rows, read_mcap(mcap)


def test_the_mcap_holds_every_topic_once_a_tick(replayed: tuple[list[dict[str, Any]], dict]) -> None:
    rows, topics = replayed
    assert set(topics) == TOPICS
    assert len(rows) == 31  # 3 s of data: 31 revolutions, a tick after each (test_replay_command)
    # A replay feeds every tick a revolution and knows the pose throughout: no tolerance needed.
    for topic in EVERY_TICK:
        assert len(topics[topic]) == len(rows), topic
    assert len(topics["/health"]) == len(rows)
    # radar frames (about 12 Hz) do not fall one per tick: a tick without one publishes no radar cloud
    assert len(rows) - 3 <= len(topics["/radar/points"]) <= len(rows)
    tick_ns = [round(r["t"] * 1e9) for r in rows]
    for topic in EVERY_TICK:
        # the ticks' own times (tracks-out rounds t to 0.1 ms)
        assert np.allclose([ns for ns, _ in topics[topic]], tick_ns, atol=1e5, rtol=0), topic


def test_track_boxes_stand_where_tracks_out_puts_the_tracks(replayed: tuple[list[dict[str, Any]], dict]) -> None:
    rows, topics = replayed
    compared = confirmed = 0
    for row, (_, update) in zip(rows, topics["/tracks"], strict=True):
        boxes = {e.id: e for e in update.entities}
        assert set(boxes) == {f"track/{tr['id']}" for tr in row["tracks"]}
        assert [d.type for d in update.deletions] == [1]  # ALL: a track that ended leaves the screen
        for tr in row["tracks"]:
            entity = boxes[f"track/{tr['id']}"]
            assert entity.frame_id == "world"
            body = drawn_body(entity, tr["shape"])
            centre = body.pose.position
            north, east = tr["position_ne"]
            # world ENU: x east, y north (tracks-out rounds to 1 mm)
            assert (centre.x, centre.y) == pytest.approx((east, north), abs=1e-3)
            assert body.size.x == pytest.approx(tr["length"], abs=1e-3)
            assert body.size.y == pytest.approx(tr["width"], abs=1e-3)
            assert entity.texts[0].text.startswith(f"{tr['id']} {tr['source']}")
            compared += 1
            confirmed += tr["confirmed"]
    assert compared > 100 and confirmed > 50  # the harbour's vessels were tracked: the comparison compared something


def drawn_body(entity: Any, shape: str) -> Any:
    """The one primitive a track entity is drawn with: an elliptic cylinder (equal scales at top and bottom) for an
    ellipse track, a cube for any other (box, point), never both."""
    if shape == "ellipse":
        assert len(entity.cylinders) == 1 and not entity.cubes
        body = entity.cylinders[0]
        assert body.bottom_scale == body.top_scale == 1.0
        return body
    assert len(entity.cubes) == 1 and not entity.cylinders
    return entity.cubes[0]


def test_round_hulls_are_drawn_as_the_ellipses_they_were_fitted_as(tmp_path: Path) -> None:
    """The moorings scene's buoys and round-ended boats are fitted as ellipses (tests/test_lidar_curved_hulls.py):
    the view draws those tracks as elliptic cylinders of their length and beam, and the workboat's as a box."""
    d = tmp_path / "moorings"
    write_captures("moorings", d, SECONDS, seed=0, scene=get_scenario("moorings"))
    tracks, mcap = tmp_path / "tracks.jsonl", tmp_path / "view.mcap"
    assert main(["replay", str(d), "--fast", "--quiet", "--tracks-out", str(tracks), "--mcap", str(mcap)]) == 0
    rows = [json.loads(line) for line in tracks.read_text().splitlines()]
    shapes: dict[str, int] = defaultdict(int)
    for row, (_, update) in zip(rows, read_mcap(mcap)["/tracks"], strict=True):
        entities = {e.id: e for e in update.entities}
        for tr in row["tracks"]:
            body = drawn_body(entities[f"track/{tr['id']}"], tr["shape"])
            assert (body.size.x, body.size.y) == pytest.approx((tr["length"], tr["width"]), abs=1e-3)
            shapes[tr["shape"]] += 1
    assert shapes["ellipse"] > 50 and shapes["box"] > 0, shapes  # both were drawn: the comparison compared something


def test_the_72_bins_decode_to_the_distances_sent(replayed: tuple[list[dict[str, Any]], dict]) -> None:
    rows, topics = replayed
    sent = 0
    max_cm = 10_000  # output.max_distance_m default, 100 m
    for row, (_, msg) in zip(rows, topics["/obstacles"], strict=True):
        assert msg.frame_id == "boat"
        bins = cloud(msg)
        assert bins["bin"].tolist() == list(range(72))
        if row["obstacle_distance_cm"] is None:
            continue
        sent += 1
        d = np.array(row["obstacle_distance_cm"])
        assert bins["distance_cm"].tolist() == d.tolist()
        state = np.where(d == 65535, frames.UNKNOWN_STATE, np.where(d > max_cm, frames.CLEAR, frames.OBSTACLE))
        assert bins["state"].tolist() == state.tolist()
        # an obstacle is drawn at its range, on its bin's bearing (bin 0 the bow, clockwise: FLU y = -starboard)
        k = np.flatnonzero(state == frames.OBSTACLE)
        bearing = np.radians(5.0 * k)
        assert np.hypot(bins["x"][k], bins["y"][k]) == pytest.approx(d[k] / 100, abs=1e-4)
        assert np.arctan2(-bins["y"][k], bins["x"][k]) == pytest.approx(np.angle(np.exp(1j * bearing)), abs=1e-5)
    assert sent >= 28


def test_every_return_is_published_with_the_rule_that_dropped_it(replayed: tuple[list[dict[str, Any]], dict]) -> None:
    _, topics = replayed
    dropped_any = False
    for (_, points), (_, health) in zip(topics["/lidar/points"], topics["/health"], strict=True):
        pts = cloud(points)
        counts = health["lidar_returns"]
        assert list(counts) == list(REASON_NAMES)
        assert pts.size == sum(counts.values())  # kept + every rejection
        assert np.bincount(pts["reason"], minlength=len(REASON_NAMES)).tolist() == list(counts.values())
        assert (pts[["red", "green", "blue", "alpha"]].tolist()) == [
            tuple(c) for c in frames.REASON_RGBA[pts["reason"]].tolist()
        ]
        dropped_any |= sum(counts.values()) > counts["kept"]
    assert dropped_any  # some returns were rejected (water, isolated): the colours mean something


def test_the_boat_frame_follows_the_own_pose(replayed: tuple[list[dict[str, Any]], dict]) -> None:
    rows, topics = replayed
    for row, (_, msg) in zip(rows, topics["/tf"], strict=True):
        (tf,) = msg.transforms
        assert (tf.parent_frame_id, tf.child_frame_id) == ("world", "boat")
        north, east = row["own"]["position_ne"]
        assert (tf.translation.x, tf.translation.y) == pytest.approx((east, north), abs=1e-3)
        q = tf.rotation
        yaw_enu = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        heading = math.pi / 2 - yaw_enu
        assert math.remainder(heading - math.radians(row["own"]["yaw_deg"]), 2 * math.pi) == pytest.approx(0, abs=1e-3)


def test_health_carries_the_loops_figures(replayed: tuple[list[dict[str, Any]], dict]) -> None:
    rows, topics = replayed
    for k, (row, (_, h)) in enumerate(zip(rows, topics["/health"], strict=True)):
        assert h["t"] == pytest.approx(row["t"], abs=1e-4)
        assert h["tracks"] == len(row["tracks"])
        assert h["confirmed"] == sum(tr["confirmed"] for tr in row["tracks"])
        assert h["sent"] + h["withheld"] == k + 1
        assert h["bins_obstacle"] + h["bins_clear"] + h["bins_unknown"] == 72
        assert h["bins_held"] == len(row["held_bins"] or []) <= h["bins_obstacle"]
        assert h["cycle_p50_ms"] > 0 and h["failed_cycles"] == 0


def test_boat_quaternion_is_the_ned_frd_attitude_seen_in_enu_flu() -> None:
    from scipy.spatial.transform import Rotation

    ned_to_enu = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    flu_to_frd = np.diag([1.0, -1.0, -1.0])
    rng = np.random.default_rng(1)
    for roll, pitch, yaw in rng.uniform(-np.pi / 2, np.pi / 2, (20, 3)) * [1, 1, 2]:
        r_ned_frd = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
        want = ned_to_enu @ r_ned_frd @ flu_to_frd
        got = Rotation.from_quat(frames.boat_quaternion(roll, pitch, yaw)).as_matrix()
        assert got == pytest.approx(want, abs=1e-12)
    # heading north, level: the bow (FLU x) points along ENU y
    assert Rotation.from_quat(frames.boat_quaternion(0, 0, 0)).apply([1, 0, 0]) == pytest.approx([0, 1, 0])


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ("8765", ("127.0.0.1", 8765)),
        (":9000", ("127.0.0.1", 9000)),
        ("0.0.0.0:8765", ("0.0.0.0", 8765)),
        ("[::1]:0", ("::1", 0)),
    ],
)
def test_host_port(text: str, want: tuple[str, int]) -> None:
    assert host_port(text) == want


def test_foxglove_without_a_value_serves_on_loopback_8765() -> None:
    from daemon.cli import build_parser

    args = build_parser().parse_args(["demo", "--foxglove"])
    assert args.foxglove == ("127.0.0.1", 8765) and args.mcap is None
    args = build_parser().parse_args(["replay", "rec", "--mcap", "x.mcap"])
    assert args.foxglove is None and args.mcap == "x.mcap"


def _child(code: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)


def test_without_the_options_foxglove_is_never_imported(recording: Path, tmp_path: Path) -> None:
    code = (
        "import sys\nfrom daemon.cli import main\n"
        f"rc = main(['replay', {str(recording)!r}, '--fast', '--quiet', '--seconds', '0.5', "
        f"'--tracks-out', {str(tmp_path / 't.jsonl')!r}])\n"
        "print(rc, sorted(m for m in sys.modules if m.startswith(('foxglove', 'daemon.view.publisher'))))\n"
    )
    res = _child(code)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split("\n")[0] == "0 []"


def test_without_the_sdk_the_options_say_what_to_install(recording: Path, tmp_path: Path) -> None:
    code = (
        "import sys\nsys.modules['foxglove'] = None  # as if foxglove-sdk were not installed\n"
        "from daemon.cli import main\n"
        f"print(main(['replay', {str(recording)!r}, '--fast', '--mcap', {str(tmp_path / 'v.mcap')!r}]))\n"
    )
    res = _child(code)
    assert res.stdout.strip() == "2", res.stderr
    assert "pip install 'usv-tracker[view]'" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "v.mcap").exists()


def test_a_failing_view_is_switched_off_and_the_daemon_goes_on(
    recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    plain, viewed = tmp_path / "plain.jsonl", tmp_path / "viewed.jsonl"
    replay(recording_config(recording, plain), ReplayOptions(tlog=str(recording / "autopilot.tlog")))
    view = FoxgloveView(mcap_path=tmp_path / "v.mcap")
    calls = []

    def broken(out: Any) -> None:
        calls.append(out.t)
        raise RuntimeError("view bug")

    monkeypatch.setattr(view, "publish", broken)
    try:
        with caplog.at_level(logging.ERROR, logger="daemon.view.publisher"):
            summary = replay(
                recording_config(recording, viewed), ReplayOptions(tlog=str(recording / "autopilot.tlog"), view=view)
            )
    finally:
        view.close()
    assert summary.ticks == 31 and len(calls) == 1  # called once, then off
    assert (view.failures, view.enabled) == (1, False)
    assert [r.message for r in caplog.records] == ["foxglove view failed: switched off, the daemon goes on without it"]
    assert caplog.records[0].exc_info is not None  # with its traceback
    assert viewed.read_bytes() == plain.read_bytes()  # the daemon's output is untouched


def test_a_websocket_client_receives_tracks_from_the_live_server(recording: Path, tmp_path: Path) -> None:
    """A real client speaks the Foxglove WebSocket protocol to the SDK's server: serverInfo and advertise (JSON),
    subscribe to /tracks, then a binary MessageData frame (opcode 1, subscription id, log time, payload). The replay
    starts only once the server has the subscription, so nothing depends on timing; every wait is bounded at 30 s
    (a run takes about 1 s)."""
    websockets = pytest.importorskip("websockets")
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    view = FoxgloveView(host="127.0.0.1", port=0)
    done = threading.Event()
    errors: list[BaseException] = []

    def run_replay() -> None:
        try:
            config = recording_config(recording, tmp_path / "t.jsonl")
            replay(config, ReplayOptions(tlog=str(recording / "autopilot.tlog"), view=view))
        except BaseException as exc:  # reported by the test, not lost in the thread
            errors.append(exc)
        finally:
            done.set()

    async def client() -> tuple[dict[str, Any], bytes]:
        # The SDK's server (0.30) names its subprotocol foxglove.sdk.v1; older servers foxglove.websocket.v1.
        async with websockets.connect(
            f"ws://127.0.0.1:{view.port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"]
        ) as ws:
            channels: dict[str, dict[str, Any]] = {}
            while "/tracks" not in channels:
                msg = json.loads(await asyncio.wait_for(ws.recv(), 30))
                if msg["op"] == "advertise":
                    channels.update({c["topic"]: c for c in msg["channels"]})
            await ws.send(
                json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channels["/tracks"]["id"]}]})
            )
            deadline = time.monotonic() + 30
            while not view.tracks.has_sinks():
                assert time.monotonic() < deadline, "the server never took the subscription"
                await asyncio.sleep(0.01)
            threading.Thread(target=run_replay, daemon=True).start()
            while True:
                frame = await asyncio.wait_for(ws.recv(), 30)
                if isinstance(frame, bytes) and frame[0] == 1:
                    return channels["/tracks"], frame

    try:
        advertised, frame = asyncio.run(client())
        assert done.wait(60) and not errors, errors
    finally:
        view.close()
    opcode, subscription, log_time = struct.unpack_from("<BIQ", frame)
    assert (opcode, subscription) == (1, 7)
    assert log_time > 1.7e18  # the capture's own clock, Unix ns
    assert (advertised["encoding"], advertised["schemaName"]) == ("protobuf", "foxglove.SceneUpdate")
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(advertised["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for f in files.file:
        pool.Add(f)
    update = message_factory.GetMessageClass(pool.FindMessageTypeByName("foxglove.SceneUpdate")).FromString(frame[13:])
    assert [d.type for d in update.deletions] == [1]
    assert all(e.id.startswith("track/") and e.frame_id == "world" for e in update.entities)


def test_a_replay_stopped_by_sigterm_finishes_its_mcap(recording: Path, tmp_path: Path) -> None:
    """`kill` and `timeout` send SIGTERM: the replay stops as with Ctrl-C, prints its summary and finishes the MCAP
    (killed outright, the file was left unreadable)."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "stopped.mcap"
    cmd = [sys.executable, "-m", "daemon.cli", "replay", str(recording), "--speed", "1", "--quiet", "--mcap", str(out)]
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60.0
        while not (out.exists() and out.stat().st_size > 20_000) and time.monotonic() < deadline:
            time.sleep(0.1)  # ticks are being written: the replay is under way
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60.0)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "replayed" in err and "(interrupted)" in err
    topics = read_mcap(out)
    assert 1 <= len(topics["/tf"]) < SECONDS * 10  # what was replayed before the signal, read back whole
