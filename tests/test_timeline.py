"""The pass timeline (issue 19, item 3): what a monitor pass records for replay, and how safely.

A real pass on a generated office records ``sessions/1/timeline.jsonl``; the tests read
the file with ``json`` alone and hold it against the pass itself (its store's events, its
frames, the simulator's true pose). A pass killed in process and resumed leaves one
timeline without a repeated moment; a torn last line (a kill mid-write) is skipped;
``mission.timeline: false`` records nothing.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import time

import pytest
from replay_site import make_replay_site, status_at, timeline_records
from site_files import REPO, bomc_command, bomc_env

from bomc_bt import run
from bomc_bt.errors import BomcError
from bomc_bt.store import SiteStore
from bomc_bt.timeline import TimelineWriter, read_timeline


class Killed(BaseException):
    """Raised from a tick hook: the process 'dies' between two ticks."""


def reconciled(event) -> bool:
    """A row ``end_session`` adds to square history with the nodes: not something the pass saw."""
    return bool((event.detail or {}).get("reconciled"))


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    return make_replay_site(tmp_path_factory.mktemp("timeline"))


def test_a_pass_records_its_tree_poses_frames_and_events(office):
    site = office["site"]
    records = timeline_records(site, 1)
    assert records[0] == {"k": "head", "v": 1, "session": 1, "t": 0.0, "resume": False}
    kinds = [r["k"] for r in records]
    assert kinds.count("tree") == 1 and kinds.count("head") == 1
    names = [row[0] for row in [r for r in records if r["k"] == "tree"][0]["n"]]
    assert names[0] == "Monitor" and "Perceive Associate" in names
    # poses every 0.5 s of robot time, the estimate close to the truth once localized
    poses = [r for r in records if r["k"] == "pose"]
    gaps = {round(b["t"] - a["t"], 1) for a, b in zip(poses, poses[1:], strict=False)}
    assert gaps <= {0.5, 0.6}, gaps
    localized = [r for r in poses if r["p"] is not None]
    assert len(localized) > 0.8 * len(poses)
    assert all(abs(r["p"][0] - r["g"][0]) < 0.5 and abs(r["p"][1] - r["g"][1]) < 0.5 for r in localized)
    # every graph event of the pass, as the store has it (less the session end's bookkeeping rows)
    with SiteStore(site, readonly=True) as store:
        stored = [(e.kind, e.node_id, e.category) for e in store.events(session=1) if not reconciled(e)]
    recorded = [(row[0], row[1], row[2]) for r in records if r["k"] == "ev" for row in r["e"]]
    assert recorded == stored and any(kind == "added" for kind, _, _ in recorded)
    # frames: numbered in order, with pixel boxes inside the image and scores in (0, 1]
    frames = [r for r in records if r["k"] == "frame"]
    assert [f["n"] for f in frames] == list(range(1, len(frames) + 1))
    report = json.loads((site / "sessions" / "1" / "report.json").read_text())
    assert len(frames) == report["frames"], report
    boxes = [(f["wh"], d) for f in frames for d in f["d"]]
    assert len(boxes) > 10
    assert all(0 <= d[1] < d[3] <= w and 0 <= d[2] < d[4] <= h and 0 < d[5] <= 1 for (w, h), d in boxes)
    # the tree: the root ends in success; only changes are written
    assert status_at(records, office["sim_time"])[0] == "s"
    assert sum(len(r["c"]) for r in records if r["k"] == "st") < office["ticks"] * len(names) / 20
    size = (site / "sessions" / "1" / "timeline.jsonl").stat().st_size
    assert size < 2000 * office["sim_time"], size  # compact: under 2 kB per robot second


def test_a_killed_and_resumed_pass_leaves_one_timeline_without_repeats(office, tmp_path):
    site = shutil.copytree(office["site"], tmp_path / "site")
    config = run.build_config()

    def kill_at_40(runner) -> None:
        if runner.robot.now() >= 40.0:
            raise Killed

    with pytest.raises(Killed):
        run.run_monitor(office["world"], site, 2, seed=2, config=config, hooks=[kill_at_40])
    killed = timeline_records(site, 2)
    assert 39.0 < max(r["t"] for r in killed) <= 40.1  # closed (flushed) as the pass died
    result = run.run_monitor(office["world"], site, 2, seed=2, config=config, resume=True)
    assert result.succeeded and result.context.restored
    timeline = read_timeline(site / "sessions" / "2" / "timeline.jsonl", 2)
    assert timeline.resumes == 1 and timeline.skipped == 0
    times = [p["t"] for p in timeline.poses]
    assert times == sorted(times) and len(set(times)) == len(times)  # no moment twice
    assert timeline.end == pytest.approx(result.sim_time, abs=0.11)
    with SiteStore(site, readonly=True) as store:
        stored = [(e.kind, e.node_id) for e in store.events(session=2) if not reconciled(e)]
    assert [(row[0], row[1]) for ev in timeline.events for row in ev["e"]] == stored


def test_kill_9_mid_pass_leaves_earlier_sessions_untouched_and_the_resume_continues_the_file(office, tmp_path):
    site = shutil.copytree(office["site"], tmp_path / "site")
    session_1 = {p.name: p.read_bytes() for p in (site / "sessions" / "1").iterdir()}
    (tmp_path / "flush.yaml").write_text("mission: {timeline_flush_period: 0}\n")  # every record on disk at once
    args = ("monitor", "--world", str(office["world"]), "--site", str(site), "--session", "2", "--seed", "2",
            "--quiet", "--config", str(tmp_path / "flush.yaml"))
    path = site / "sessions" / "2" / "timeline.jsonl"
    proc = subprocess.Popen(bomc_command(*args), cwd=REPO, env=bomc_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while (not path.exists() or path.stat().st_size < 15000) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL, "the pass ended before it could be killed"
    assert {p.name: p.read_bytes() for p in (site / "sessions" / "1").iterdir()} == session_1
    killed = read_timeline(path, 2)
    assert killed.poses and killed.skipped <= 1
    resumed = subprocess.run(bomc_command(*args, "--resume"), capture_output=True, text=True, cwd=REPO,
                             env=bomc_env(), timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    timeline = read_timeline(path, 2)
    assert timeline.resumes == 1 and timeline.skipped <= 1
    times = [p["t"] for p in timeline.poses]
    assert times == sorted(times) and len(set(times)) == len(times)
    report = json.loads((site / "sessions" / "2" / "report.json").read_text())
    assert timeline.end == pytest.approx(report["sim_time_s"], abs=0.11)
    assert {p.name: p.read_bytes() for p in (site / "sessions" / "1").iterdir()} == session_1


def test_a_torn_last_line_is_skipped_and_a_fresh_start_replaces_a_dead_run(tmp_path):
    path = tmp_path / "timeline.jsonl"
    writer = TimelineWriter(path, flush_period=0.0)
    writer.write({"k": "head", "v": 1, "session": 3, "t": 0.0, "resume": False})
    for t in (0.5, 1.0, 1.5):
        writer.write({"k": "pose", "t": t, "p": [t, 0.0, 0.0]})
    writer.close()
    with open(path, "ab") as f:
        f.write(b'{"k":"pose","t":2.0,"p":[2.0,')  # a kill in the middle of a line
    timeline = read_timeline(path, 3)
    assert [p["t"] for p in timeline.poses] == [0.5, 1.0, 1.5] and timeline.skipped == 1
    resumed = TimelineWriter(path)  # the resumed pass's head starts a line of its own
    resumed.write({"k": "head", "v": 1, "session": 3, "t": 1.0, "resume": True})
    resumed.write({"k": "pose", "t": 1.1, "p": [5.0, 0.0, 0.0]})
    resumed.close()
    timeline = read_timeline(path, 3)
    assert [p["t"] for p in timeline.poses] == [0.5, 1.1] and timeline.resumes == 1  # from 1.0 on: the resumed run
    assert timeline.skipped == 1
    with open(path, "ab") as f:  # the pass starts again from scratch (killed before its session opened)
        f.write(b'{"k":"head","v":1,"session":3,"t":0.0,"resume":false}\n{"k":"pose","t":0.5,"p":[9,9,0]}\n')
    assert [p["p"] for p in read_timeline(path, 3).poses] == [[9, 9, 0]]
    path.write_bytes(b'{"k":"pose","t":0.5}\n')
    with pytest.raises(BomcError, match="not a timeline"):
        read_timeline(path, 3)
    with pytest.raises(BomcError, match="no timeline recorded for session 4"):
        read_timeline(tmp_path / "missing.jsonl", 4)


def test_recording_off_writes_no_timeline(office, tmp_path):
    site = shutil.copytree(office["site"], tmp_path / "site")
    (tmp_path / "off.yaml").write_text("mission: {timeline: false}\n")
    config = run.build_config([str(tmp_path / "off.yaml")])
    assert run.run_monitor(office["world"], site, 2, seed=2, config=config).succeeded
    assert (site / "sessions" / "2" / "report.json").exists()
    assert not (site / "sessions" / "2" / "timeline.jsonl").exists()


@pytest.mark.parametrize("line, words", [("timeline_pose_period: 0", "timeline_pose_period"),
                                         ("timeline_flush_period: -1", "timeline_flush_period"),
                                         ("timeline: maybe", "mission.timeline")])
def test_timeline_settings_are_checked(tmp_path, line, words):
    (tmp_path / "bad.yaml").write_text(f"mission:\n  {line}\n")
    with pytest.raises(BomcError, match=words) as caught:
        run.build_config([str(tmp_path / "bad.yaml")])
    assert "bad.yaml" in str(caught.value)
