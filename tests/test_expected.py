"""Which nodes a frame is evidence about: a flat object seen edge-on is not one of them, and a
miss counts only where the depth camera sees the node's place empty."""

from __future__ import annotations

import math

import cv2
import numpy as np

from bomc_bt.algorithm_params import ProjectionParams
from bomc_bt.geometry import Pose2D
from bomc_bt.graph import AssociationParams, Node, ObjectGraph
from bomc_bt.grid import OccupancyGrid
from bomc_bt.perception.expected import edge_on, expected_nodes, miss_weights, place_taken
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.projection import detections_to_observations
from bomc_bt.sim.camera import CameraParams, SimCamera
from bomc_bt.world import WorldObject

RES = 0.1
DOOR = WorldObject("door", "door", (0.0, 0.0, 1.0), (0.9, 0.06, 2.0), yaw=0.0)  # its face looks along y


def door_node(footprint=(-0.5, -0.08, 0.5, 0.08)) -> Node:
    return Node(1, "door", np.array([0.0, 0.0, 1.0]), 0.9, 1, 1, footprint=footprint)


def render(objects, pose: Pose2D):
    """A frame inside a walled room x -5..2.5, y -4.5..1.5 (the walls are what the camera sees past the door)."""
    n = int(20.0 / RES)
    grid = OccupancyGrid(np.zeros((n, n), dtype=np.int8), RES, (-10.0, -10.0))
    walls = np.ones((n, n), dtype=bool)
    (r0, r1), (c0, c1) = grid.world_to_cell(np.array([-5.0, 2.5]), np.array([-4.5, 1.5]))
    walls[int(r0):int(r1), int(c0):int(c1)] = False
    cam = SimCamera(CameraParams(scale=0.25, depth_noise=0.0), seed=0)
    return cam.render(walls, grid, 2.5, list(objects), [], [], pose, pose, 0.0)


def test_a_door_seen_edge_on_from_a_narrow_corridor_is_no_evidence_head_on_it_is():
    lateral, along = 1.0, 3.4  # from 1 m beside its plane, 3.4 m along: 74 deg off its normal
    edge = Pose2D(-along, -lateral, math.atan2(lateral, along))
    head_on = Pose2D(0.0, -math.hypot(lateral, along), math.pi / 2)
    node = door_node()
    params = ProjectionParams(expect_edge_on_deg=65.0)
    # The door is gone: both frames see through to where it stood.
    assert expected_nodes(render([], head_on), [node], params) == [node]
    assert expected_nodes(render([], edge), [node], params) == []
    assert expected_nodes(render([], edge), [node], ProjectionParams()) == [node]  # off by default


def test_only_flat_footprints_seen_past_the_limit_are_edge_on():
    camera = np.array([-3.4, -1.0])  # 74 deg off the door's normal
    flat, square, unknown = door_node(), door_node((-0.3, -0.3, 0.3, 0.3)), door_node(None)
    turned = door_node((-0.08, -0.5, 0.08, 0.5))  # the same door in a wall along y: camera 16 deg off its normal
    assert edge_on([flat, square, unknown, turned], camera, 65.0).tolist() == [True, False, False, False]
    assert edge_on([flat], camera, 80.0).tolist() == [False]
    assert edge_on([flat], np.array([0.0, -3.0]), 65.0).tolist() == [False]


