"""A pass's resume point is written as rows, each only when it changed (bomc_bt.resume_rows).

What a resume reads back must be the point of the moment of the last commit, whatever
rows that commit left alone; and a frame that changed little must write little (a whole
point a frame was 0.8 GB a pass on a 50 x 45 m office).
"""

from __future__ import annotations

import json

import pytest

from bomc_bt import monitoring, pass_resume, run
from bomc_bt.errors import BomcError
from bomc_bt.json_text import DROP, JSONMemo
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.pass_resume import resume_point
from bomc_bt.resume_rows import ResumeRows, load_resume_point, resume_key
from bomc_bt.store import SiteStore


class Rows:
    """The progress table as a dict, written the way the store writes it."""

    path = "site.db"

    def __init__(self) -> None:
        self.table: dict[str, str] = {}

    def apply(self, rows: dict) -> int:
        """Write ``rows``; the bytes written."""
        size = 0
        for key, value in rows.items():
            if value is DROP:
                self.table.pop(key, None)
            else:
                self.table[key] = value.text
                size += len(value.text)
        return size

    def progress_below(self, key: str) -> dict:
        return {k: json.loads(v) for k, v in self.table.items() if k == key or k.startswith(key + "/")}


def point(tiles: dict, fov: list, last_seen: dict, navigation=None) -> dict:
    memo = JSONMemo()
    return {"robot": {"steps": 5, "obstacles": {"tile": 256, "shape": [300, 600], "tiles": tiles, "version": 2},
                      "navigation": navigation},
            "graph": {"session": 1, "last_seen": memo.map("last_seen", last_seen.items()), "tentative": None},
            "frames": 3, "fov_since": fov, "looked_since": [], "sighted_since": []}


def plain(value) -> str:
    return json.dumps(json.loads(json.dumps(value, default=lambda v: json.loads(v.text))), sort_keys=True)


def test_a_moment_s_rows_read_back_as_its_point_and_unchanged_parts_are_not_written_again():
    writer, store = ResumeRows(), Rows()
    fov = [[[0.0, 0.0], [1.0, 0.5], [0.5, 1.0]]]
    tiles = {"0,0": "eJzT", "0,1": "eJyL"}
    first = point(tiles, fov, {3: 12.5})
    store.apply(writer.rows(1, first))
    writer.written()
    assert plain(load_resume_point(store, 1)) == plain(first)
    assert "resume/1/robot/obstacles/tiles/0,1" in store.table and "resume/1/graph/last_seen" in store.table

    assert writer.rows(1, point(dict(tiles), fov, {3: 12.5})) == {}  # nothing changed: nothing written
    writer.written()

    tiles2 = {"0,0": "eJzT", "0,1": "eJxz", "1,1": "eJwL"}  # one tile changed, one new
    fov.append([[2.0, 2.0], [3.0, 2.5], [2.5, 3.0]])
    second = point(tiles2, fov, {3: 12.5, 4: 20.0})
    rows = writer.rows(1, second)
    assert set(rows) == {resume_key(1), "resume/1/robot/obstacles/tiles/0,1", "resume/1/robot/obstacles/tiles/1,1",
                         "resume/1/graph/last_seen", "resume/1/fov_since/1"}
    store.apply(rows)
    writer.written()
    assert plain(load_resume_point(store, 1)) == plain(second)


def test_an_appended_list_writes_only_its_new_items_and_a_new_list_drops_the_old_ones():
    writer, store = ResumeRows(), Rows()
    fov: list = []
    for i in range(12):
        fov.append([[float(i), 0.0], [i + 1.0, 0.0], [float(i), 1.0]])
        rows = writer.rows(1, point({}, fov, {}))
        assert sorted(k for k in rows if k.startswith("resume/1/fov_since/")) == [f"resume/1/fov_since/{i}"]
        store.apply(rows)
        writer.written()
    assert load_resume_point(store, 1)["fov_since"] == fov

    rows = writer.rows(1, point({}, [], {}))  # a waypoint's commit starts the list again
    assert sorted(k for k, v in rows.items() if v is DROP) == sorted(f"resume/1/fov_since/{k}" for k in range(12))
    store.apply(rows)
    writer.written()
    assert load_resume_point(store, 1)["fov_since"] == []
    assert not any(k.startswith("resume/1/fov_since/") for k in store.table)


