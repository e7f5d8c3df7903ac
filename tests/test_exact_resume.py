"""Exact resume: a killed pass resumed is the uninterrupted pass continued (issue 18, item 3).

A small generated office with an intra-session change is built once; session 2 runs
uninterrupted for the reference, then killed (in-process at chosen robot times, and a
real ``kill -9`` of ``bomc monitor``) and resumed. The resumed pass must go on at the
robot time of the last commit with the world as it was then (the change applied before the
kill stays applied, none is applied twice) and end with the uninterrupted pass's F1.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from py_trees.common import Status
from site_files import bomc_command, bomc_env, error_line

from bomc_bt import run
from bomc_bt.evaluate_site import evaluate_session
from bomc_bt.looked_sides import looked_sides_key
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.pass_resume import coverage_key, looked_key, sightings_key
from bomc_bt.resume_rows import load_resume_point, resume_key
from bomc_bt.store import SiteStore
from bomc_bt.world import load_world

REPO = Path(__file__).resolve().parents[1]


class Killed(BaseException):
    """Raised from a tick hook: the process 'dies' between two ticks, nothing more is written."""


def kill_at(robot_time: float):
    def hook(runner) -> None:
        if runner.robot.now() >= robot_time:
            raise Killed
    return hook


def final_graph(site: Path, session: int) -> list[tuple]:
    with SiteStore(site, readonly=True) as store:
        return [(n.id, n.category, tuple(n.position.round(6))) for n in store.graph_after(session)]


def saved_robot_time(site: Path, session: int) -> float:
    with SiteStore(site, readonly=True) as store:
        point = load_resume_point(store, session) or {}
    robot = point.get("robot") or {}
    return robot.get("steps", 0) * 0.1


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    """A 16 x 12 m office, built and monitored in session 1; session 2 has a change during
    the pass; the uninterrupted session 2 is the reference."""
    root = tmp_path_factory.mktemp("resume")
    world_path = root / "office.yaml"
    generate_office(OfficeParams(width=16, height=12, seed=3, sessions=2), world_path)
    world = load_world(world_path)
    assert world.during_changes(2), "the generated world must change during session 2"
    config = run.build_config()
    base = root / "base"
    assert run.run_build(world_path, base, seed=0, config=config).succeeded
    assert run.run_monitor(world_path, base, 1, seed=1, config=config).succeeded
    reference = shutil.copytree(base, root / "reference")
    result = run.run_monitor(world_path, reference, 2, seed=2, config=config)
    assert result.succeeded
    return {"world": world_path, "during": world.during_changes(2), "base": base, "config": config,
            "reference": reference,
            "root": root, "f1": evaluate_session(world_path, reference, 2, config).overall.f1,
            "graph": final_graph(reference, 2), "sim_time": result.sim_time}


def world_checker(world_path: Path, ticks: list):
    """A tick hook recording (robot time, the simulator's objects == the timeline's at that time)."""
    world = load_world(world_path)

    def hook(runner) -> None:
        robot = runner.robot
        truth = world.ground_truth(2, at=robot.now())
        ticks.append((robot.now(), set(robot.current_objects()) == set(truth)))
    return hook


@pytest.mark.parametrize("fraction", [0.25, 0.7])
def test_a_pass_killed_in_process_resumes_where_it_was_with_the_same_f1(office, fraction):
    at = fraction * office["sim_time"]
    site = shutil.copytree(office["base"], office["root"] / f"killed-{fraction}")
    with pytest.raises(Killed):
        run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], hooks=[kill_at(at)])
    committed = saved_robot_time(site, 2)
    assert 0 < committed <= at + 0.1 + 1e-9  # the hook kills after the tick that reached ``at``
    ticks: list = []
    result = run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], resume=True,
                             hooks=[world_checker(office["world"], ticks)])
    assert result.succeeded and result.context.restored
    first_time = ticks[0][0]
    assert abs(first_time - (committed + 0.1)) < 0.15, (first_time, committed)  # robot time goes on
    assert all(same for _, same in ticks), "the simulated world left the world file's timeline"
    change_at = office["during"][0].at
    if committed > change_at:  # the change happened before the kill: it holds from the first tick
        assert ticks[0][1]
    assert evaluate_session(office["world"], site, 2, office["config"]).overall.f1 == office["f1"]
    with SiteStore(site, readonly=True) as store:
        session = store.sessions()[1]
        looked = [store.get_progress(key) for key in (looked_key(2), looked_sides_key(2))]
    assert session.ended and session.outcome == "completed"
    with SiteStore(office["reference"], readonly=True) as store:  # what the next pass judges additions by
        assert looked == [store.get_progress(key) for key in (looked_key(2), looked_sides_key(2))]
    assert looked[1] is not None


def _looking_around(runner) -> bool:
    return any(n.name == "Look Around" and n.status == Status.RUNNING for n in runner.root.iterate())


def test_a_pass_killed_while_looking_around_looks_around_there_again(office):
    """A stop's waypoint is marked visited once its Look Around is done: a pass killed in the
    middle of one goes back to that stop after the resume and looks around there again,
    rather than going on to the next waypoint with the stop half looked at."""
    killed: dict = {}

    def kill_mid_look(ctx):
        def hook(runner) -> None:
            killed["ticks"] = killed.get("ticks", 0) + 1 if _looking_around(runner) else 0
            if killed["ticks"] >= 5 and ctx.robot.now() > 0.2 * office["sim_time"]:  # a few ticks into a look
                killed["waypoint"], killed["at"] = ctx.traverse.current, ctx.robot.pose()
                raise Killed
        return hook

    resumed: dict = {}

    def first_look(ctx):
        def hook(runner) -> None:
            if "waypoint" not in resumed and _looking_around(runner):
                resumed["waypoint"], resumed["at"] = ctx.traverse.current, ctx.robot.pose()
        return hook

    site = shutil.copytree(office["base"], office["root"] / "killed-looking")
    with pytest.raises(Killed):
        run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], context_hooks=[kill_mid_look])
    result = run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], resume=True,
                             context_hooks=[first_look])
    assert result.succeeded and result.context.restored
    assert resumed["waypoint"] == killed["waypoint"]  # the same stop, not the next one
    assert resumed["at"].distance_to(killed["at"]) < 0.3
    assert evaluate_session(office["world"], site, 2, office["config"]).overall.f1 >= office["f1"] - 0.02


def test_a_resume_with_another_seed_is_refused(office):
    site = shutil.copytree(office["base"], office["root"] / "other-seed")
    with pytest.raises(Killed):
        run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], hooks=[kill_at(30.0)])
    result = subprocess.run(bomc_command("monitor", "--world", str(office["world"]), "--site", str(site),
                                         "--session", "2", "--seed", "5", "--resume", "--quiet"),
                            capture_output=True, text=True, cwd=REPO, env=bomc_env(), timeout=120)
    assert "--seed 2" in error_line(result)


def nothing_written(site, before: bytes) -> bool:
    """site.db as it was, and no write left in its write-ahead log (WAL mode: a write that was
    never checkpointed would leave site.db's bytes as they were)."""
    wal = site / "site.db-wal"
    return (site / "site.db").read_bytes() == before and (not wal.exists() or wal.stat().st_size == 0)


@pytest.mark.parametrize("key, corrupt", [
    (looked_sides_key(2), "8:bm90IGJpdHM="),  # eight sides of a mask that is not one
    (looked_key(2), "bm90IGJpdHM="),  # valid base64, not zlib
    (coverage_key(2), "eJwDAAAAAAE="),  # zlib of nothing: too short for the map
    (sightings_key(2), {"chair": "not base64!"}),
])
def test_a_resume_whose_saved_masks_are_corrupt_is_one_line_and_changes_nothing(office, key, corrupt):
    site = shutil.copytree(office["base"], office["root"] / f"corrupt-{key.split('/')[0]}")
    with pytest.raises(Killed):
        run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], hooks=[kill_at(60.0)])
    with SiteStore(site) as store:
        assert store.get_progress(key) is not None  # the waypoint snapshots saved it
        store.set_progress(key, corrupt)
    before = (site / "site.db").read_bytes()
    result = subprocess.run(bomc_command("monitor", "--world", str(office["world"]), "--site", str(site),
                                         "--session", "2", "--seed", "2", "--resume", "--quiet"),
                            capture_output=True, text=True, cwd=REPO, env=bomc_env(), timeout=120)
    assert result.returncode == 2 and f"progress.{key}" in error_line(result), result.stderr
    assert "Traceback" not in result.stderr and nothing_written(site, before)