def test_a_door_missed_edge_on_weighs_less_the_more_edge_on_and_a_chair_the_same_from_anywhere():
    """The door gone, a frame from 2.4 m at 30, 62 and 80 degrees off its face's normal: the
    miss weighs 1, then about the cosine's share of cos 45 (the width the image shows), then
    little; seen from along the corridor three misses no longer remove it (opt-in)."""
    params = ProjectionParams(miss_full_range=2.5, miss_face_on_deg=45.0)
    weights = []
    for angle in (30.0, 62.0, 80.0):
        a = math.radians(angle)
        x, y = -2.4 * math.sin(a), -2.4 * math.cos(a)
        pose = Pose2D(x, y, math.atan2(-y, -x))
        weights.append(miss_weights(render([], pose), [door_node()], params)[0])
        square = door_node((-0.3, -0.3, 0.3, 0.3))  # a chair-like footprint: no face to see edge-on
        assert miss_weights(render([], pose), [square], params) == [1.0]
    assert weights[0] == 1.0 and 0.6 < weights[1] < 0.7 and 0.2 < weights[2] < 0.3
    assert miss_weights(render([], pose), [door_node()], ProjectionParams(miss_full_range=2.5)) == [1.0]  # off
    graph = ObjectGraph(AssociationParams(), [door_node()])
    for k in range(3):
        graph.associate([], [1], 2, 10.0 + k, miss_weights=[weights[1]])
    assert 1 in graph.nodes


def chair(name: str, x: float, y: float = -1.5) -> WorldObject:
    return WorldObject(name, "chair", (x, y, 0.45), (0.5, 0.5, 0.9), yaw=0.0)


def test_a_chair_seen_only_over_the_table_in_front_is_no_evidence_of_its_absence():
    camera = Pose2D(-4.0, -1.5, 0.0)  # looking along +x over a table at the chair behind it
    table = WorldObject("t", "table", (-1.8, -1.5, 0.375), (0.8, 1.6, 0.75), yaw=0.0)
    behind = chair("b", -0.9)
    node = Node(2, "chair", np.array([-0.9, -1.5, 0.82]), 0.5, 1, 1,  # its top: all pass 1 saw of it
                footprint=(-1.15, -1.75, -0.65, -1.25))
    both, table_only = render([table, behind], camera), render([table], camera)
    params = ProjectionParams()
    # It stands there: its back fills the place, nothing wall-high does: a miss weighs nothing.
    assert expected_nodes(both, [node], params) == [node]
    assert miss_weights(both, [node], params) == [0.0]
    # Taken away: the camera sees past its place, and the miss counts.
    assert expected_nodes(table_only, [node], params) == [node]
    assert miss_weights(table_only, [node], params)[0] > 0.5
    # With the check off, the miss counted while it stood there (the phantom removal).
    assert miss_weights(both, [node], ProjectionParams(absence_margin=0.0))[0] > 0.5
    # A detection covering its place explains what stands there (another node's object: this
    # node is a duplicate or a neighbour's), so the miss counts.
    h, w = both.shape
    covering = Detection("chair", (0.0, 0.0, float(w), float(h)), 0.9)
    elsewhere = Detection("table", (0.0, 0.0, 2.0, 2.0), 0.9)
    assert miss_weights(both, [node], params, [covering])[0] > 0.5
    assert miss_weights(both, [node], params, [elsewhere]) == [0.0]
    # A detection of another kind over its place is what hides it (the table in front, its
    # mask spilling over the chair's back), not what stands there: the miss still weighs nothing.
    in_front = Detection("table", (0.0, 0.0, float(w), float(h)), 0.9)
    assert miss_weights(both, [node], params, [in_front]) == [0.0]
    assert miss_weights(table_only, [node], params, [in_front])[0] > 0.5


def test_a_detection_on_a_wall_or_an_object_gone_from_against_the_wall_can_still_be_missed():
    camera = Pose2D(-1.0, -1.5, 0.0)  # facing the room's east wall (x = 2.5), 3.5 m ahead
    on_wall = Node(3, "chair", np.array([2.5, -1.5, 0.5]), 0.5, 1, 1)  # a false detection's node
    by_wall = Node(4, "trash bin", np.array([2.42, -1.0, 0.3]), 0.3, 1, 1)  # a bin that stood against it
    frame = render([], camera)
    assert min(miss_weights(frame, [on_wall, by_wall], ProjectionParams())) > 0.5
    # Nearer, the camera (tilted 15 degrees down) shows less of the wall above a high node:
    # 2.4 m away only 0.5 m above it, 1 m away nothing above it. Either way the miss counts.
    high = Node(5, "cabinet", np.array([2.5, -1.5, 0.88]), 0.5, 1, 1)
    for x in (0.0, 1.4):
        assert miss_weights(render([], Pose2D(x, -1.5, 0.0)), [high], ProjectionParams()) == [1.0]


