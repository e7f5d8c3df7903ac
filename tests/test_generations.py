"""A site is never lost to a build (issue 18, item 1): map generations.

A re-build writes into ``generations/<n>.partial`` and becomes current in one step only
when it succeeds; a failed, killed or mistaken build leaves the site's map, trajectory and
build record byte-identical. A re-build over an object graph needs ``--new-map``, which
archives the graph with its map; sites built before generations keep working and are
adopted as generation 1.
"""

from __future__ import annotations

import errno
import json
import random
import signal
import subprocess
import time
from pathlib import Path

import pytest
from site_files import (
    LAB_B,
    REPO,
    bomc,
    bomc_command,
    bomc_env,
    build_files,
    copy_site,
    error_line,
    snapshot,
)

from bomc_bt import generations, run
from bomc_bt.errors import BomcError
from bomc_bt.evaluate_site import evaluate_session
from bomc_bt.site import Site, current_generation, generation_dir
from bomc_bt.site_lock import SiteLock
from bomc_bt.store import SiteStore


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """lab-b built once (40 s of robot time): generation 1, no graph."""
    if not LAB_B.exists():
        pytest.skip(f"shared data not found at {LAB_B} (set BOMC_SHARED to the shared folder)")
    site = tmp_path_factory.mktemp("built") / "site"
    result = run.run_build(LAB_B, site, seed=0)
    assert result.succeeded and current_generation(site) == 1
    return site


@pytest.fixture(scope="module")
def monitored(built, tmp_path_factory) -> Path:
    """The built site after monitor session 1: it has a graph."""
    site = copy_site(built, tmp_path_factory.mktemp("monitored") / "site")
    assert run.run_monitor(LAB_B, site, 1, seed=1).succeeded
    return site


def test_a_build_writes_generation_1_and_publishes_the_contract_files(built):
    assert build_files(built) == build_files(generation_dir(built, 1))
    assert (built / "map.yaml").read_text().startswith("image: map.pgm")
    assert not list((built / "generations").glob("*.partial"))


def test_a_negative_max_time_is_refused_before_anything_is_written(built, tmp_path):
    site = copy_site(built, tmp_path / "site")
    before = snapshot(site, skip=())
    line = error_line(bomc("build", "--world", str(LAB_B), "--site", str(site), "--quiet", "--max-time", "-5"))
    assert "--max-time" in line
    assert snapshot(site, skip=()) == before
    fresh = tmp_path / "fresh"
    error_line(bomc("build", "--world", str(LAB_B), "--site", str(fresh), "--max-time", "-5"))
    assert not fresh.exists()


def test_a_monitor_tree_given_to_a_build_and_back_is_refused(monitored, tmp_path):
    site = copy_site(monitored, tmp_path / "site")
    before = snapshot(site, skip=())
    line = error_line(bomc("build", "--world", str(LAB_B), "--site", str(site), "--quiet", "--new-map",
                           "--tree", str(REPO / "trees" / "monitor.yaml")))
    assert "not a build tree" in line and "--tree" in line
    line = error_line(bomc("monitor", "--world", str(LAB_B), "--site", str(site), "--quiet", "--session", "2",
                           "--tree", str(REPO / "trees" / "build.yaml")))
    assert "not a monitor tree" in line
    assert snapshot(site, skip=()) == before


def test_a_build_whose_tree_fails_leaves_the_site_as_it_was(built, tmp_path):
    site = copy_site(built, tmp_path / "site")
    tree = tmp_path / "failing.yaml"
    tree.write_text("version: 1\nname: failing\nroot:\n  sequence: Start Then Fail\n  memory: true\n  children:\n"
                    "    - behaviour: StartExploration\n    - behaviour: Fail\n      params: {message: broken}\n")
    before = build_files(site)
    result = run.run_build(LAB_B, site, max_time=20.0, tree=tree)
    assert not result.succeeded
    assert build_files(site) == before and current_generation(site) == 1
    assert build_files(Site(site).data) == before  # what bomc itself reads: still generation 1
    assert (site / "generations" / "2.partial" / "map.yaml").exists()  # the failed map, kept aside
    assert "keeps generation 1" in result.site_note
    assert run.run_build(LAB_B, site, seed=3).succeeded  # the next build (another seed) clears it away
    assert current_generation(site) == 2 and not (site / "generations" / "2.partial").exists()
    assert build_files(site) == build_files(generation_dir(site, 2)) != before


def test_a_build_that_runs_out_of_disk_leaves_the_site_as_it_was(built, tmp_path, monkeypatch):
    site = copy_site(built, tmp_path / "site")
    before = snapshot(site)

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("bomc_bt.build_record.save_map", full_disk)
    with pytest.raises(OSError):
        run.run_build(LAB_B, site)
    after = snapshot(site)
    assert {k: v for k, v in after.items() if not k.startswith("generations/2.partial")} == before
    SiteLock.acquire(site, "build").release()  # the failed build let go of the lock


