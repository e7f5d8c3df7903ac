"""The records the object graph is made of: nodes, observations, events, and the tunables.

Plain dataclasses with no behaviour beyond normalising their arrays, so that the site
store, the viewer and the evaluation can use them without the association machinery.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from bomc_bt.graph.footprints import box_or_none
from bomc_bt.graph.looks import colour_or_none

PRESENT = "present"
REMOVED = "removed"
EVENT_KINDS = ("added", "removed", "moved", "updated")
# An operator's corrections (``bomc edit``), kept in the same history as the robot's events
# but never counted as something a pass observed (see bomc_bt.site.edits).
OPERATOR_KINDS = ("relabelled", "deleted", "restored", "noted")


@dataclass
class Node:
    """One object in the graph; ``position`` is (3,) in the map frame."""

    id: int
    category: str
    position: np.ndarray
    confidence: float
    first_session: int
    last_session: int
    state: str = PRESENT  # "present" | "removed" (removed nodes live on in the store's history)
    observations: int = 1  # times matched
    misses: int = 0  # consecutive expected-but-unseen frames (robust mode)
    # robust: floor-plane box (xmin, ymin, xmax, ymax) the object's points have covered, None unknown
    footprint: np.ndarray | None = None
    # robot time of the latest frame that matched (or added) the node in this process; None
    # when it was loaded from the store and not seen since. Not persisted: it only says how
    # stale a node has grown during the pass at hand (see monitoring.unverified_headings).
    last_seen: float | None = None
    # how the object looks: (r, g) chromaticity, the running mean of its views' (None: unknown)
    colour: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float).reshape(3)
        self.footprint = box_or_none(self.footprint)
        self.colour = colour_or_none(self.colour)


@dataclass
class Observation:
    """One detected object in one frame: category and map-frame centroid of its points."""

    category: str
    position: np.ndarray
    confidence: float
    n_points: int = 0
    extent: float = 0.0  # horizontal spread (m) of the object's points about the centroid
    box: np.ndarray | None = None  # floor-plane box (xmin, ymin, xmax, ymax) of those points
    truncated: bool = False  # cut by the image border or an occluder: part of the object is missing
    # cut by the image's top edge: the object goes on above what the view shows, so its centre
    # lies higher than this one (a door seen from 2 m: its lower metre)
    above_image: bool = False
    colour: np.ndarray | None = None  # (r, g) chromaticity of its surface's pixels; None: no colour image

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float).reshape(3)
        self.box = box_or_none(self.box)
        self.colour = colour_or_none(self.colour)


def bounded_height(o: Observation, current: float, target: float) -> float:
    """The height a node at ``current`` moves to on ``o`` (``target`` from the running
    average): a view cut by the image's top edge only raises it. Close views of a door show
    its lower metre, and the running average of the last few put a door's node 0.7 m low,
    past the scoring distance (office-s, pass 2). A view cut at the bottom (a chair or a
    table seen from close) moves it either way, as any other view does."""
    return max(target, current) if o.above_image else target


@dataclass
class Event:
    """A change of the graph, as recorded in the store's history."""

    kind: str  # "added" | "removed" | "moved" | "updated"
    node_id: int
    category: str
    position: np.ndarray
    session: int
    stamp: float
    previous: np.ndarray | None = None  # position before a move
    confidence: float = 0.0
    # JSON-able evidence or an operator's words: on a removal {"misses": n, "merged": bool,
    # "seen": robot time last seen, "merged_into": id}; {"text": ..., "from": ...,
    # "after_session": n} on an operator event; None when there is nothing
    detail: dict | None = None

    @property
    def by_operator(self) -> bool:
        return self.kind in OPERATOR_KINDS

    @property
    def misses(self) -> int | None:
        """A removal: frames that counted the node missing (0: merged; None: not recorded)."""
        value = (self.detail or {}).get("misses")
        return None if value is None else int(value)

    @property
    def last_seen(self) -> float | None:
        """A removal: robot time of the latest frame that saw the node (None: not recorded)."""
        value = (self.detail or {}).get("seen")
        return None if value is None else float(value)

    @property
    def merged_into(self) -> int | None:
        """A removal that folded a duplicate into this node (None: not a merge, or not known)."""
        value = (self.detail or {}).get("merged_into")
        return None if value is None else int(value)

    @property
    def retracted(self) -> bool:
        """A removal of a node seen too seldom to have been trusted (see ``retract_observations``)."""
        return bool((self.detail or {}).get("retracted", False))

    def removal_evidence(self, misses: int, merged: bool, last_seen: float | None,
                         merged_into: int | None = None, observations: int | None = None,
                         retracted: bool = False) -> None:
        """Record why a removal was decided (the history keeps it as ``detail``)."""
        self.detail = {"misses": int(misses), "merged": bool(merged)}
        if observations is not None:
            self.detail["observations"] = int(observations)
        if retracted:
            self.detail["retracted"] = True
        if last_seen is not None:
            self.detail["seen"] = float(last_seen)
        if merged_into is not None:
            self.detail["merged_into"] = int(merged_into)


