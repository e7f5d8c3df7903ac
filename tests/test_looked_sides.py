"""From which sides a pass looked (issue 17): an object earlier passes looked at only from
sides it cannot be seen from (a door edge-on, a look-alike mistaken from a few sides) and that
this pass detected from another side is first seen, not added."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bomc_bt.errors import BomcError
from bomc_bt.first_seen import FIRST_SEEN, UNSEEN_SIDES, load_seen_before, seen_before_for
from bomc_bt.graph import AssociationParams, Event, Node
from bomc_bt.graph.view_sides import side_of
from bomc_bt.grid import OccupancyGrid
from bomc_bt.looked_sides import (
    LookedSides,
    face_sides,
    fan_sides,
    looked_sides_for,
    looked_sides_key,
    unpack_sides,
)
from bomc_bt.monitoring import Coverage
from bomc_bt.pass_resume import looked_key, pack_mask
from bomc_bt.store import SiteStore


def corridor() -> OccupancyGrid:
    """A 20 x 10 m floor at 0.05 m per cell with a wall along y = 6 m (a door's wall)."""
    data = np.zeros((200, 400), dtype=np.int8)
    data[120:122, :] = 100
    return OccupancyGrid(data, 0.05, (0.0, 0.0))


def fan(camera, start_deg: float, end_deg: float, reach: float = 5.0, columns: int = 40) -> np.ndarray:
    """A looked-at fan: the camera, then points at ``reach`` from ``start_deg`` to ``end_deg``."""
    a = np.radians(np.linspace(start_deg, end_deg, columns))
    return np.vstack([camera, np.c_[camera[0] + reach * np.cos(a), camera[1] + reach * np.sin(a)]])


@pytest.mark.parametrize("start, end", [(-30.0, 60.0), (150.0, 230.0), (-100.0, -20.0)])
def test_a_fan_is_cut_into_one_fan_per_side_each_the_side_its_cells_see_the_camera_from(start, end):
    grid = corridor()
    camera = np.array([10.0, 3.0])
    whole = LookedSides(grid, 8)
    polygon = fan(camera, start, end)
    parts = fan_sides(polygon, 8)
    assert len(parts) == len({s for s, _ in parts}) >= 2  # the fan spans more than one 45 degree sector
    for side, part in parts:  # a cell inside each part sees the camera from that part's side
        inner = camera + 0.6 * (part[1:].mean(axis=0) - camera)
        assert side_of(inner, camera, 8) == side
    whole.add(polygon)
    squares = whole.grid  # the looks are kept on squares of about 0.2 m
    assert squares.resolution == pytest.approx(0.2) and whole.bits.shape == (50, 100)
    import cv2

    filled = np.zeros(squares.data.shape, dtype=np.uint8)
    rows, cols = squares.world_to_cell(polygon[:, 0], polygon[:, 1])
    cv2.fillPoly(filled, [np.stack([cols, rows], axis=1).astype(np.int32)], 1)
    sided, looked = whole.bits > 0, filled > 0  # the same squares but a few on the cuts and the rim
    assert np.count_nonzero(sided ^ looked) <= 0.02 * np.count_nonzero(looked)
    ys, xs = np.nonzero(filled)
    x, y = squares.cell_to_world(ys, xs)
    far = np.hypot(x - camera[0], y - camera[1]) > 1.0
    expected = np.array([1 << side_of((a, b), camera, 8) for a, b in zip(x[far], y[far], strict=True)])
    wrong = (whole.bits[ys[far], xs[far]] & expected) == 0
    assert np.mean(wrong) < 0.05  # and those lie on a cut: a square's centre against its corner
    bearing = np.arctan2(y[far][wrong] - camera[1], x[far][wrong] - camera[0])
    off_cut = np.abs(np.remainder(bearing + np.pi / 8, np.pi / 4) - np.pi / 8)
    assert np.all(np.hypot(x[far][wrong] - camera[0], y[far][wrong] - camera[1]) * np.sin(off_cut)
                  <= squares.resolution * 1.5)


def test_bits_survive_packing_and_are_refused_for_another_count_of_sides():
    grid = corridor()
    sides = LookedSides(grid, 8)
    sides.add(fan(np.array([5.0, 3.0]), 0.0, 70.0))
    text = sides.packed()
    assert text.startswith("8:")
    assert np.array_equal(unpack_sides(text, sides.bits.shape, 8), sides.bits)
    with pytest.raises(ValueError):
        unpack_sides(text, sides.bits.shape, 16)
    with pytest.raises(ValueError):
        unpack_sides(text, grid.data.shape, 8)  # the map's own cells: not what was saved
    assert LookedSides(grid, 16).bits.dtype == np.uint16
    resumed, floor = LookedSides(grid, 8), np.zeros(grid.data.shape, dtype=np.uint8)
    resumed.restore(text, floor)  # a killed pass's snapshot
    assert np.array_equal(resumed.bits, sides.bits)
    floor[100:104, 200:204] = 1  # a snapshot without sides (or of another count): its floor, from every side
    for saved in (None, "16:" + text[2:]):
        older = LookedSides(grid, 8)
        older.restore(saved, floor)
        assert np.count_nonzero(older.bits) == 1 and older.bits[25, 50] == 255
    odd = OccupancyGrid(np.zeros((9, 11), dtype=np.int8), 0.05, (0.0, 0.0))  # not whole squares: 3 x 3 of them
    edge, corner = LookedSides(odd, 8), np.zeros((9, 11), dtype=bool)
    corner[8, 10] = True
    edge.restore(None, corner)
    assert edge.bits.shape == (3, 3) and np.argwhere(edge.bits).tolist() == [[2, 2]]
    assert looked_sides_for(grid, AssociationParams(face_on_deg=90.0)) is None
    assert looked_sides_for(grid, AssociationParams(mode="paper")) is None
    assert looked_sides_for(grid, AssociationParams(miss_sides=0)) is None
    assert looked_sides_for(grid, AssociationParams()).sides == 8


DOOR = np.array([12.0, 6.05, 1.0])  # in the wall at y = 6; its faces look along -y and +y


def door(node_id: int = 7) -> Node:
    """The door as a pass that saw it face-on maps it: a 0.9 x 0.05 m footprint along the wall."""
    return Node(node_id, "door", DOOR, 0.9, 2, 2, footprint=np.array([11.55, 6.02, 12.45, 6.08]))


def added_in_pass_2(node: Node) -> list[Event]:
    return [Event("added", node.id, node.category, node.position, 2, 10.0)]


def pass_along_the_wall() -> list[np.ndarray]:
    """Pass 1 drives along the corridor below the wall, camera ahead: the door only edge-on
    (60-80 degrees off its normal), never face-on."""
    return [fan(np.array([x, 5.0]), -20.0, 30.0) for x in np.arange(6.0, 10.5, 0.5)]


def stored(path: Path, grid: OccupancyGrid, fans: list[np.ndarray], sides: int = 8,
           save_sides: bool = True) -> SiteStore:
    """A store whose pass 1 looked with ``fans`` (its looked mask and, unless not, its side bits)."""
    looked, floor = LookedSides(grid, sides), Coverage(grid)
    for polygon in fans:
        looked.add(polygon)
        floor.add(polygon)
    store = SiteStore(path)
    store.begin_session(1, {"stamp": 0.0})
    keys = {looked_key(1): pack_mask(floor.seen)}
    if save_sides:
        keys[looked_sides_key(1)] = looked.packed()
    store.end_session(1, "succeeded", {"stamp": 1.0}, (), keys)
    return store


def test_face_sides_are_those_within_the_limit_of_either_face_normal_and_none_for_a_chair():
    assert face_sides(door(), 8, 45.0) == [1, 2, 5, 6]  # bearings -135..-45 and 45..135 degrees
    assert face_sides(door(), 8, 10.0) == []  # no side's middle that near: 22.5 degrees off
    assert face_sides(door(), 4, 45.0) == [0, 1, 2, 3]  # four 90 degree sides: each middle 45 degrees off
    chair = Node(8, "chair", np.array([3.0, 3.0, 0.45]), 0.9, 2, 2, footprint=np.array([2.75, 2.75, 3.25, 3.25]))
    assert face_sides(chair, 8, 45.0) == []


def test_a_door_looked_at_only_edge_on_before_is_first_seen_at_the_pass_end(tmp_path):
    grid = corridor()
    seen = load_seen_before(stored(tmp_path / "site", grid, pass_along_the_wall()), 2, grid, 0.3, sides=8,
                            face_deg=45.0)
    assert seen.saw(DOOR[:2])[0], "pass 1 looked at the door's place (the old judgement: added)"
    assert seen.verdict("door", DOOR) == {FIRST_SEEN: False}
    node = door()
    ((judged, verdict),) = seen.final_verdicts([node], added_in_pass_2(node))
    assert judged is node and verdict == {FIRST_SEEN: True, UNSEEN_SIDES: [1, 2, 5, 6]}
    # a pass 1 that also looked at it from in front (3 m off, 20 degrees from its normal): added
    in_front = load_seen_before(stored(tmp_path / "front", grid, [*pass_along_the_wall(),
                                                                  fan(np.array([11.0, 3.2]), 60.0, 110.0)]),
                                2, grid, 0.3, sides=8, face_deg=45.0)
    assert in_front.final_verdicts([node], added_in_pass_2(node)) == []
    # never looked at at all: first seen, as before
    far = door(9)
    far.position = np.array([18.5, 6.05, 1.0])
    far.footprint = far.footprint + np.array([6.5, 0.0, 6.5, 0.0])
    assert seen.final_verdicts([far], added_in_pass_2(far))[0][1] == {FIRST_SEEN: True}


def test_a_chair_is_added_wherever_an_earlier_pass_looked_at_its_place_from(tmp_path):
    """Not flat: a chair put where pass 1 looked, from whichever side, is an addition."""
    grid = corridor()
    seen = load_seen_before(stored(tmp_path / "site", grid, pass_along_the_wall()), 2, grid, 0.3, sides=8,
                            face_deg=45.0)
    chair = Node(8, "chair", np.array([10.5, 5.5, 0.45]), 0.9, 2, 2,
                 footprint=np.array([10.25, 5.25, 10.75, 5.75]))
    assert seen.saw(chair.position[:2])[0]
    assert seen.final_verdicts([chair], added_in_pass_2(chair)) == []


def test_without_saved_sides_with_another_count_or_turned_off_any_look_counts(tmp_path):
    grid = corridor()
    node = door()
    for name, sides, save, face_deg in (("old", 8, False, 45.0), ("other", 16, True, 45.0), ("off", 8, True, 90.0)):
        store = stored(tmp_path / name, grid, pass_along_the_wall(), sides=sides, save_sides=save)
        seen = seen_before_for(store, 2, grid, AssociationParams(face_on_deg=face_deg))
        assert seen.final_verdicts([node], added_in_pass_2(node)) == [], name
        assert (seen.side_seen is None) == (face_deg >= 90.0), name


def test_saved_sides_that_are_not_of_this_map_are_one_line_naming_the_key(tmp_path):
    grid = corridor()
    store = stored(tmp_path / "site", grid, pass_along_the_wall())
    store.set_progress(looked_sides_key(1), "8:bm90IGJpdHM=")
    with pytest.raises(BomcError) as err:
        load_seen_before(store, 2, grid, 0.3, sides=8, face_deg=45.0)
    assert "looked_sides/1" in str(err.value) and "\n" not in str(err.value)


def test_the_report_says_why_a_node_is_first_seen():
    """An operator reads one line per node: a door earlier passes looked at only edge-on is not
    "a place no earlier pass saw"."""
    from bomc_bt.net_changes import NetChange, net_changes

    base = [Event("added", 9, "chair", np.array([1.0, 1.0, 0.45]), 1, 1.0)]  # pass 1, so pass 2 has a before
    door_events = [Event("added", 7, "door", DOOR, 2, 10.0),
                   Event("updated", 7, "door", DOOR, 2, 90.0, detail={FIRST_SEEN: True, UNSEEN_SIDES: [1, 2, 5, 6]}),
                   Event("added", 8, "chair", np.array([3.0, 3.0, 0.45]), 2, 20.0,
                         detail={FIRST_SEEN: True, "sighted_in": 1}),
                   Event("added", 10, "chair", np.array([5.0, 3.0, 0.45]), 2, 30.0, detail={FIRST_SEEN: True}),
                   Event("added", 11, "chair", np.array([7.0, 3.0, 0.45]), 2, 40.0)]
    changes = {c.node_id: c for c in net_changes(base + door_events, 1, lambda _c: 0.7)}
    assert {n: (c.kind, c.first_seen_why) for n, c in changes.items()} == {
        7: ("first_seen", "edge_on"), 8: ("first_seen", "sighted"), 10: ("first_seen", "unseen"), 11: ("added", None)}
    assert "earlier passes looked at this place only edge-on to it" in changes[7].describe()
    assert "the previous pass had detected it here" in changes[8].describe()
    assert "no earlier pass saw this place" in changes[10].describe()
    again = NetChange.from_json(changes[7].to_json())  # a report read back (the viewer)
    assert (again.kind, again.first_seen_why, again.describe()) == ("first_seen", "edge_on", changes[7].describe())
    assert NetChange.from_json({**changes[10].to_json(), "first_seen_why": None}).describe() == changes[10].describe()


def test_bomc_changes_says_why_too_in_its_table_json_and_last_csv_column():
    from bomc_bt.site.formats import format_changes
    from bomc_bt.site.query import NodeChange, SessionChanges

    door = NodeChange(2, "first_seen", 7, "door", None, tuple(DOOR), 2, 90.0, first_seen_why="edge_on")
    result = [SessionChanges(2, 1, [door])]
    table = format_changes(result, "table").splitlines()
    assert table[0] == "session 2 (since session 1): 0 change(s), 1 first seen"
    assert table[1].startswith("  first_seen node 7 (door) at (12.00, 6.05) (earlier passes looked at this place "
                               "only edge-on to it)")
    header, row = format_changes(result, "csv").splitlines()[:2]
    assert header.split(",")[-2:] == ["back_of", "first_seen_why"] and row.split(",")[-1] == "edge_on"
    assert '"first_seen_why": "edge_on"' in format_changes(result, "json")