def test_a_build_killed_at_random_moments_leaves_old_or_new_never_mixed(built, tmp_path):
    """SIGKILL 5 times at a random moment of a re-build: the old files byte-identical, or the new whole."""
    rng = random.Random(18)
    old = build_files(built)
    outcomes = []
    for attempt in range(5):
        site = copy_site(built, tmp_path / f"site{attempt}")
        proc = subprocess.Popen(bomc_command("build", "--world", str(LAB_B), "--site", str(site), "--quiet",
                                             "--max-time", "200", "--seed", str(attempt),
                                             "--explorer", "dwfe"),  # the slower explorer: kills land mid-build
                                env=bomc_env(), cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 60
        while not (site / "generations" / "2.partial").exists() and proc.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 1.2))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        current = current_generation(site)
        made = generation_dir(site, 2).is_dir()  # renamed from 2.partial: the build had finished (step 5b)
        if current == 1:
            outcomes.append("old")
            assert build_files(site) == old and build_files(Site(site).data) == old
        else:  # the kill came after the switch: the new generation, whole
            outcomes.append("new")
            assert current == 2 and build_files(Site(site).data) != old
        with SiteLock.acquire(site, "build"):  # what the next writer does first
            generations.recover(site)
        assert build_files(site) == build_files(Site(site).data)
        # a kill between the rename and the switch is rolled forward: the build had succeeded
        assert current_generation(site) == (2 if made else 1)
        current = current_generation(site)
        rows = (Site(site).data / "trajectory.csv").read_text().count("\n") - 1
        if current == 2:
            assert json.loads((Site(site).data / "build.json").read_text())["trajectory_points"] == rows
    assert "old" in outcomes, outcomes  # most kills land in the run, not after it


@pytest.mark.parametrize("crash_in", ["_complete", "_archive_graph", "_publish"])
def test_a_kill_between_the_commit_steps_is_finished_by_the_next_writer(monitored, tmp_path, monkeypatch,
                                                                         crash_in):
    """Kill after the rename (before the switch), after the switch, after the archive: recover rolls forward."""
    site = copy_site(monitored, tmp_path / "site")
    old = build_files(site)

    original = getattr(generations, crash_in)

    def killed(root, number):
        if crash_in == "_publish" and number != 2:  # the build's own recover() publishes generation 1 first
            return original(root, number)
        raise KeyboardInterrupt  # stands for the kill: nothing after this step runs

    with monkeypatch.context() as patch:
        patch.setattr(generations, crash_in, killed)
        with pytest.raises(KeyboardInterrupt):
            run.run_build(LAB_B, site, seed=7, new_map=True)  # another seed: another map
    reader = Site(site)  # a reader in between sees one generation whole, whichever
    assert build_files(reader.data) in (old, build_files(generation_dir(site, 2)))
    assert (generation_dir(site, 2) / "commit.json").exists()
    lock = generations.lock_for_monitor(site)  # the next writer command finishes the switch
    lock.release()
    assert current_generation(site) == 2 and not (generation_dir(site, 2) / "commit.json").exists()
    assert build_files(site) == build_files(generation_dir(site, 2)) != old
    assert not (site / "site.db").exists() and (generation_dir(site, 1) / "graph" / "site.db").exists()


def test_a_rebuild_over_a_graph_needs_new_map_then_archives_and_can_go_back(monitored, tmp_path):
    site = copy_site(monitored, tmp_path / "site")
    before = snapshot(site, skip=())
    line = error_line(bomc("build", "--world", str(LAB_B), "--site", str(site), "--quiet"))
    assert "--new-map" in line and "1 session" in line
    assert snapshot(site) == {k: v for k, v in before.items() if k != ".lock"}  # the lock's note is not data

    result = bomc("build", "--world", str(LAB_B), "--site", str(site), "--quiet", "--new-map")
    assert result.returncode == 0, result.stderr
    archive = generation_dir(site, 1) / "graph"
    assert current_generation(site) == 2 and "archived" in result.stderr
    assert not (site / "site.db").exists() and not (site / "sessions").exists()
    assert (archive / "site.db").read_bytes() == before["site.db"]
    assert build_files(generation_dir(site, 1)) == {k: before[k] for k in build_files(site)}
    with pytest.raises(BomcError, match="no object graph"):
        evaluate_session(LAB_B, site, 1, run.build_config())

    # Going back, as the README says: move the graph back, point `current` at 1.
    for item in archive.iterdir():
        item.rename(site / item.name)
    archive.rmdir()
    (site / "current").write_text("1\n")
    assert evaluate_session(LAB_B, site, 1, run.build_config()).overall.f1 > 0.9
    assert run.run_monitor(LAB_B, site, 2, seed=2).succeeded  # the writer republishes generation 1's files
    assert build_files(site) == build_files(generation_dir(site, 1))
    with SiteStore(site / "site.db", readonly=True) as store:
        assert [s.number for s in store.sessions()] == [1, 2]


def test_a_site_built_before_generations_still_works_and_is_adopted(built, tmp_path):
    site = copy_site(built, tmp_path / "site")
    (site / "current").unlink()
    for path in sorted((site / "generations").rglob("*"), reverse=True):
        path.rmdir() if path.is_dir() else path.unlink()
    (site / "generations").rmdir()
    old = build_files(site)
    assert Site(site).data == site
    assert run.run_monitor(LAB_B, site, 1, seed=1).succeeded
    assert evaluate_session(LAB_B, site, 1, run.build_config()).overall.f1 > 0.9
    assert not (site / "current").exists() and build_files(site) == old

    result = run.run_build(LAB_B, site, new_map=True)
    assert result.succeeded and current_generation(site) == 2
    assert build_files(generation_dir(site, 1)) == old  # adopted byte for byte
    assert (generation_dir(site, 1) / "graph" / "site.db").exists()