def _spoil_robot(store) -> None:
    shell = store.get_progress(resume_key(2))
    shell["robot"]["true_pose"] = ["north", 0.0, 0.0]
    store.set_progress(resume_key(2), shell)


def _spoil_graph(store) -> None:
    store.set_progress(f"{resume_key(2)}/graph/last_seen", {"0": "yesterday"})


@pytest.mark.parametrize("spoil", [_spoil_robot, _spoil_graph])
def test_a_resume_whose_saved_robot_or_graph_state_is_corrupt_is_one_line_and_changes_nothing(office, spoil):
    site = shutil.copytree(office["base"], office["root"] / f"corrupt{spoil.__name__}")
    with pytest.raises(Killed):
        run.run_monitor(office["world"], site, 2, seed=2, config=office["config"], hooks=[kill_at(60.0)])
    with SiteStore(site) as store:
        spoil(store)
    before = (site / "site.db").read_bytes()
    result = subprocess.run(bomc_command("monitor", "--world", str(office["world"]), "--site", str(site),
                                         "--session", "2", "--seed", "2", "--resume", "--quiet"),
                            capture_output=True, text=True, cwd=REPO, env=bomc_env(), timeout=120)
    assert result.returncode == 2 and "progress.resume/2" in error_line(result), result.stderr
    assert "Traceback" not in result.stderr and nothing_written(site, before)


def test_kill_9_of_bomc_monitor_then_resume_gives_the_same_f1(office):
    """A real SIGKILL, after the intra-session change was applied; resumed by a second process."""
    site = shutil.copytree(office["base"], office["root"] / "kill-9")
    args = ("monitor", "--world", str(office["world"]), "--site", str(site), "--session", "2", "--seed", "2",
            "--quiet")
    proc = subprocess.Popen(bomc_command(*args), cwd=REPO, env=bomc_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    target = office["during"][0].at + 10.0
    deadline = time.monotonic() + 120
    while saved_robot_time(site, 2) < target and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL, "the pass ended before it could be killed"
    assert saved_robot_time(site, 2) >= target
    resumed = subprocess.run(bomc_command(*args, "--resume"), capture_output=True, text=True, cwd=REPO,
                             env=bomc_env(), timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert evaluate_session(office["world"], site, 2, office["config"]).overall.f1 == office["f1"]
