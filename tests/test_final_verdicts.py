"""First seen or added, judged where a node stands when the pass ends, not where it was added.

A node is added where its first confirming views put it. A door seen edge-on first, or a
table seen at one end, stands off the object's middle until later views bring it there, and
whether the previous pass detected an object of its kind at that place must be asked at the
object's place.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bomc_bt.first_seen import FIRST_SEEN, SIGHTED_IN, SeenBefore, first_seen_verdicts
from bomc_bt.graph import AssociationParams, Event, ObjectGraph, Observation
from bomc_bt.grid import OccupancyGrid, inflate_mask
from bomc_bt.net_changes import net_changes
from bomc_bt.sightings import Sightings


def d07(_category: str) -> float:
    return 0.7


def seen_with_sightings(*points: tuple[str, float]) -> SeenBefore:
    """A 10 x 10 m floor pass 1 saw all of, and where it detected objects (category, x at y = 5 m)."""
    grid = OccupancyGrid(np.zeros((100, 100), dtype=np.int8), 0.1, (0.0, 0.0))
    sightings = Sightings(grid)
    sightings.add(SimpleNamespace(category=c, position=np.array([x, 5.0, 0.5])) for c, x in points)
    masks = {c: inflate_mask(m, 0.35 / grid.resolution) for c, m in sightings.masks.items()}
    return SeenBefore(grid, np.ones(grid.data.shape, dtype=bool), masks, 1)


def pass_2_adds(seen: SeenBefore, category: str, x: float) -> tuple[ObjectGraph, list[Event]]:
    """Pass 1 mapped one chair far off; pass 2 adds a node of ``category`` at (x, 5), marked as the
    frame that added it marks it."""
    graph = ObjectGraph(AssociationParams(confirm_detections=1))
    history = [Event("added", 99, "chair", np.array([9.0, 9.0, 0.4]), 1, 1.0)]  # pass 1's only node
    events = graph.associate([Observation(category, np.array([x, 5.0, 0.5]), 0.9, 500, 0.0)], [], 2, 10.0)
    seen.mark(events)
    return graph, history + events


def kinds(history: list[Event]) -> dict[int, str]:
    return {c.node_id: c.kind for c in net_changes(history, 1, d07)}


def test_a_door_added_off_its_middle_is_first_seen_where_its_later_views_put_it():
    """Pass 1 detected the door at x = 5.0 m (one frame, never confirmed). Pass 2's first views
    were edge-on and put its node 0.55 m along the wall, beyond the sighting radius: an
    addition when it was added. Its later views bring it to 5.05 m: the door pass 1 saw."""
    seen = seen_with_sightings(("door", 5.0))
    graph, history = pass_2_adds(seen, "door", 5.55)
    assert FIRST_SEEN not in (history[-1].detail or {})
    assert kinds(history)[0] == "added"
    door = graph.nodes[0]
    door.position = np.array([5.05, 5.0, 0.5])
    [(node, verdict)] = seen.final_verdicts(graph.nodes.values(), history)
    assert node is door and verdict == {FIRST_SEEN: True, SIGHTED_IN: 1}
    mark = Event("updated", 0, "door", door.position.copy(), 2, 20.0, detail=verdict)
    assert kinds([*history, mark])[0] == "first_seen"
    assert seen.final_verdicts(graph.nodes.values(), [*history, mark]) == []  # judged once: nothing new


def test_a_chair_added_beside_where_its_neighbour_was_sighted_is_an_addition_where_it_stands():
    """Pass 1 detected a chair at x = 5.0 m. Pass 2's first view of a new chair put it 0.3 m
    from there (first seen by the sighting); where the chair stands, 0.8 m off, pass 1 looked
    and saw nothing: an addition."""
    seen = seen_with_sightings(("chair", 5.0))
    graph, history = pass_2_adds(seen, "chair", 5.3)
    assert history[-1].detail == {FIRST_SEEN: True, SIGHTED_IN: 1} and kinds(history)[0] == "first_seen"
    graph.nodes[0].position = np.array([5.8, 5.0, 0.5])
    [(_, verdict)] = seen.final_verdicts(graph.nodes.values(), history)
    assert verdict == {FIRST_SEEN: False}
    assert kinds([*history, Event("updated", 0, "chair", graph.nodes[0].position, 2, 20.0, detail=verdict)])[0] \
        == "added"


def test_the_last_verdict_counts_and_only_after_the_node_was_added():
    added = Event("added", 3, "door", np.zeros(3), 2, 1.0)
    later = [Event("updated", 3, "door", np.zeros(3), 2, t, detail={FIRST_SEEN: v}) for t, v in ((2.0, True),
                                                                                              (3.0, False))]
    assert first_seen_verdicts([added]) == {3: False}
    assert first_seen_verdicts([added, later[0]]) == {3: True}
    assert first_seen_verdicts([added, *later]) == {3: False}
    assert first_seen_verdicts([later[0]]) == {}  # no addition in the period: nothing to judge
