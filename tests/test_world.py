"""World files: loading, timeline semantics, the wall rule, validation messages, generation."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shared_data import SHARED, local_world
from yaml_fuzz import paths_of, yaml_values

from bomc_bt.errors import BomcError
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, save_map
from bomc_bt.world import Change, Obstacle, WorldObject, apply_change, load_world
from bomc_bt.worldgen import clearance_map, generate_world, reachable_free

REPO = Path(__file__).resolve().parents[1]


def shared_worlds() -> list[Path]:
    """World files among the shared examples (the folder also holds their map YAMLs)."""
    return sorted(p for p in (SHARED / "worlds").glob("*.yaml") if "version" in yaml.safe_load(p.read_text()))


# -- a small synthetic map: 4 x 3 m room, a 0.25 m thick inner wall with a doorway --------------
def make_room(folder: Path) -> Path:
    data = np.full((60, 80), FREE, dtype=np.int8)  # rows = y (0.05 m), cols = x
    data[:4, :] = data[-4:, :] = OCCUPIED
    data[:, :4] = data[:, -4:] = OCCUPIED
    data[:, 38:43] = OCCUPIED  # inner wall x in [1.90, 2.15)
    data[20:40, 38:43] = FREE  # doorway y in [1.0, 2.0)
    data[45:56, 60:76] = UNKNOWN  # an unmapped pocket x [3.0, 3.8), y [2.25, 2.8)
    save_map(OccupancyGrid(data, 0.05, (0.0, 0.0)), folder / "room.yaml")
    return folder / "room.yaml"


def base_world() -> dict:
    return {
        "version": 1,
        "name": "room",
        "map": "room.yaml",
        "start": [1.0, 0.6, 0.0],
        "objects": [
            {"name": "chair-1", "category": "chair", "position": [1.0, 1.5, 0.45], "size": [0.5, 0.5, 0.9]},
            {"name": "table-1", "category": "table", "position": [3.0, 1.2, 0.375],
             "size": [1.2, 0.8, 0.75], "yaw": 0.3},
            {"name": "bin-1", "category": "trash bin", "position": [3.3, 0.6, 0.3], "size": [0.4, 0.4, 0.6]},
        ],
        "sessions": {
            2: {"remove": ["bin-1"], "move": {"chair-1": [1.2, 2.0]},
                "add": [{"name": "bin-2", "category": "trash bin", "position": [0.6, 2.4, 0.3],
                         "size": [0.4, 0.4, 0.6]}]},
            3: {"obstacles": [{"position": [1.0, 1.0], "size": [0.6, 0.4], "height": 0.8}]},
        },
        "during": [{"session": 2, "at": 10.0, "move": {"table-1": [3.0, 1.9]}}],
    }


@pytest.fixture(scope="module")
def room(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("room")
    make_room(folder)
    return folder


def write(folder: Path, doc: dict, name: str = "w.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


# -- the shared examples ---------------------------------------------------------------------
def test_shared_folder_has_example_worlds():
    assert {p.stem for p in shared_worlds()} >= {"lab-b", "office-s", "hospital"}


@pytest.mark.parametrize("path", shared_worlds(), ids=lambda p: p.stem)
def test_every_shared_example_world_loads(path):
    world = load_world(path)
    assert world.objects and world.grid.data.size
    assert not world.is_wall(world.start.x, world.start.y)
    for n in range(1, world.last_session + 1):  # every session's ground truth is computable
        assert all(isinstance(o, WorldObject) for o in world.ground_truth(n).values())


def test_lab_b_sessions_follow_the_papers_changes():
    world = load_world(SHARED / "worlds" / "lab-b.yaml")
    s1, s2, s3 = (world.objects_in_session(n) for n in (1, 2, 3))
    assert len(s1) == 12
    assert [o for o in s1.values() if o.category == "trash bin"]
    assert not [o for o in s2.values() if o.category == "trash bin"]
    assert "umbrella-1" not in s2
    assert s2["person-1"].position == (6.0, 7.0, 0.85)  # [x, y] keeps z
    assert "chair-1" not in s3 and "chair-2" not in s3
    assert s3["person-1"].position[:2] == (7.0, 11.0)


def test_lab_b_chair_moved_during_session_3():
    world = load_world(SHARED / "worlds" / "lab-b.yaml")
    assert world.ground_truth(3, at=0.0)["chair-3"].position[:2] == (4.5, 9.0)
    assert world.ground_truth(3, at=39.9)["chair-3"].position[:2] == (4.5, 9.0)
    assert world.ground_truth(3, at=40.0)["chair-3"].position[:2] == (3.0, 11.0)
    assert world.ground_truth(3)["chair-3"].position[:2] == (3.0, 11.0)
    assert world.objects_in_session(3)["chair-3"].position[:2] == (4.5, 9.0)
    # an intra-session change persists into the next session
    assert world.objects_in_session(4)["chair-3"].position[:2] == (3.0, 11.0)
    assert [d.at for d in world.during_changes(3)] == [40.0] and world.during_changes(2) == []


def test_office_obstacle_is_present_in_its_session_only():
    world = load_world(SHARED / "worlds" / "office-s.yaml")
    assert world.obstacles_in_session(2) == []
    assert world.obstacles_in_session(3) == [Obstacle((30.0, 13.5), (1.6, 1.0), 1.2)]
    assert world.obstacles_in_session(4) == []
    assert {"chair-10", "chair-27", "chair-15"} <= set(world.objects_in_session(3))
    assert not {"chair-10", "chair-27", "chair-15"} & set(world.ground_truth(3))


def test_session_below_one_is_a_clear_error():
    world = load_world(SHARED / "worlds" / "lab-b.yaml")
    with pytest.raises(BomcError, match=r"lab-b\.yaml: session: session must be an integer >= 1"):
        world.ground_truth(0)


# -- the test worlds over real maps ----------------------------------------------------------
@pytest.mark.parametrize("stem", ["small_house", "bookstore", "depot"])
def test_test_worlds_over_real_maps(stem):
    world = load_world(local_world(stem))
    assert world.map_path.resolve() == (SHARED / "maps" / f"{stem}.yaml").resolve()
    clear = clearance_map(reachable_free(world.grid), world.grid.resolution)
    r, c = world.grid.world_to_cell(world.start.x, world.start.y)
    assert clear[r, c] > 1.0  # the start is well inside the largest free region
    s2 = world.sessions[2]
    assert s2.remove and s2.move and s2.add
    assert world.obstacles_in_session(3) and world.during
    assert {"chair", "table", "trash bin", "door"} <= {o.category for o in world.objects.values()}
    for obj in world.objects.values():  # every object sits in free space, reachable from the start
        r, c = world.grid.world_to_cell(obj.position[0], obj.position[1])
        assert clear[r, c] > 0


# -- records ---------------------------------------------------------------------------------
def test_footprint_is_the_rotated_box():
    obj = WorldObject("t", "table", (1.0, 2.0, 0.4), (2.0, 1.0, 0.8), yaw=math.pi / 2)
    corners = obj.footprint()
    assert corners.shape == (4, 2)
    np.testing.assert_allclose(corners, [[1.5, 1.0], [1.5, 3.0], [0.5, 3.0], [0.5, 1.0]], atol=1e-12)
    np.testing.assert_allclose(Obstacle((0.0, 0.0), (2.0, 1.0)).footprint().min(axis=0), [-1.0, -0.5])


def test_moved_to_keeps_or_replaces_height():
    obj = WorldObject("c", "chair", (1.0, 2.0, 0.45), (0.5, 0.5, 0.9), yaw=0.2)
    assert obj.moved_to([3.0, 4.0]) == WorldObject("c", "chair", (3.0, 4.0, 0.45), (0.5, 0.5, 0.9), 0.2)
    assert obj.moved_to([3.0, 4.0, 1.0]).position == (3.0, 4.0, 1.0)
    assert obj.position == (1.0, 2.0, 0.45)  # frozen: the original is untouched


def test_apply_change_is_pure_and_rejects_unknown_names():
    a = WorldObject("a", "chair", (0.0, 0.0, 0.4), (0.5, 0.5, 0.8))
    b = WorldObject("b", "chair", (1.0, 0.0, 0.4), (0.5, 0.5, 0.8))
    before = {"a": a}
    after = apply_change(before, Change(remove=["a"], add=[b]))
    assert before == {"a": a} and after == {"b": b}
    # remove then add under the same name replaces the object in one change
    door = WorldObject("a", "door", (2.0, 2.0, 1.0), (0.9, 0.1, 2.0))
    assert apply_change(before, Change(remove=["a"], add=[door])) == {"a": door}
    with pytest.raises(BomcError, match=r"^f\.yaml: s\.move\.zz: cannot move 'zz'"):
        apply_change(before, Change(move={"zz": (1.0, 1.0)}), "f.yaml", "s")
    with pytest.raises(BomcError, match=r"^f\.yaml: s\.add\[0\]\.name: cannot add 'a'"):
        apply_change(before, Change(add=[a]), "f.yaml", "s")


# -- the wall rule on a synthetic map --------------------------------------------------------
@pytest.mark.parametrize("position, size, yaw", [
    ([2.025, 1.5, 1.0], [0.9, 0.06, 2.0], math.pi / 2),  # a door standing in the doorway
    ([0.45, 1.5, 0.6], [0.9, 0.5, 1.2], math.pi / 2),  # a cabinet pushed against the outer wall
    ([0.18, 1.5, 0.6], [0.9, 0.5, 1.2], math.pi / 2),  # centre on the wall, half of it in the room
])
def test_objects_touching_walls_are_accepted(room, position, size, yaw):
    doc = base_world()
    doc["objects"].append({"name": "x", "category": "thing", "position": position, "size": size, "yaw": yaw})
    world = load_world(write(room, doc))
    assert world.objects["x"].category == "thing"
    assert tuple(world.objects["x"].position) == pytest.approx(tuple(position))


@pytest.mark.parametrize("position, size", [
    ([2.02, 0.5, 0.4], [0.1, 0.1, 0.8]),  # a small box inside the thick inner wall
    ([2.025, 0.5, 1.0], [0.06, 0.9, 2.0]),  # a door typed into the middle of that wall
    ([3.4, 2.5, 0.4], [0.3, 0.3, 0.8]),  # inside the unmapped (unknown) pocket
    ([9.0, 1.0, 0.4], [0.5, 0.5, 0.8]),  # outside the image
])
def test_objects_inside_walls_are_rejected(room, position, size):
    doc = base_world()
    doc["objects"].append({"name": "x", "category": "thing", "position": position, "size": size})
    with pytest.raises(BomcError) as err:
        load_world(write(room, doc))
    assert str(err.value).startswith(f"{room / 'w.yaml'}: objects[3].position: 'x' at ")
    assert "inside a wall" in str(err.value)


def test_base_world_semantics(room):
    world = load_world(write(room, base_world()))
    assert world.wall_height == 2.5 and world.start.x == 1.0
    assert world.walls().shape == world.grid.data.shape
    assert world.walls()[50, 65] and world.walls()[0, 0] and not world.walls()[30, 20]
    assert set(world.objects_in_session(2)) == {"chair-1", "table-1", "bin-2"}
    assert world.objects_in_session(2)["table-1"].position[:2] == (3.0, 1.2)
    assert world.ground_truth(2, at=10.0)["table-1"].position[:2] == (3.0, 1.9)
    assert world.objects_in_session(3)["table-1"].position[:2] == (3.0, 1.9)
    assert world.obstacles_in_session(3)[0].height == 0.8 and world.obstacles_at(2, 100.0) == []


# -- malformed input: one line naming the file and the entry ---------------------------------
def _set(doc: dict, edit) -> dict:
    doc = copy.deepcopy(doc)
    edit(doc)
    return doc


MALFORMED = [
    ("missing version", lambda d: d.pop("version"), "version", "missing"),
    ("version 2", lambda d: d.update(version=2), "version", "unsupported version 2"),
    ("missing map", lambda d: d.pop("map"), "map", "missing"),
    ("unknown top key", lambda d: d.update(colour="red"), "colour", "unknown key"),
    ("2d position", lambda d: d["objects"][0].update(position=[1, 2]), "objects[0].position",
     "expected [x, y, z] numbers"),
    ("nan position", lambda d: d["objects"][1].update(position=[float("nan"), 1, 0]), "objects[1].position",
     "finite numbers"),
    ("inf yaw", lambda d: d["objects"][0].update(yaw=float("inf")), "objects[0].yaw",
     "must be a finite number"),
    ("text yaw", lambda d: d["objects"][0].update(yaw="north"), "objects[0].yaw", "expected a number"),
    ("negative size", lambda d: d["objects"][2].update(size=[0.4, -0.4, 0.6]), "objects[2].size",
     "sizes must be positive"),
    ("zero size", lambda d: d["objects"][0].update(size=[0, 0.5, 0.9]), "objects[0].size",
     "sizes must be positive"),
    ("missing category", lambda d: d["objects"][0].pop("category"), "objects[0].category", "missing"),
    ("duplicate name", lambda d: d["objects"][1].update(name="chair-1"), "objects[1].name",
     "duplicate object name 'chair-1'"),
    ("unknown removal", lambda d: d["sessions"][2]["remove"].append("sofa-9"), "sessions[2].remove[1]",
     "cannot remove 'sofa-9'"),
    ("removed twice", lambda d: d["sessions"].update({3: {"remove": ["bin-1"]}}), "sessions[3].remove[0]",
     "cannot remove 'bin-1': no such object at this point"),
    ("moved after a during removal",
     lambda d: (d["during"].append({"session": 2, "at": 5.0, "remove": ["chair-1"]}),
                d["sessions"].update({3: {"move": {"chair-1": [1.0, 1.0]}}})),
     "sessions[3].move.chair-1", "cannot move 'chair-1'"),
    ("add existing", lambda d: d["sessions"][2]["add"][0].update(name="table-1"), "sessions[2].add[0].name",
     "cannot add 'table-1'"),
    ("session 1", lambda d: d["sessions"].update({1: {}}), "sessions", "integers >= 2, got int 1"),
    ("session text", lambda d: d["sessions"].update({"two": {}}), "sessions", "integers >= 2, got str 'two'"),
    ("during session 0", lambda d: d["during"][0].update(session=0), "during[0].session",
     "expected a session number >= 1"),
    ("negative at", lambda d: d["during"][0].update(at=-1.0), "during[0].at", "must be >= 0"),
    ("start in a wall", lambda d: d.update(start=[2.0, 0.5, 0.0]), "start", "not in free space"),
    ("start outside", lambda d: d.update(start=[-5.0, 0.5]), "start", "not in free space"),
    ("move into a wall", lambda d: d["sessions"][2]["move"].update({"chair-1": [3.4, 2.6]}),
     "sessions[2].move.chair-1", "inside a wall"),
    ("obstacle in a wall",
     lambda d: d["sessions"][3]["obstacles"][0].update(position=[2.02, 2.6], size=[0.1, 0.1]),
     "sessions[3].obstacles[0].position", "obstacle lies inside a wall"),
    ("zero wall height", lambda d: d.update(wall_height=0), "wall_height", "must be positive"),
    ("missing map file", lambda d: d.update(map="nope.yaml"), "map", "map file not found"),
    ("move as text", lambda d: d["sessions"][2].update(move="chair-1"), "sessions[2].move",
     "expected a mapping"),
    ("unknown object key", lambda d: d["objects"][0].update(material="oak"), "objects[0].material",
     "unknown key"),
    ("colour as a name", lambda d: d["objects"][0].update(colour="red"), "objects[0].colour",
     "expected [r, g, b] numbers"),
    ("colour out of range", lambda d: d["objects"][0].update(colour=[300, 0, 0]), "objects[0].colour",
     "whole numbers from 0 to 255"),
    ("colour in fractions", lambda d: d["objects"][0].update(colour=[0.5, 0.2, 0.1]), "objects[0].colour",
     "whole numbers from 0 to 255"),
    ("added object's colour", lambda d: d["sessions"][2].update(add=[{**d["objects"][0], "name": "new-1",
                                                                      "colour": [1, 2]}]),
     "sessions[2].add[0].colour", "expected [r, g, b] numbers"),
]


@pytest.mark.parametrize("edit, field, message", [m[1:] for m in MALFORMED], ids=[m[0] for m in MALFORMED])
def test_malformed_world_is_one_line_naming_file_and_field(room, edit, field, message):
    path = write(room, _set(base_world(), edit), "bad.yaml")
    with pytest.raises(BomcError) as err:
        load_world(path)
    text = str(err.value)
    assert text.startswith(f"{path}: {field}: "), text
    assert message in text and "\n" not in text


def test_extension_keys_are_allowed(room):
    plain = load_world(write(room, base_world()))
    extended = load_world(write(room, _set(base_world(), lambda d: (d.update({"x-notes": "hi"}),
                                                                       d["objects"][0].update({"x-colour": "red"})))))
    assert extended.objects == plain.objects  # the extension keys are ignored, nothing else changes


@pytest.mark.parametrize("text, field, message", [
    ("version: 1\nmap: room.yaml\nstart: [1, 1\nobjects: []\n", "line 4", "YAML syntax error"),
    ("version: 1\nmap: room.yaml\nmap: other.yaml\nstart: [1, 1]\n", "line 3", "duplicate key 'map'"),
    ("- just\n- a list\n", None, "expected a mapping"),
])
def test_yaml_level_errors_are_one_line(room, text, field, message):
    path = room / "syntax.yaml"
    path.write_text(text)
    with pytest.raises(BomcError) as err:
        load_world(path)
    prefix = f"{path}: {field}: " if field else f"{path}: "
    assert str(err.value).startswith(prefix) and message in str(err.value) and "\n" not in str(err.value)


def test_missing_world_file(tmp_path):
    with pytest.raises(BomcError, match="world file not found"):
        load_world(tmp_path / "absent.yaml")


# -- generation ------------------------------------------------------------------------------
CATEGORIES = ["chair", "table", "trash bin", "door", "backpack"]


def test_generated_world_loads_and_is_deterministic(tmp_path):
    grid_file = SHARED / "maps" / "depot.yaml"
    a = generate_world(grid_file, 3, 15, CATEGORIES, tmp_path / "a.yaml")
    generate_world(grid_file, 3, 15, CATEGORIES, tmp_path / "b.yaml")
    c = generate_world(grid_file, 4, 15, CATEGORIES, tmp_path / "c.yaml")
    assert (tmp_path / "a.yaml").read_text() == (tmp_path / "b.yaml").read_text()
    assert a.objects != c.objects
    assert len(a.objects) == 15 and {o.category for o in a.objects.values()} == set(CATEGORIES)
    assert a.sessions[2].remove and a.sessions[2].move and a.sessions[2].add
    assert a.obstacles_in_session(3) and {d.session for d in a.during} == {2, 3}
    # objects never overlap: bounding circles stay apart at every point of the timeline
    for n in (1, 2, 3):
        objs = list(a.ground_truth(n).values())
        xy = np.array([o.position[:2] for o in objs])
        radius = np.array([math.hypot(o.size[0], o.size[1]) / 2 for o in objs])
        dist = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(dist, np.inf)
        assert np.all(dist >= radius[:, None] + radius[None, :])


def test_generator_reports_a_map_too_small(tmp_path, room):
    with pytest.raises(BomcError, match="no free space left"):
        generate_world(room / "room.yaml", 0, 60, ["table"], tmp_path / "full.yaml")


# -- fuzz: any mutation either loads or is a BomcError ---------------------------------------
_scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True),
                     st.text(max_size=6))
_values = yaml_values(_scalars, st.text(max_size=5), max_keys=3, max_leaves=6)


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzzed_worlds_load_or_raise_bomc_error(room, data):
    doc = base_world()
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in paths_of(doc) if p]
        path = data.draw(st.sampled_from(paths))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        action = data.draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "delete" and isinstance(parent, dict):
            del parent[path[-1]]
        elif action == "add" and isinstance(parent, dict):
            parent[data.draw(st.one_of(st.text(max_size=6), st.integers(0, 4)))] = data.draw(_values)
        else:
            parent[path[-1]] = data.draw(_values)
    target = room / "fuzz.yaml"
    target.write_text(yaml.safe_dump(doc, sort_keys=False))
    try:
        world = load_world(target)
    except BomcError as exc:
        assert "\n" not in str(exc) and str(target) in str(exc)
    else:
        for n in range(1, world.last_session + 1):
            world.ground_truth(n)