@dataclass
class AssociationParams:
    """Tunables of association (``config/*.yaml`` key ``association``).

    Fields marked "robust" only matter in robust mode (see :mod:`bomc_bt.graph.robust`).
    """

    default_distance: float = 0.7  # [m] delta: how close a same-category observation must be to be a node (paper: 0.7)
    per_category: dict[str, float] = field(default_factory=dict)  # [m] delta_c overrides, by category name
    mode: Literal["paper", "robust"] = "robust"  # [choice] "paper": Algorithm 2 as written; "robust": our extension
    confirm_misses: int = 3  # [count] robust: consecutive counted misses before a node is removed
    # [-] robust: detection rate assumed for a node before frames show its own: at this rate
    # confirm_misses misses remove it; a node seen in fewer of the frames that expected it
    # needs as many more as keep the chance of a present object's removal the same
    detection_prior: float = 0.8
    detection_prior_weight: float = 2.0  # [count] robust: how many frames' worth the prior counts
    max_misses: int = 12  # [count] robust: consecutive misses that remove any node, however rarely detected
    confirm_interval: float = 0.5  # [s] robust: robot time between two counted misses or two confirming sightings
    # [m] robust: a node is removed only once its run of misses was seen from robot places at
    # least this far apart: misses from one place are one look (a robot standing at a doorway); a pass that
    # ends with one look leaves the next pass's run from anywhere as the second (a pass late); 0: off
    miss_spacing: float = 0.0
    # [count] robust: sectors of bearing round a node (its viewing sides) each with its own
    # detection rate, counted from the frames that expected it there; a run of misses is judged
    # by the lowest rate of the sides it was seen from (bomc_bt.graph.view_sides). 0: off
    miss_sides: int = 8
    # [-] robust: weight of the earlier passes' per-side counts a pass starts with (what the
    # previous pass learnt, and so on back, each pass weighing them again); 0: each pass starts afresh
    side_memory: float = 0.5
    move_radius: float = 3.0  # [m] robust: how far a removed or pending object may have moved and keep its id
    # [m] robust: when a pass ends, a node it removed and a node it added, of one category,
    # each the other's nearest within this, are one object moved (bomc_bt.graph.relocations); 0: off
    relocation_radius: float = 5.0
    # [-] robust: how far apart two colours may lie (chromaticity: r and g over r + g + b) and be
    # one object's look; colours that differ part a pair by position (a move in the pass or a
    # pair when it ends), and a removal and an addition left whose looks match each other, no
    # other and few of their kind are one object moved, at any distance, unless a node of their look the
    # pass never saw stands within move_radius of the addition (bomc_bt.graph.looks); 0: off
    colour_tolerance: float = 0.04
    # [-] robust: how far a view's colour may lie from a node's (chromaticity) and the view still
    # match that node by position; farther, it is another object (a red chair put where a blue one
    # stood). Wider than colour_tolerance: one view's colour strays more than a node's running
    # mean of many; 0, or colour_tolerance 0: colour never refuses a match
    colour_match_tolerance: float = 0.08
    # [-] robust: a removal and an arrival paired by look (above) are one object moved while the
    # matches chance would give among the pass's candidates of their kind (n times the look's share
    # of the kind, bomc_bt.graph.looks.coincidence) stay below this: the odds of a move against an
    # object taken away while an unrelated one of its model came in. 1: even odds
    look_odds: float = 1.5
    # [m] robust: when a pass ends, a node it added this near (planar) where an earlier pass
    # removed one of its category on evidence of absence, not seen since, and of its look where
    # both are known, is that object brought back: never paired as another's move
    # (bomc_bt.graph.brought_back); 0: off
    return_radius: float = 0.35
    position_smoothing: float = 0.3  # [-] robust: running-average weight of a new observation in a node's position
    report_distance: float = 0.1  # [m] robust: drift since the last report that makes a refresh an "updated" event
    vertical_weight: float = 0.5  # [-] robust: weight of height differences in distances (paper: 1)
    extent_gate: float = 2.0  # [-] robust: a big object's own spread widens its gate, up to this times delta_c
    confirm_detections: int = 2  # [count] robust: frames (confirm_interval apart) that must see a new object
    tentative_ttl: float = 10.0  # [s] robust: how long a first sighting waits for its confirmation
    footprint_overlap: float = 0.5  # [-] robust: box overlap (of the smaller box) that makes the same object; 0: off
    # [m] robust: gap between a truncated view's box and a big object's footprint that still
    # touches it (about the width of what hides the rest: a chair in front of a table)
    footprint_touch: float = 0.5
    # [bool] robust: a view whose box lies clear of a small node's footprint (one that holds a
    # whole view of the object, not only views cut off by an occluder) is another object
    # (chairs side by side at a table)
    separate_neighbours: bool = True
    # [-] a detection nearer to where the operator deleted an object of its category than to
    # any node counts only at this confidence or more (bomc_bt.graph.operator_edits)
    readd_confidence: float = 0.95
    # [m] how far into a wall (a cell the map holds as occupied) beyond the floor an earlier
    # pass saw a newly added object may stand and still count as appearing there ("added", a
    # change): a door's centre lies in its wall. Anywhere else off that floor it is
    # "first_seen": new to the map, not a change (bomc_bt.first_seen)
    first_seen_margin: float = 0.3
    # [deg] robust: a flat node (a door leaf: floor footprint 3 or more times longer than wide)
    # is seen face-on from within this of its face's normal (bomc_bt.graph.faces). It is "added"
    # only where an earlier pass looked at its place face-on (from a viewing side of miss_sides
    # whose middle lies this near the normal); looked at only edge-on it is "first_seen"
    # (bomc_bt.looked_sides). 90: every view counts (and miss_sides 0 or above 32: no looks)
    face_on_deg: float = 45.0
    # [m] a new node this near where the previous pass detected an object of its category is
    # "first_seen", not "added": the object was there, the map had folded it into a neighbour
    # or removed it (bomc_bt.sightings). Under an object's size; 0: off
    sighting_radius: float = 0.35
    # [m] robust: a new object's sighting this near (planar) a node of another category counts
    # only in a frame that also matched that node: one object under two labels in different
    # frames is the detector confusing it, two objects are seen together. 0: off
    relabel_radius: float = 0.3
    # [count] robust: frames (confirm_interval apart) naming one other kind on a node this pass
    # has not matched that take the node off: another object stands where it stood
    # (bomc_bt.graph.replacements). 0: off
    replace_sightings: int = 3
    # [count] robust: a node taken off after being matched in at most this many frames in all
    # is retracted, not removed: sightings the map no longer trusts (a look-alike, a confusion),
    # reported apart from the changes (bomc_bt.net_changes). 1: never matched again after the
    # sightings that confirmed it; 0: off
    retract_observations: int = 1
    # [s] robust: a node that misses take off within this much robot time of a frame of the same
    # pass that matched it is retracted, not removed: one visit saw it and then missed it from
    # elsewhere (a look-alike seen from one side, a door missed edge-on), which says the sighting
    # depends on the view, not that the object went (bomc_bt.net_changes), unless the misses came
    # from viewing sides that saw it and never missed it, or no sides are kept (miss_sides 0). 0: off
    retract_within: float = 30.0

    def __post_init__(self) -> None:
        if not self.default_distance > 0:
            raise ValueError("default_distance must be > 0")
        for cat, d in self.per_category.items():
            if not d > 0:
                raise ValueError(f"per_category distance for {cat!r} must be > 0")
        if self.mode not in ("paper", "robust"):
            raise ValueError(f"mode must be 'paper' or 'robust', got {self.mode!r}")
        if self.confirm_misses < 1:
            raise ValueError("confirm_misses must be >= 1")
        if not 0.0 < self.detection_prior < 1.0:
            raise ValueError("detection_prior must be in (0, 1)")
        if self.detection_prior_weight < 0 or self.max_misses < self.confirm_misses:
            raise ValueError("detection_prior_weight must be >= 0 and max_misses >= confirm_misses")
        if min(self.confirm_interval, self.move_radius, self.report_distance, self.relocation_radius,
               self.miss_spacing) < 0:
            raise ValueError("confirm_interval, move_radius, relocation_radius, report_distance and miss_spacing "
                             "must be >= 0")
        if self.confirm_detections < 1 or self.tentative_ttl < 0:
            raise ValueError("confirm_detections must be >= 1 and tentative_ttl >= 0")
        if self.extent_gate < 1.0:
            raise ValueError("extent_gate must be >= 1 (1 turns it off)")
        if not 0.0 <= self.vertical_weight <= 1.0:
            raise ValueError("vertical_weight must be in [0, 1]")
        if not 0.0 < self.position_smoothing <= 1.0:
            raise ValueError("position_smoothing must be in (0, 1]")
        if not 0.0 <= self.footprint_overlap <= 1.0:
            raise ValueError("footprint_overlap must be in [0, 1] (0 turns it off)")
        if self.footprint_touch < 0:
            raise ValueError("footprint_touch must be >= 0")
        if not 0.0 <= self.readd_confidence <= 1.0:
            raise ValueError("readd_confidence must be in [0, 1]")
        if not 0.0 <= self.first_seen_margin <= 10.0:
            raise ValueError("first_seen_margin must be in [0, 10] m")
        if not 0.0 <= self.face_on_deg <= 90.0:
            raise ValueError("face_on_deg must be in [0, 90] deg (90: every view is face-on)")
        if not 0.0 <= self.sighting_radius <= 2.0:
            raise ValueError("sighting_radius must be in [0, 2] m")
        if not 0 <= self.retract_observations <= 1000:
            raise ValueError("retract_observations must be 0 to 1000")
        if not 0.0 <= self.retract_within <= 3600.0:
            raise ValueError("retract_within must be in [0, 3600] s (0 turns it off)")
        if not 0.0 <= self.relabel_radius <= 2.0:
            raise ValueError("relabel_radius must be in [0, 2] m")
        if isinstance(self.replace_sightings, bool) or not 0 <= self.replace_sightings <= 1000 \
                or int(self.replace_sightings) != self.replace_sightings:
            raise ValueError("replace_sightings must be a whole number 0 to 1000")
        if not 0.0 < self.look_odds <= 10.0:
            raise ValueError("look_odds must be in (0, 10]")
        if not 0.0 <= self.colour_tolerance <= 0.5:
            raise ValueError("colour_tolerance must be in [0, 0.5] (0 turns it off)")
        if not 0.0 <= self.colour_match_tolerance <= 0.5:
            raise ValueError("colour_match_tolerance must be in [0, 0.5] (0 turns it off)")
        if isinstance(self.miss_sides, bool) or not 0 <= self.miss_sides <= 64 \
                or int(self.miss_sides) != self.miss_sides:
            raise ValueError("miss_sides must be a whole number 0 to 64 (0 turns it off)")
        if not 0.0 <= self.side_memory <= 1.0:
            raise ValueError("side_memory must be in [0, 1]")
        if not 0.0 <= self.return_radius <= 2.0:
            raise ValueError("return_radius must be in [0, 2] m (0 turns it off)")

    def distance(self, category: str) -> float:
        """delta_c: the association distance of ``category``."""
        return self.per_category.get(category, self.default_distance)

    def retracts(self, v: Node) -> bool:
        """Whether ``v``, taken off now, is retracted rather than removed: matched in at most
        ``retract_observations`` frames in all, so the map never trusted an object there."""
        return v.observations <= self.retract_observations

    def contradicted(self, v: Node, session: int, stamp: float) -> float | None:
        """Seconds since a frame of ``session`` matched ``v``, taken off at ``stamp``, where that
        is at most ``retract_within`` (None otherwise): the misses contradict a sighting of the
        same visit, so ``v`` is retracted, not removed."""
        if self.retract_within <= 0 or v.last_seen is None or v.last_session != session:
            return None
        since = stamp - v.last_seen
        return since if 0.0 <= since <= self.retract_within else None

    def largest_distance(self) -> float:
        """The largest delta_c of any category: the spatial index's cell size."""
        return max([self.default_distance, *self.per_category.values()])