def test_an_undetected_chair_behind_a_table_keeps_its_node_pass_after_pass_until_it_is_taken_away():
    camera = Pose2D(-3.0, -1.5, 0.0)  # 2.1 m from the chair: every miss would weigh fully
    table = WorldObject("t", "table", (-1.5, -1.5, 0.375), (0.8, 1.6, 0.75), yaw=0.0)
    params = ProjectionParams()

    def changes_over_frames_without_a_chair_detection(objects, table_found: bool) -> list[tuple[str, int]]:
        node = Node(0, "chair", np.array([-0.9, -1.5, 0.82]), 0.9, 1, 1, observations=20,
                    footprint=np.array([-1.15, -1.75, -0.65, -1.25]))
        graph = ObjectGraph(AssociationParams(), [node])
        frame = render(objects, camera)
        found = [table_detection(frame)] if table_found else []
        events = []
        for k in range(30):  # 15 s of frames at 2 Hz, the detector never finding the chair
            expected = expected_nodes(frame, list(graph.nodes.values()), params)
            weights = miss_weights(frame, expected, params, found)
            events += graph.associate([], [n.id for n in expected], 2, 100.0 + 0.5 * k, miss_weights=weights)
        return [(e.kind, e.node_id) for e in events]

    for table_found in (False, True):  # the table found too, its mask spilling over the chair's back
        assert changes_over_frames_without_a_chair_detection([table, chair("b", -0.9)], table_found) == []
        assert changes_over_frames_without_a_chair_detection([table], table_found) == [("removed", 0)]


def table_detection(frame) -> Detection:
    """The table as a segmenter returns it, its mask spilling 10 pixels round it (over the chair's back)."""
    ids = [i for i, c in frame.instance_categories.items() if c == "table"]
    mask = cv2.dilate(np.isin(frame.instances, ids).astype(np.uint8), np.ones((21, 21), np.uint8)) > 0
    rows, cols = np.nonzero(mask)
    box = (float(cols.min()), float(rows.min()), float(cols.max()), float(rows.max()))
    return Detection("table", box, 0.9, mask)


def test_a_node_whose_place_lies_just_behind_a_walls_face_is_hidden_not_missed():
    """A door's node made from views of one end of its leaf stands at the jamb. Seen past
    the jamb, the wall's face 0.15 m in front of the node's centre fills its place and the
    view above it, as a wall fills the place of a false detection on it; but that detection's
    centre lies on the face, and this one's behind it: the place is hidden, the miss weighs
    nothing. A false detection on the face itself is still missed."""
    camera = Pose2D(-1.0, -1.5, 0.0)  # facing the room's east wall (x = 2.5), 3.5 m ahead
    frame = render([], camera)
    behind = Node(6, "door", np.array([2.65, -1.5, 1.0]), 0.9, 1, 1)
    on_face = Node(7, "door", np.array([2.5, -1.0, 1.0]), 0.9, 1, 1)
    params = ProjectionParams()
    assert expected_nodes(frame, [behind, on_face], params) == [behind, on_face]  # within visible()'s 0.3 m
    weights = miss_weights(frame, [behind, on_face], params)
    assert weights[0] == 0.0 and weights[1] > 0.5


def category_detection(frame, category: str) -> Detection:
    """Every pixel of the frame's objects of ``category``, as a perfect segmenter returns them."""
    ids = [i for i, c in frame.instance_categories.items() if c == category]
    mask = np.isin(frame.instances, ids)
    rows, cols = np.nonzero(mask)
    return Detection(category, (float(cols.min()), float(rows.min()), float(cols.max()), float(rows.max())), 0.9,
                     mask)


