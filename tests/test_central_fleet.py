# ruff: noqa: F811  (the fixtures are imported by name)
"""Issue 22's acceptance against a real PostgreSQL: kill -9 of a sync, the viewer over the central
store in Chromium, and two robots alternating six passes on one floor.

The server is ``tests/postgres_server.py``'s (initdb + pg_ctl on a free loopback port;
skipped, with the reason, where it cannot run). The kill and viewer tests use lab-b with
the perfect detector (``tests/central_sites.py``); the alternation runs a generated office
with the default (realistic, seeded) detector, since that is where a state not carried by a
pull would show.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys
from pathlib import Path

import psycopg
import pytest
from browser import Browser
from central_sites import central_state, lab_site, lab_site_2, perfect, run_pass_2  # noqa: F401  (fixtures)
from postgres_server import central_url, postgres  # noqa: F401  (fixtures)
from site_files import REPO, bomc_env, copy_site, snapshot

from bomc_bt import run
from bomc_bt.central.pull import pull_site
from bomc_bt.central.rows import read_central, read_local
from bomc_bt.central.site_files import local_files, local_generations, sha256
from bomc_bt.central.sync import sync_site
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.viewer import SiteView, serve_site
from bomc_bt.viewer.sections import category_hex

ARTIFACTS = REPO / "artifacts"
KILL_POINTS = REPO / "tests" / "kill_points.py"
STATE_TABLES = ("floors", "generations", "sessions", "nodes", "node_history", "progress", "files", "leases",
                "sync_log")
FLOOR = ("--building", "lab", "--floor", "2", "--robot", "r1")


# ------------------------------------------------------------------ kill -9 of a sync
def sync_killed_at(step: int, site: Path, url: str, count_file: Path) -> subprocess.CompletedProcess:
    """``bomc sync`` that kills itself with SIGKILL at ``step`` (0: never; the count goes to ``count_file``)."""
    command = [sys.executable, str(KILL_POINTS), str(step), str(count_file), "sync", str(site), "--to", url, *FLOOR]
    return subprocess.run(command, capture_output=True, text=True, cwd=REPO, env=bomc_env(), timeout=120)


def prepared(kind: str, lab_site: Path, lab_site_2: Path, folder: Path, url: str) -> Path:
    """The site about to be synced: ``first`` (never synced, empty database) or ``next`` (pass 2 after a sync)."""
    site = copy_site(lab_site, folder)
    if kind == "next":
        sync_site(site, url, building="lab", floor="2", robot="r1")
        run_pass_2(site, lab_site_2)
    return site


def test_kill_9_of_a_sync_at_ten_points_leaves_before_or_after_and_the_next_sync_completes_it(
        lab_site, lab_site_2, tmp_path, postgres):
    """Ten syncs killed with SIGKILL at points spread over the whole command (schema migration,
    statements, COPY rows, the commit, the site.json write): the central state is the one
    before or the one after, never a mix, and the next sync leaves the one after."""
    after, steps, commit_ends = {}, {}, {}
    for kind in ("first", "next"):  # a whole sync of each kind: its end state, its steps, its commit
        url = postgres.create_database()
        site = prepared(kind, lab_site, lab_site_2, tmp_path / f"whole-{kind}", url)
        count = tmp_path / f"count-{kind}"
        assert sync_killed_at(0, site, url, count).returncode == 0
        counted = json.loads(count.read_text())
        after[kind], steps[kind] = central_state(url, STATE_TABLES), counted["steps"]
        commit_ends[kind] = counted["after_transactions"][-1]  # the sync's own transaction ends last
        assert central_rows(url) == read_local(site / "site.db")
    # the step right after each kind's commit (the state after), and eight more drawn over both syncs
    rng = random.Random(22)
    drawn = rng.sample([(k, s) for k in steps for s in range(1, steps[k] + 1) if s != commit_ends[k]], 8)
    points = sorted([*commit_ends.items(), *drawn])
    outcomes = []
    for i, (kind, step) in enumerate(points):
        url = postgres.create_database()
        site = prepared(kind, lab_site, lab_site_2, tmp_path / f"killed-{i}", url)
        before = central_state(url, STATE_TABLES)
        killed = sync_killed_at(step, site, url, tmp_path / "unused")
        assert killed.returncode == -9, (kind, step, killed.stderr)
        state = central_state(url, STATE_TABLES)
        assert state in (before, after[kind]), f"{kind} sync killed at step {step}/{steps[kind]}: a mixed state"
        outcomes.append("after" if state == after[kind] else "before")
        assert (state == after[kind]) == (step >= commit_ends[kind]), (kind, step, commit_ends[kind])
        sync_site(site, url, building="lab", floor="2", robot="r1")  # the operator runs the same sync again
        assert central_state(url, STATE_TABLES) == after[kind], (kind, step)
        assert central_rows(url) == read_local(site / "site.db")
    assert {"before", "after"} <= set(outcomes), outcomes


def central_rows(url: str):
    with psycopg.connect(url) as conn:
        return read_central(conn, ("lab", "2", 1))


# ------------------------------------------------------------------ the viewer in Chromium
def rendered(browser: Browser, where: str, points: list[tuple[float, float]], shot: str | None = None) -> dict:
    """What the site page shows for ``where`` (a folder or a postgresql:// floor) once drawn:
    the sessions listed, the difference of 1 and 2, the legend, the canvas, its pixels at ``points``."""
    server = serve_site(where, port=0)
    try:
        browser.open(server.url)
        browser.wait_for("document.querySelector('#diff').dataset.ready === '1-2' && bomcViewer.state.map.img"
                         " && +document.querySelector('#map').dataset.draws > 0 && bomcHeatmap.state.settled",
                         what="the site drawn")
        # The map fills what the panels leave; their text (the site's name, a folder or a floor)
        # may wrap differently, so both pages draw at one fixed size to be compared pixel for pixel.
        browser.evaluate("(() => { const m = document.querySelector('#map'); Object.assign(m.style, {position: "
                         "'fixed', left: '0px', top: '0px', width: '720px', height: '540px'}); "
                         "bomcViewer.draw(); return true; })()")
        page = browser.evaluate("""(() => ({
            sessions: Array.from(document.querySelectorAll('#sessions li.session')).map(li => li.dataset.session),
            added: Array.from(document.querySelectorAll('#diff-added li[data-id]')).map(li => +li.dataset.id),
            removed: Array.from(document.querySelectorAll('#diff-removed li[data-id]')).map(li => +li.dataset.id),
            moved: Array.from(document.querySelectorAll('#diff-moved li[data-id]')).map(li => +li.dataset.id),
            legend: Array.from(document.querySelectorAll('#legend [data-category]')).map(s => s.dataset.category),
            canvas: document.querySelector('#map').toDataURL('image/png'),
        }))()""")
        page["pixels"] = [browser.evaluate(f"bomcViewer.pixelAtWorld({x}, {y})") for x, y in points]
        if shot:
            browser.screenshot(ARTIFACTS / shot)
        assert browser.errors == []
        return page
    finally:
        server.close()


def test_the_viewer_draws_a_floor_read_from_postgresql_in_chromium(browser, lab_site_2, tmp_path, central_url):
    site = copy_site(lab_site_2, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="A")
    floor = central_url + "?building=lab&floor=2"
    view = SiteView(floor)
    objects = view.sections()["site"]["sessions"][-1]["objects"]
    apart = [o for o in objects if all(o is p or abs(o["x"] - p["x"]) + abs(o["y"] - p["y"]) > 1.0 for p in objects)]
    assert apart, "lab-b should have an object a metre from every other"
    central = rendered(browser, floor, [(o["x"], o["y"]) for o in apart], shot="viewer_central_floor.png")
    # what a user sees: both sessions listed, the difference of 1 and 2, the objects in their colours
    diff = view.diff(1, 2)
    assert central["sessions"] == ["1", "2"]
    assert (central["added"], central["removed"], central["moved"]) == tuple(
        sorted(item["id"] for item in diff[kind]) for kind in ("added", "removed", "moved"))
    assert central["legend"] == sorted({o["category"] for o in objects})
    for o, colour in zip(apart, central["pixels"], strict=True):
        want = [int(category_hex(o["category"])[i:i + 2], 16) for i in (1, 3, 5)]
        assert all(abs(a - b) <= 12 for a, b in zip(colour[:3], want, strict=True)), (o, colour)
    # and the same page, pixel for pixel, as the robot's own folder gives
    assert rendered(browser, str(site), [(o["x"], o["y"]) for o in apart]) == central


# ------------------------------------------------------------------ two robots, six passes
SESSIONS = 6


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    """A generated 16 x 12 m office with changes in each of 6 sessions, built once (seed 0)."""
    root = tmp_path_factory.mktemp("fleet-office")
    world = root / "office.yaml"
    generate_office(OfficeParams(width=16, height=12, seed=7, sessions=SESSIONS), world)
    config = run.build_config()
    assert run.run_build(world, root / "built", seed=0, config=config).succeeded
    return {"world": world, "built": root / "built", "config": config}


def wall_times_dropped(sessions: list[tuple]) -> list[tuple]:
    """Session rows without ``started_wall`` and ``ended_wall``: the computer's clock, not the pass."""
    return [row[:2] + row[3:4] + row[5:] for row in sessions]


@pytest.mark.slow
def test_two_robots_alternating_six_passes_through_postgresql_build_one_robots_graph(office, tmp_path,
                                                                                     central_url):
    """CI's small representative of acceptance 1 (a larger office: benchmarks/bench_central_alternate.py).

    Robot A runs passes 1, 3, 5 and robot B passes 2, 4, 6, each pulling the floor first and
    syncing after; one robot alone runs passes 1-6 with the same seeds. The central graph
    (nodes, the whole history, sessions, resume state) and every report and plan file are
    the lone robot's, and the last robot's folder holds the lone robot's files byte for byte."""
    world, config = office["world"], office["config"]
    alone = copy_site(office["built"], tmp_path / "alone")
    for n in range(1, SESSIONS + 1):
        assert run.run_monitor(world, alone, n, seed=n, config=config).succeeded
    sync_site(copy_site(office["built"], tmp_path / "builder"), central_url, building="hq", floor="3",
              robot="builder")
    for n in range(1, SESSIONS + 1):
        robot = "A" if n % 2 else "B"
        pull_site(tmp_path / robot, central_url, "hq", "3", robot)
        assert run.run_monitor(world, tmp_path / robot, n, seed=n, config=config).succeeded
        sync_site(tmp_path / robot, central_url)
    expected = read_local(alone / "site.db")
    with psycopg.connect(central_url) as conn:
        got = read_central(conn, ("hq", "3", 1))
        robots = dict(conn.execute("SELECT number, robot FROM bomc.sessions").fetchall())
        files = dict(conn.execute("SELECT path, sha256 FROM bomc.files").fetchall())
    kinds = {row[4] for row in expected.node_history if row[2] > 1}
    assert kinds & {"added", "removed", "moved"}, "the office must change between passes"
    assert got.nodes == expected.nodes
    assert got.node_history == expected.node_history
    assert got.progress == expected.progress
    assert got.region_passes == expected.region_passes and expected.region_passes  # the change model travels
    assert wall_times_dropped(got.sessions) == wall_times_dropped(expected.sessions)
    assert robots == {n: "A" if n % 2 else "B" for n in range(1, SESSIONS + 1)}
    (generation,) = local_generations(alone)
    assert files == {name: sha256(path.read_bytes()) for name, path in local_files(generation).items()}
    skip = (".lock", "site.db", "site.db-wal", "site.db-shm", "site.json")
    assert snapshot(tmp_path / "B", skip=skip) == snapshot(alone, skip=skip)


class Killed(BaseException):
    """Raised from a tick hook: the robot's process dies between two ticks (as in test_exact_resume)."""


def killed_at(robot_time: float):
    def hook(runner) -> None:
        if runner.robot.now() >= robot_time:
            raise Killed
    return hook


@pytest.mark.slow
def test_a_pass_killed_on_one_robot_is_resumed_by_another_as_by_itself(office, tmp_path, central_url):
    """Robot A dies half-way through pass 1 and syncs what it saved; robot B pulls and resumes the
    pass: the central graph is the one A would have made by resuming the pass itself."""
    world, config = office["world"], office["config"]
    a = copy_site(office["built"], tmp_path / "A")
    sync_site(a, central_url, building="hq", floor="3", robot="A")
    with pytest.raises(Killed):
        run.run_monitor(world, a, 1, seed=1, config=config, hooks=[killed_at(60.0)])
    itself = copy_site(a, tmp_path / "itself")
    (itself / "site.json").unlink()  # A's own resume, off the fleet: the reference
    assert run.run_monitor(world, itself, 1, seed=1, config=config, resume=True).succeeded
    sync_site(a, central_url)  # the half pass: its session row, its history, its resume state
    pull_site(tmp_path / "B", central_url, "hq", "3", "B")
    resumed = run.run_monitor(world, tmp_path / "B", 1, seed=1, config=config, resume=True)
    assert resumed.succeeded and resumed.context.restored
    sync_site(tmp_path / "B", central_url)
    expected = read_local(itself / "site.db")
    with psycopg.connect(central_url) as conn:
        got = read_central(conn, ("hq", "3", 1))
    assert (got.nodes, got.node_history, got.progress) == (expected.nodes, expected.node_history, expected.progress)
    assert wall_times_dropped(got.sessions) == wall_times_dropped(expected.sessions)
    skip = (".lock", "site.db", "site.db-wal", "site.db-shm", "site.json")
    assert snapshot(tmp_path / "B", skip=skip) == snapshot(itself, skip=skip)
