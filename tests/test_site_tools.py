"""Operator tools on a finished site (issue 19): queries, formats, exports, corrections.

One lab-b site is built and monitored with the perfect detector (seconds); tests that
change a site work on a copy. The formats are parsed back (JSON, CSV, GeoJSON checked
against its RFC 7946 structure, the PNG and its world file against the saved map).
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from site_files import LAB_B, REPO, bomc, bomc_command, bomc_env, copy_site, error_line, snapshot

from bomc_bt import cli, run
from bomc_bt.evaluate_changes import evaluate_changes
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, load_map
from bomc_bt.site import Site, open_site
from bomc_bt.site_lock import SiteLock
from bomc_bt.store import SiteStore

PERFECT = "detector: {preset: perfect}\n"


def config(tmp: Path, text: str = PERFECT):
    path = tmp / "extra.yaml"
    path.write_text(text)
    return run.build_config([str(path)])


@pytest.fixture(scope="module")
def sites(tmp_path_factory) -> dict[int, Path]:
    """lab-b after session 1, and a copy taken on to session 2 (perfect detector)."""
    if not LAB_B.exists():
        pytest.skip(f"shared data not found at {LAB_B} (set BOMC_SHARED to the shared folder)")
    root = tmp_path_factory.mktemp("tools")
    cfg = config(root)
    one = root / "one"
    assert run.run_build(LAB_B, one, seed=0, config=cfg, quiet=True).succeeded
    assert run.run_monitor(LAB_B, one, 1, seed=1, config=cfg, quiet=True).succeeded
    two = copy_site(one, root / "two")
    assert run.run_monitor(LAB_B, two, 2, seed=2, config=cfg, quiet=True).succeeded
    return {1: one, 2: two}


def bomc_here(capsys, *args: str) -> subprocess.CompletedProcess:
    """``bomc ARGS`` in this process (no interpreter start-up): exit code, stdout, stderr."""
    capsys.readouterr()
    try:
        code = cli.main(list(args))
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    out = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, out.out, out.err)


def cli_json(*args: str):
    result = bomc(*args)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


# ------------------------------------------------------------------------ queries
def test_objects_api_cli_and_every_format_agree(sites):
    site = sites[2]
    with open_site(site) as reader:
        now = reader.objects()
        first = reader.objects(session=1)
    assert len(first) == 12 and len(now) == 9  # lab-b: 12 objects, session 2 takes 3 away
    assert {o.category for o in now} >= {"chair", "cabinet", "person"}
    by_id = {o.id: o for o in now}
    listed = cli_json("objects", str(site), "--format", "json")
    assert [o["id"] for o in listed["objects"]] == sorted(by_id)
    for o in listed["objects"]:
        assert o["position"] == pytest.approx(by_id[o["id"]].position, abs=1e-3)
        assert o["first_seen"] <= o["last_seen"] and o["sessions_seen"][-1] == o["last_seen"]
    # the objects that stayed were seen in both passes, the people who moved are new in 2
    assert {tuple(o["sessions_seen"]) for o in listed["objects"]} == {(1, 2), (2,)}
    rows = list(csv.DictReader(io.StringIO(bomc("objects", str(site), "--format", "csv").stdout)))
    assert [int(r["id"]) for r in rows] == sorted(by_id)
    assert all(float(r["x"]) == pytest.approx(by_id[int(r["id"])].position[0], abs=1e-3) for r in rows)
    collection = cli_json("objects", str(site), "--format", "geojson")
    check_geojson(collection)
    assert {f["id"] for f in collection["features"]} == set(by_id)
    assert collection["frame"] == "map" and collection["units"] == "m"
    table = bomc("objects", str(site)).stdout.splitlines()
    assert table[0].split()[:3] == ["id", "category", "x"] and len(table) == 1 + len(now)


def check_geojson(collection: dict) -> None:
    """RFC 7946 structure of a FeatureCollection of Points."""
    assert collection["type"] == "FeatureCollection" and isinstance(collection["features"], list)
    for feature in collection["features"]:
        assert feature["type"] == "Feature" and isinstance(feature["properties"], dict)
        assert isinstance(feature["id"], (int, str))
        geometry = feature["geometry"]
        assert geometry["type"] == "Point" and len(geometry["coordinates"]) in (2, 3)
        assert all(isinstance(v, (int, float)) and math.isfinite(v) for v in geometry["coordinates"])
        assert "position" not in feature["properties"] and "category" in feature["properties"]


def test_filters_by_session_category_and_distance(sites):
    site = sites[2]
    chairs = cli_json("objects", str(site), "--category", "chair", "--format", "json")["objects"]
    assert chairs and {o["category"] for o in chairs} == {"chair"}
    with open_site(site) as reader:
        everything = reader.objects()
    x, y = everything[0].position[:2]
    near = cli_json("objects", str(site), "--near", f"{x},{y}", "--radius", "2.5", "--format", "json")["objects"]
    expected = sorted((math.hypot(o.position[0] - x, o.position[1] - y), o.id) for o in everything)
    assert [o["id"] for o in near] == [i for d, i in expected if d <= 2.5]
    assert [o["distance"] for o in near] == sorted(o["distance"] for o in near)
    old = cli_json("objects", str(site), "--session", "1", "--category", "trash bin", "--format", "json")
    assert len(old["objects"]) == 2 and old["session"] == 1  # both bins were there in session 1 ...
    assert cli_json("objects", str(site), "--category", "trash bin", "--format", "json")["objects"] == []  # not now


@pytest.mark.parametrize("args, words", [
    (("--session", "7"), "session 7 was not recorded"),
    (("--session", "0"), "must be >= 1"),
    (("--category", "sofa"), "no object of category 'sofa'"),
    (("--radius", "2"), "--radius needs --near"),
    (("--near", "1,nan"), "--near must be finite"),
    (("--near", "1,2", "--radius", "-1"), "positive number"),
    (("--format", "xml"), "invalid choice"),
])
def test_bad_query_input_is_one_line_and_exit_2(sites, capsys, args, words):
    assert words in error_line(bomc_here(capsys, "objects", str(sites[2]), *args))


def test_queries_on_a_missing_site_or_one_without_a_graph(tmp_path):
    assert "not a site directory" in error_line(bomc("objects", str(tmp_path / "nowhere")))
    assert "no object graph here" in error_line(bomc("changes", str(tmp_path)))


def test_changes_net_per_node_with_evidence(sites):
    site = sites[2]
    result = cli_json("changes", str(site), "--format", "json")["sessions"]
    assert [s["session"] for s in result] == [1, 2] and result[0]["previous_session"] is None
    assert {c["kind"] for c in result[0]["changes"]} == {"added"} and len(result[0]["changes"]) == 12
    second = cli_json("changes", str(site), "--since", "1", "--format", "json")["sessions"]
    assert len(second) == 1 and second[0]["previous_session"] == 1
    changes = second[0]["changes"]
    removed = [c for c in changes if c["kind"] == "removed"]
    # the same netting as `bomc evaluate`: bins and umbrella, and person-2, who went 7 m (beyond
    # association.move_radius: a removal and an addition); person-1's 2.5 m is a move
    scored = evaluate_changes(LAB_B, site, 2, config(site.parent))
    assert len(removed) == scored.kinds["removed"].mapped == 4
    assert len([c for c in changes if c["kind"] == "moved"]) == scored.kinds["moved"].mapped
    assert len([c for c in changes if c["kind"] == "added"]) == scored.kinds["added"].mapped
    confirm = run.build_config().association.confirm_misses
    for c in removed:  # evidence: the frames that saw it missing, and when it was last seen
        assert c["missing_frames"] >= confirm and not c["merged"]
        assert c["last_seen_session"] == 1 and c["last_seen_stamp"] > 0 and c["new"] is None
    assert all(c["last_seen_session"] == 2 for c in changes if c["kind"] == "added")
    rows = list(csv.DictReader(io.StringIO(bomc("changes", str(site), "--since", "1", "--format", "csv").stdout)))
    assert len(rows) == len(changes) and {r["kind"] for r in rows} == {"removed", "added", "moved"}
    text = bomc("changes", str(site), "--since", "1").stdout
    assert "session 2 (since session 1)" in text and re.search(r"missing in \d+ frame\(s\)", text)
    assert "must be before" in error_line(bomc("changes", str(site), "--since", "2", "--until", "1"))
    assert "from 0 to 2" in error_line(bomc("changes", str(site), "--until", "5"))


def test_a_node_removed_and_found_again_in_one_pass_is_no_change(tmp_path):
    """Net, not raw: a removal undone within the pass (a move back) is not listed."""
    from bomc_bt.graph import AssociationParams, Observation

    params = AssociationParams(confirm_detections=1, confirm_misses=1, confirm_interval=0.0)
    with SiteStore(tmp_path) as store:
        graph = store.load_graph(params)
        store.begin_session(1, {"stamp": 0.0})
        store.record(graph.associate([Observation("chair", [1.0, 1.0, 0.4], 0.9)], [], 1, 0.0), graph.drain_changed())
        store.end_session(1, "succeeded", {"stamp": 1.0})
        store.begin_session(2, {"stamp": 0.0})
        store.record(graph.associate([], [0], 2, 0.0), graph.drain_changed())  # missed: removed
        store.record(graph.associate([Observation("chair", [1.1, 1.0, 0.4], 0.9)], [], 2, 1.0),
                     graph.drain_changed())  # seen again: kept its id ("moved" back)
        store.end_session(2, "succeeded", {"stamp": 2.0})
        kinds = [e.kind for e in store.events(session=2)]
    assert "removed" in kinds and "moved" in kinds
    with open_site(tmp_path) as reader:
        (session,) = reader.changes(since=1)
    assert session.changes == []


def test_a_move_across_a_pass_says_how_far_and_when_last_seen(tmp_path):
    from bomc_bt.graph import AssociationParams, Observation

    params = AssociationParams(confirm_detections=1, confirm_misses=1, confirm_interval=0.0)
    with SiteStore(tmp_path) as store:
        graph = store.load_graph(params)
        store.begin_session(1, {"stamp": 0.0})
        store.record(graph.associate([Observation("chair", [1.0, 1.0, 0.4], 0.9)], [], 1, 5.0), graph.drain_changed())
        store.end_session(1, "succeeded", {"stamp": 9.0})
        store.begin_session(2, {"stamp": 0.0})
        store.record(graph.associate([], [0], 2, 3.0), graph.drain_changed())
        store.record(graph.associate([Observation("chair", [3.0, 1.0, 0.4], 0.9)], [], 2, 4.0),
                     graph.drain_changed())
        store.end_session(2, "succeeded", {"stamp": 6.0})
    with open_site(tmp_path) as reader:
        (session,) = reader.changes(since=1)
    (move,) = session.changes
    assert (move.kind, move.node_id, move.moved_m) == ("moved", 0, pytest.approx(2.0))
    assert (move.last_seen_session, move.last_seen_stamp) == (2, 4.0) and move.missing_frames is None


# ------------------------------------------------------------------------ exports
def test_export_writes_geojson_csv_and_a_png_that_its_world_file_places(sites, tmp_path):
    site, out = sites[2], tmp_path / "export"
    before = snapshot(site, mtimes=True, skip=())
    result = bomc("export", str(site), "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert snapshot(site, mtimes=True, skip=()) == before
    check_geojson(json.loads((out / "objects.geojson").read_text()))
    assert len(list(csv.DictReader((out / "objects.csv").open()))) == 9
    grid = load_map(Site(site).map_yaml)
    png = cv2.imread(str(out / "map.png"), cv2.IMREAD_UNCHANGED)
    assert png.shape == grid.data.shape and png.dtype == np.uint8
    a, d, b, e, c, f = (float(v) for v in (out / "map.pgw").read_text().split())
    assert (a, d, b, e) == (grid.resolution, 0.0, 0.0, -grid.resolution)
    rng = np.random.default_rng(0)
    rows, cols = rng.integers(0, png.shape[0], 500), rng.integers(0, png.shape[1], 500)
    x, y = c + a * cols, f + e * rows  # the world file's pixel centres in map metres
    grid_rows, grid_cols = grid.world_to_cell(x, y)
    assert np.array_equal(grid_cols, cols) and np.array_equal(grid_rows, png.shape[0] - 1 - rows)
    colour = {FREE: 254, OCCUPIED: 0, UNKNOWN: 205}
    assert all(png[r, q] == colour[int(grid.data[gr, q])] for r, q, gr in zip(rows, cols, grid_rows, strict=True))
    # the objects land on the map: every object's cell is inside the image
    for feature in json.loads((out / "objects.geojson").read_text())["features"]:
        px, py = feature["geometry"]["coordinates"][:2]
        assert 0 <= round((px - c) / a) < png.shape[1] and 0 <= round((py - f) / e) < png.shape[0]


# --------------------------------------------------------------- read-only site
def test_queries_and_export_work_on_a_site_nobody_may_write(sites):
    from test_site_lock import _as_nobody

    prefix = _as_nobody()
    if prefix is None:
        pytest.skip("running as root, and nobody cannot run bomc from this checkout: cannot drop the "
                    "permission to write")
    parent = Path(tempfile.mkdtemp(prefix="bomc-ro-"))
    try:
        parent.chmod(0o755)
        site = copy_site(sites[2], parent / "site")
        out = parent / "out"
        out.mkdir()
        out.chmod(0o777)
        subprocess.run(["chmod", "-R", "a-w", str(site)], check=True)
        before = snapshot(site, mtimes=True, skip=())
        env = {**bomc_env(), "HOME": str(parent)}
        for args in (("objects", str(site), "--format", "geojson"), ("changes", str(site)),
                     ("export", str(site), "--out", str(out))):
            result = subprocess.run(prefix + bomc_command(*args), capture_output=True, text=True, cwd=REPO,
                                    env=env, timeout=120)
            assert result.returncode == 0, (args, result.stderr)
        edit = subprocess.run(prefix + bomc_command("edit", str(site), "delete", "1"), capture_output=True,
                              text=True, cwd=REPO, env=env, timeout=120)
        assert "cannot lock the site for writing" in error_line(edit)
        assert snapshot(site, mtimes=True, skip=()) == before
    finally:
        subprocess.run(["chmod", "-R", "u+w", str(parent)], check=False)
        shutil.rmtree(parent, ignore_errors=True)


def test_a_query_takes_no_lock_and_runs_beside_a_writer(sites):
    with SiteLock.acquire(sites[2], "monitor"):
        assert bomc("objects", str(sites[2])).returncode == 0
        assert "another writer holds this site" in error_line(bomc("edit", str(sites[2]), "delete", "1"))