def test_rows_a_failed_commit_did_not_write_are_written_with_the_next():
    writer, store = ResumeRows(), Rows()
    store.apply(writer.rows(1, point({"0,0": "eJzT"}, [], {3: 1.0})))
    writer.written()
    lost = writer.rows(1, point({"0,0": "eJyL"}, [], {3: 2.0}))  # the transaction rolled back: not applied
    assert "resume/1/robot/obstacles/tiles/0,0" in lost
    later = point({"0,0": "eJyL"}, [], {3: 2.0})
    store.apply(writer.rows(1, later))
    writer.written()
    assert plain(load_resume_point(store, 1)) == plain(later)


def test_a_point_saved_whole_reads_as_it_is_and_a_missing_part_is_a_damaged_site(tmp_path):
    with SiteStore(tmp_path / "site") as store:
        whole = {"robot": None, "graph": {"session": 2}, "frames": 4, "fov_since": []}
        store.set_progress(resume_key(2), whole)  # a resume point saved before the split
        assert load_resume_point(store, 2) == whole
        assert load_resume_point(store, 3) is None
        writer = ResumeRows()
        store.record([], [], writer.rows(1, point({"0,0": "eJzT"}, [], {})))
        writer.written()
        assert load_resume_point(store, 1)["robot"]["obstacles"]["tiles"] == {"0,0": "eJzT"}
        store.record([], [], {"resume/1/graph/last_seen": DROP, "resume/10": {"frames": 1}})
        assert store.get_progress("resume/1/graph/last_seen") is None
        assert set(store.progress_below("resume/1")) == {"resume/1", "resume/1/robot/obstacles/tiles/0,0",
                                                         "resume/1/graph/session", "resume/1/graph/tentative"}
        with pytest.raises(BomcError, match="resume/1/graph/last_seen"):
            load_resume_point(store, 1)


def test_every_commit_of_two_passes_reads_back_as_the_pass_state_and_writes_a_fraction_of_it(tmp_path, monkeypatch):
    """Each frame's and each waypoint's rows, applied as the store applies them, read back as
    the whole point encoded plainly at that moment (the graph's maps from its state, not
    from the memo: a value changed in place would part them); the rows written are a small
    share of the whole point's text."""
    world = tmp_path / "office.yaml"
    generate_office(OfficeParams(width=16, height=12, seed=3, sessions=2), world)
    config = run.build_config()
    site = tmp_path / "site"
    assert run.run_build(world, site, seed=0, config=config).succeeded
    mirror, differ, sizes = Rows(), [], [0, 0]
    original = pass_resume.frame_progress

    def checked(perception, robot):
        rows = original(perception, robot)
        sizes[0] += mirror.apply(rows)
        expected = plain(resume_point(perception, robot))
        sizes[1] += len(expected)
        if plain(load_resume_point(mirror, perception.session)) != expected:
            differ.append((perception.session, perception.frames))
        return rows

    monkeypatch.setattr(pass_resume, "frame_progress", checked)
    monkeypatch.setattr(monitoring, "frame_progress", checked)
    for session in (1, 2):
        assert run.run_monitor(world, site, session, seed=session, config=config).succeeded
    assert differ == []
    assert sizes[1] > 5_000_000, "two passes of frames were checked"
    assert sizes[0] < 0.15 * sizes[1], sizes
    with SiteStore(site, readonly=True) as store:  # what the store holds is the mirror's
        assert plain(load_resume_point(store, 2)) == plain(load_resume_point(mirror, 2))
