# ruff: noqa: F811  (the server fixtures are imported by name)
"""The central PostgreSQL store (issue 22): sync, pull, the floor lease, and the read-only commands over it.

Against a real PostgreSQL server started by ``tests/postgres_server.py`` (initdb + pg_ctl
on a free loopback port; skipped, with the reason, where it cannot run). Sites are lab-b
with the perfect detector: a build and a pass take seconds.
"""

from __future__ import annotations

import json

import psycopg
import pytest
from central_sites import central_state, lab_site, lab_site_2, monitor, perfect, run_pass_2  # noqa: F401  (fixtures)
from postgres_server import central_url, postgres  # noqa: F401  (fixtures)
from site_files import LAB_B, bomc, copy_site, error_line

from bomc_bt import run
from bomc_bt.central import schema
from bomc_bt.central.rows import read_central, read_local
from bomc_bt.central.sync import sync_site
from bomc_bt.store import SiteStore


def central_rows(url: str, building: str, floor: str, generation: int = 1):
    with psycopg.connect(url) as conn:
        return read_central(conn, (building, floor, generation))


def test_sync_is_idempotent_and_mirrors_the_site(lab_site, tmp_path, central_url):
    site = copy_site(lab_site, tmp_path / "a")
    first = bomc("sync", str(site), "--to", central_url, "--building", "lab", "--floor", "2", "--robot", "r1")
    assert first.returncode == 0, first.stderr
    assert "history rows" in first.stdout
    state = central_state(central_url)
    again = bomc("sync", str(site), "--to", central_url)
    assert again.returncode == 0 and "already up to date" in again.stdout, again
    assert central_state(central_url) == state
    assert central_rows(central_url, "lab", "2") == read_local(site / "site.db")
    nodes = central_rows(central_url, "lab", "2").nodes
    assert nodes and all(None not in row[-2:] for row in nodes)  # each node's colour (cr, cg) travels too
    assert json.loads((site / "site.json").read_text())["robot"] == "r1"
    assert "password" not in (site / "site.json").read_text()


def test_a_failed_sync_leaves_the_central_state_and_the_next_completes_it(lab_site, lab_site_2, tmp_path,
                                                                          central_url, monkeypatch):
    site = copy_site(lab_site, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="r1")
    before = central_state(central_url)
    run_pass_2(site, lab_site_2)
    from bomc_bt.central import sync as sync_module

    def network_gone(*args, **kwargs):  # the graph's rows are sent by now, in the open transaction
        raise psycopg.OperationalError("connection lost (injected)")

    monkeypatch.setattr(sync_module, "_push_files", network_gone)
    with pytest.raises(Exception, match="injected"):
        sync_site(site, central_url)
    assert central_state(central_url) == before
    monkeypatch.undo()
    sync_site(site, central_url)
    assert central_rows(central_url, "lab", "2") == read_local(site / "site.db")