def test_a_chair_whose_place_a_plant_took_is_missed_and_the_plant_gets_its_own_node():
    """Seed 7503, pass 4 (36 x 28 m office): a chair moved away before the pass, a plant put
    where it stood during it. The plant filled the chair's place, so the chair's misses
    weighed nothing, and the plant's sightings, on the chair's node, were taken for the
    chair under another name (confusions.py): the chair stayed on the map, the plant never
    came on. A place where an object of another kind is seen standing is no longer held."""
    camera = Pose2D(-3.0, -1.5, 0.0)  # 2.1 m from the place: a miss weighs fully
    plant = WorldObject("p", "potted plant", (-0.95, -1.45, 0.45), (0.4, 0.4, 0.9), yaw=0.0)
    params = ProjectionParams()
    frame = render([plant], camera)
    seen = [category_detection(frame, "potted plant")]
    observations = detections_to_observations(frame, seen, params)
    assert [o.category for o in observations] == ["potted plant"]
    node = Node(0, "chair", np.array([-0.9, -1.5, 0.5]), 0.9, 1, 1, observations=20,
                footprint=np.array([-1.15, -1.75, -0.65, -1.25]))
    assert expected_nodes(frame, [node], params) == [node]
    assert miss_weights(frame, [node], params, seen) == [0.0]  # held, as before
    assert miss_weights(frame, [node], params, seen, observations, 0.3) == [1.0]
    # A television above a cabinet's place stands on it, not in it: the cabinet stays held.
    cabinet = Node(1, "cabinet", np.array([-0.9, -1.5, -0.2]), 0.9, 1, 1)
    assert place_taken([cabinet], observations, 0.3).tolist() == [False]

    graph = ObjectGraph(AssociationParams(), [node])
    events = []
    for k in range(20):  # 10 s of frames at 2 Hz
        expected = expected_nodes(frame, list(graph.nodes.values()), params)
        weights = miss_weights(frame, expected, params, seen, observations, graph.params.relabel_radius)
        events += graph.associate(observations, [n.id for n in expected], 4, 100.0 + 0.5 * k, miss_weights=weights)
    kinds = [(e.kind, e.category) for e in events if e.kind != "updated"]
    assert kinds == [("removed", "chair"), ("added", "potted plant")]


def test_a_chair_named_plant_keeps_its_node():
    """The other side: a chair that stands there. Named "potted plant" in one frame before
    the pass saw it as a chair, that frame counts one miss, which the next sighting ends.
    Once the pass has seen it as a chair, another name at its place, frame after frame (a
    detector's confusion from one viewpoint), is no evidence: the place stays held. Neither
    way is a plant node made (one object, one label)."""
    camera = Pose2D(-3.0, -1.5, 0.0)
    params = ProjectionParams()
    frame = render([chair("c", -0.9)], camera)
    as_chair = [category_detection(frame, "chair")]
    as_plant = [Detection("potted plant", as_chair[0].box, 0.9, as_chair[0].mask)]

    def events_over(names: str) -> list[tuple[str, str]]:
        node = Node(0, "chair", np.array([-0.9, -1.5, 0.5]), 0.9, 1, 1, observations=20,
                    footprint=np.array([-1.15, -1.75, -0.65, -1.25]))  # from the store: not seen yet
        graph = ObjectGraph(AssociationParams(), [node])
        events = []
        for k, name in enumerate(names):
            found = as_plant if name == "p" else as_chair
            observations = detections_to_observations(frame, found, params)
            expected = expected_nodes(frame, list(graph.nodes.values()), params)
            weights = miss_weights(frame, expected, params, found, observations, graph.params.relabel_radius)
            events += graph.associate(observations, [n.id for n in expected], 2, 100.0 + 0.5 * k,
                                      miss_weights=weights)
        return [(e.kind, e.category) for e in events if e.kind not in ("updated", "moved")]

    assert events_over("pccccpcccc") == []
    assert events_over("c" + "p" * 20) == []
    assert events_over("p" * 20) == [("removed", "chair"), ("added", "potted plant")]  # never seen as a chair