def test_kill_9_in_the_middle_of_a_sync_then_repeat(lab_site, lab_site_2, tmp_path, central_url):
    """A sync killed with every row of the new pass sent but not committed: the central state
    is the one before it, and the next sync completes it.

    The test holds the sync log's table lock, so the sync stops at its last statement, inside
    its transaction, until it is killed."""
    import subprocess
    import time

    from site_files import bomc_command, bomc_env

    site = copy_site(lab_site, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="r1")
    run_pass_2(site, lab_site_2)
    before = central_state(central_url)
    with psycopg.connect(central_url) as blocker:
        blocker.execute("LOCK TABLE bomc.sync_log IN EXCLUSIVE MODE")
        proc = subprocess.Popen(bomc_command("sync", str(site), "--to", central_url), env=bomc_env(),
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with psycopg.connect(central_url, autocommit=True) as watch:
            for _ in range(600):  # until the sync waits on the lock with its rows sent
                waiting = watch.execute("SELECT count(*) FROM pg_stat_activity WHERE application_name = 'bomc'"
                                        " AND wait_event_type = 'Lock'").fetchone()[0]
                if waiting or proc.poll() is not None:
                    break
                time.sleep(0.1)
            assert waiting, "the sync never reached its last statement"
            proc.kill()
            proc.wait()
        blocker.rollback()
    assert central_state(central_url) == before
    sync_site(site, central_url)
    assert central_rows(central_url, "lab", "2") == read_local(site / "site.db")


def test_incremental_sync_pushes_only_the_new_pass(lab_site, lab_site_2, tmp_path, central_url):
    site = copy_site(lab_site, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="r1")
    rows_before = len(read_local(site / "site.db").node_history)
    run_pass_2(site, lab_site_2)
    new_rows = len(read_local(site / "site.db").node_history) - rows_before
    result = sync_site(site, central_url)
    assert result.pushed["history rows"] == new_rows > 0
    assert result.pushed["sessions"] == 1  # session 2; session 1's row is unchanged
    assert central_rows(central_url, "lab", "2") == read_local(site / "site.db")


def test_two_robots_alternate_through_the_central_store(lab_site, lab_site_2, tmp_path, central_url, perfect):
    """Robot A passes 1 and 3, robot B pass 2 (pulled); the central graph is the one robot's graph."""
    alone = copy_site(lab_site_2, tmp_path / "alone")
    assert run.run_monitor(LAB_B, alone, 3, seed=3, config=run.build_config([str(perfect)])).succeeded
    a = copy_site(lab_site, tmp_path / "a")
    synced = bomc("sync", str(a), "--to", central_url, "--building", "lab", "--floor", "2", "--robot", "A")
    assert synced.returncode == 0, synced.stderr
    pulled = bomc("pull", "--from", central_url, "--building", "lab", "--floor", "2", "--robot", "B",
                  str(tmp_path / "b"))
    assert pulled.returncode == 0, pulled.stderr
    b = tmp_path / "b"
    assert (b / "map.pgm").read_bytes() == (a / "map.pgm").read_bytes()
    assert monitor(b, 2, perfect).returncode == 0
    assert bomc("sync", str(b), "--to", central_url).returncode == 0
    # A has not seen pass 2: its pass and its sync are refused until it pulls
    assert "bomc pull" in error_line(monitor(a, 2, perfect))
    assert bomc("pull", "--from", central_url, "--building", "lab", "--floor", "2", str(a)).returncode == 0
    assert monitor(a, 3, perfect).returncode == 0
    assert bomc("sync", str(a), "--to", central_url).returncode == 0
    with SiteStore(alone / "site.db", readonly=True) as reference:
        expected = {n: reference.graph_after(n) for n in (1, 2, 3)}
    from bomc_bt.central.reader import CentralGraph

    central = CentralGraph(central_url + "?building=lab&floor=2")
    for n in (1, 2, 3):
        got = central.graph_after(n)
        assert [(x.id, x.category, x.position.tolist()) for x in got] == \
               [(x.id, x.category, x.position.tolist()) for x in expected[n]], n
    with psycopg.connect(central_url) as conn:
        robots = dict(conn.execute("SELECT number, robot FROM bomc.sessions").fetchall())
    assert robots == {1: "A", 2: "B", 3: "A"}


def test_the_lease_refuses_a_second_robot_until_it_expires(lab_site, tmp_path, central_url, perfect):
    a = copy_site(lab_site, tmp_path / "a")
    sync_site(a, central_url, building="lab", floor="2", robot="A")
    with psycopg.connect(central_url) as conn:
        conn.execute("INSERT INTO bomc.leases VALUES ('lab', '2', 'B', 'host-b', 4242, 'bomc monitor', now(),"
                     " now() + interval '5 minutes')")
    refused = error_line(monitor(a, 2, perfect))
    assert "'B'" in refused and "host-b" in refused and "4242" in refused
    assert len(SiteStore(a / "site.db", readonly=True).sessions()) == 1  # nothing was written
    with psycopg.connect(central_url) as conn:
        conn.execute("UPDATE bomc.leases SET expires_at = now() - interval '1 second'")
    done = monitor(a, 2, perfect)
    assert done.returncode == 0, done.stderr
    with psycopg.connect(central_url) as conn:
        assert conn.execute("SELECT count(*) FROM bomc.leases").fetchone()[0] == 0  # released at the end


def test_evaluate_and_view_read_the_central_store_as_the_site(lab_site_2, tmp_path, central_url):
    site = copy_site(lab_site_2, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="A")
    url = central_url + "?building=lab&floor=2"
    for n in (1, 2):
        local = bomc("evaluate", "--world", str(LAB_B), "--site", str(site), "--session", str(n), "--json")
        central = bomc("evaluate", "--world", str(LAB_B), "--site", url, "--session", str(n), "--json")
        assert central.returncode == 0, central.stderr
        assert json.loads(central.stdout) == json.loads(local.stdout)
    from bomc_bt.viewer.site import SiteView

    here, there = SiteView(site), SiteView(url)
    ours, theirs = here.sections()["site"], there.sections()["site"]
    for key in ("build", "sessions", "path", "waypoints", "default_diff"):
        assert theirs[key] == ours[key], key
    assert there.grid.data.tobytes() == here.grid.data.tobytes()
    assert there.diff(1, 2) == here.diff(1, 2)


def test_an_old_schema_is_migrated_in_place(lab_site, tmp_path, central_url):
    with psycopg.connect(central_url) as conn:
        conn.execute("CREATE SCHEMA bomc")
        conn.execute("CREATE TABLE bomc.schema_version (version integer NOT NULL)")
        conn.execute("INSERT INTO bomc.schema_version VALUES (1)")
        for statement in schema._statements(schema.MIGRATIONS[1]):
            conn.execute(statement)
        conn.execute("INSERT INTO bomc.floors VALUES ('old', '1', NULL)")
    site = copy_site(lab_site, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="A")
    with psycopg.connect(central_url) as conn:
        assert conn.execute("SELECT version FROM bomc.schema_version").fetchone()[0] == schema.VERSION
        assert conn.execute("SELECT count(*) FROM bomc.floors").fetchone()[0] == 2  # the old row is kept
        assert conn.execute("SELECT to_regclass('bomc.leases')").fetchone()[0] is not None


def test_bad_inputs_are_one_line_errors(lab_site, tmp_path, central_url, postgres):  # noqa: F811
    site = copy_site(lab_site, tmp_path / "a")
    assert "central store error" in error_line(bomc("sync", str(site), "--to", "postgresql://bomc@127.0.0.1:1/x"))
    assert "no floor" in error_line(bomc("pull", "--from", central_url, "--building", "x", "--floor", "1",
                                         str(tmp_path / "new")))
    assert not (tmp_path / "new").exists()
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    assert "not empty" in error_line(bomc("pull", "--from", central_url, "--building", "lab", "--floor", "2",
                                          str(tmp_path / "busy")))
    sync_site(site, central_url, building="lab", floor="2", robot="A")
    assert "site.json" in error_line(bomc("sync", str(site), "--to", central_url, "--floor", "3"))
    assert "building=B&floor=F" in error_line(bomc("evaluate", "--world", str(LAB_B), "--site", central_url,
                                                   "--session", "1"))
    assert "--building" in error_line(bomc("sync", str(site), "--to", central_url, "--building", "a/b"))


def test_the_viewer_serves_a_floor_of_the_central_store(lab_site_2, tmp_path, central_url):
    import urllib.request

    from bomc_bt.viewer import serve_site

    site = copy_site(lab_site_2, tmp_path / "a")
    sync_site(site, central_url, building="lab", floor="2", robot="A")
    pages = []
    for where in (str(site), central_url + "?building=lab&floor=2"):
        server = serve_site(where, port=0)
        try:
            state = json.loads(urllib.request.urlopen(server.url + "state.json", timeout=10).read())
            png = urllib.request.urlopen(server.url + "map.png", timeout=10).read()
        finally:
            server.close()
        pages.append((state["sections"]["site"]["sessions"], png))
    assert pages[1] == pages[0]
    assert [s["number"] for s in pages[1][0]] == [1, 2]


def test_sync_without_a_store_named_is_a_one_line_error(tmp_path):
    (tmp_path / "s").mkdir()
    result = subprocess_bomc_without_env("sync", str(tmp_path / "s"))
    assert "BOMC_CENTRAL" in error_line(result)


def subprocess_bomc_without_env(*args: str):
    import os
    import subprocess

    from site_files import REPO, bomc_command

    env = {k: v for k, v in os.environ.items() if k not in ("BOMC_CENTRAL", "PGHOST", "PGDATABASE", "PGSERVICE")}
    env["PYTHONPATH"] = str(REPO)
    return subprocess.run(bomc_command(*args), capture_output=True, text=True, cwd=REPO, env=env, timeout=120)
