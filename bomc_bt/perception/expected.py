"""Which nodes a frame can deny: the evidence of absence a miss needs.

A node that a frame does not detect counts a miss (robust association) only when the frame
would have shown the object well: the node lies within ``projection.expect_range`` of the
camera, and most of its body -- not only its centre -- projects into the image with no
nearer surface in front of it. Testing the centre alone took a door leaf seen through its
doorway at a grazing angle for "in plain view" when the corridor wall hid two thirds of
it; the detector missed it three frames in a row and the node was removed, then found
again two seconds later (issue 17: 10 of 55 nodes flipped in a static first pass). Such
a view is no evidence either way.

A flat object seen edge-on is no evidence either: a door leaf on the side wall of a narrow
corridor, seen from along the corridor, is a sliver in the image that detectors miss (the
``hard`` simulated detector does, as the paper's did). Its misses counted, the node was
removed and a door across the corridor, 2 m away, took its id as a "move" (issue 17, hard
preset on office-s). With ``projection.expect_edge_on_deg`` below 90 (opt-in: measured, it
raised the hard preset's object F1 but not its change scores), a flat node (a floor footprint
at least ``FLAT_ASPECT`` times longer than wide, :mod:`bomc_bt.graph.faces`) seen more than that
from its face's normal is not expected. Footprints are axis-aligned boxes, so this knows the
faces of walls' doors (the generator's, and most buildings'); a flat object standing
diagonally has a square box and is always expected, as before.

How much a miss weighs (:func:`miss_weights`): 1 within ``projection.miss_full_range``
of the camera, falling linearly to nothing at ``expect_range``. Any detector misses far
objects more often (fewer pixels, more depth noise); three far misses in a row happen to
a present object, three near ones rarely. For the same reason a flat node's miss weighs in
full only seen within ``projection.miss_face_on_deg`` of its face's normal, less as the
cosine of the angle falls (the width the image shows), nothing at ``expect_edge_on_deg``:
a door leaf seen along its corridor at 62-66 degrees was missed three frames in a row and
removed with 86 sightings behind it, and one approached along its wall at 77-79 degrees
was missed five frames in a row (``hard`` preset, 36 x 28 m and 93 x 90 m offices). Seen
face-on, a duplicate or a false door goes on three misses as before. Opt-in (measured, it
cut the small office's phantoms but not the large floor's: docs/association.md).

A miss also needs the node's place seen empty (``projection.absence_margin``, robust mode):
the depth at the node's centre lies more than the margin beyond it (the camera sees past
where the object stood), or whatever fills it rises to wall height. A chair seen only over
the table in front has its node's centre at the top of its back; the detector misses the
barely visible chair frame after frame, and its misses removed it while it stood there
(issue 17: 3 of 10 phantoms on two static Environment-A-size floors). The depth camera
shows something at the node's place no higher than furniture, and nothing the detector
found there, which is no evidence of absence. Two exceptions keep misses where they did
their work before: a place one of the frame's detections of the node's category covers is
explained by that object (a second node on one table is a duplicate, removed by its misses
as ever; a detection of another kind there is what hides the node: the table in front,
whose mask a segmenter spills over the chair's back above it), and a
false detection on a wall stays removable, since the wall fills its place and also the
view 0.5-0.8 m above it, where no chair, table or bin reaches (a camera tilted down may
not show that high above a near node; then the miss counts, as before). A wall's face more
than the margin in front of the node's centre is no such detection, though: the place lies
behind the wall from here. A door's node made from views of one end of its leaf stands at
the jamb; seen past the jamb, its centre 0.17 m behind the wall's end, the door out of
sight, three misses removed it (static 36 x 28 m office, seed 4416, in more than one run).
Nor does an object of another kind that the frame sees standing in the node's place hold
it (:func:`place_taken`): that object is what fills it, and the node's own kind was not
detected there (a plant put where a chair stood).

The body is sampled at the node's centroid height: its centre and, when the node has a
floor footprint, the footprint's corners pulled ``_INSET`` towards the middle (the true
outline is noisy and a corner against a wall must not read as hidden by it).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bomc_bt.algorithm_params import ProjectionParams
from bomc_bt.graph import Node, Observation
from bomc_bt.graph.faces import facing as face_facing
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.projection import pixels, visible
from bomc_bt.robot import RGBDFrame

_INSET = 0.2  # share of the footprint's half-size the sampled corners lie inside it
# m: above a node's centre, a surface this high up is a wall's, not furniture's; the highest
# of these rises the image shows is looked at (a camera tilted down shows less above near nodes)
_WALL_RISES = (0.8, 0.65, 0.5)
_TAKEN_RISE = 0.5  # m: how far above or below a node's centre another object still stands in its place


def body_samples(node: Node) -> np.ndarray:
    """(k, 3) points on the node's object: its centre first, then its footprint's inset corners."""
    centre = np.asarray(node.position, dtype=float).reshape(1, 3)
    fp = node.footprint
    if fp is None:
        return centre
    mid = np.array([(fp[0] + fp[2]) / 2.0, (fp[1] + fp[3]) / 2.0])
    corners = np.array([[fp[0], fp[1]], [fp[2], fp[1]], [fp[2], fp[3]], [fp[0], fp[3]]])
    corners = mid + (corners - mid) * (1.0 - _INSET)
    z = np.full((4, 1), centre[0, 2])
    return np.vstack([centre, np.hstack([corners, z])])


def expected_nodes(frame: RGBDFrame, candidates: Sequence[Node], params: ProjectionParams) -> list[Node]:
    """The ``candidates`` (nodes inside the field-of-view polygon) this frame is evidence about.

    A node is expected when it lies within ``expect_range`` of the camera, its centre is
    visible (:func:`visible`) and at least ``expect_visible`` of its body samples are.
    """
    if not candidates:
        return []
    samples = [body_samples(n) for n in candidates]
    owner = np.concatenate([np.full(len(s), i) for i, s in enumerate(samples)])
    points = np.vstack(samples)
    camera = frame.T_map_camera[:3, 3]
    seen = visible(frame, points)
    counts = np.bincount(owner, minlength=len(candidates))
    fraction = np.bincount(owner, weights=seen.astype(float), minlength=len(candidates)) / counts
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    centres = points[first]
    near = np.hypot(centres[:, 0] - camera[0], centres[:, 1] - camera[1]) <= params.expect_range
    keep = near & seen[first] & (fraction >= params.expect_visible)
    if params.expect_edge_on_deg < 90.0:
        keep &= ~edge_on(candidates, camera[:2], params.expect_edge_on_deg)
    return [n for n, k in zip(candidates, keep, strict=True) if k]


def edge_on(nodes: Sequence[Node], camera_xy: np.ndarray, limit_deg: float) -> np.ndarray:
    """Per node: a flat footprint seen more than ``limit_deg`` from its face's normal."""
    return facing(nodes, camera_xy) < np.cos(np.radians(limit_deg))


def facing(nodes: Sequence[Node], camera_xy: np.ndarray) -> np.ndarray:
    """Per node: the cosine of the angle between the view ray and a flat footprint's face
    normal (1: face-on, 0: edge-on); 1 for a node that is not flat or has no footprint."""
    return np.array([face_facing(node, camera_xy) for node in nodes], dtype=float).reshape(len(nodes))


def edge_on_weights(nodes: Sequence[Node], camera_xy: np.ndarray, params: ProjectionParams) -> np.ndarray:
    """Per node, how much of a miss's weight its viewing angle leaves (module docstring)."""
    full, zero = np.cos(np.radians(params.miss_face_on_deg)), np.cos(np.radians(params.expect_edge_on_deg))
    if params.miss_face_on_deg >= min(90.0, params.expect_edge_on_deg):
        return np.ones(len(nodes))
    return np.clip((facing(nodes, camera_xy) - zero) / (full - zero), 0.0, 1.0)


def miss_weights(frame: RGBDFrame, nodes: Sequence[Node], params: ProjectionParams,
                 detections: Sequence[Detection] = (), observations: Sequence[Observation] = (),
                 taken_radius: float = 0.0) -> list[float]:
    """Per expected node, how much its absence from this frame weighs (see the module docstring).

    ``detections`` are the frame's own: a place one of them covers is explained, not held.
    ``observations`` are their map-frame objects: a place where one of another category
    stands (:func:`place_taken`, within ``taken_radius``; 0: never) is never held.
    """
    if not nodes:
        return []
    camera = frame.T_map_camera[:3, 3]
    xy = np.array([n.position[:2] for n in nodes], dtype=float)
    distance = np.hypot(xy[:, 0] - camera[0], xy[:, 1] - camera[1])
    span = params.expect_range - params.miss_full_range
    weights = np.ones(len(nodes)) if span <= 0.0 else np.clip((params.expect_range - distance) / span, 0.0, 1.0)
    weights = weights * edge_on_weights(nodes, camera[:2], params)
    if params.absence_margin > 0.0:
        held = place_held(frame, nodes, params.absence_margin, detections)
        weights[held & ~place_taken(nodes, observations, taken_radius)] = 0.0
    return weights.tolist()


def place_taken(nodes: Sequence[Node], observations: Sequence[Observation], radius: float) -> np.ndarray:
    """Per node: an object of another category stands where it stood, seen in this frame.

    Within ``radius`` of the node's centre on the floor and ``_TAKEN_RISE`` of its height (a
    television on a cabinet stands above it, not in its place). Whatever fills the node's
    place is then that object, detected as what it is, and the node's own kind was not
    detected there: a chair moved away before a pass, a plant put where it stood during the
    pass (36 x 28 m office, seed 7503, pass 4). Held, the chair's node stayed and the
    plant's sightings, on the chair's node, counted only in frames that also saw the chair
    (:mod:`bomc_bt.graph.confusions`): neither ever changed.

    Only for a node no frame of this pass has seen (``last_seen`` None): one this pass saw
    as its own kind, named otherwise at its place, is the detector confusing it (one object,
    one label), which a detector may do from one viewpoint frame after frame. A node not
    yet seen and named otherwise once counts one miss, which its next sighting ends.
    ``last_seen`` is saved with the resume point (:meth:`ObjectGraph.pass_state
    <bomc_bt.graph.ObjectGraph.pass_state>`), so a resumed pass tells them apart as the pass did.
    """
    if radius <= 0.0 or not observations or not nodes:
        return np.zeros(len(nodes), dtype=bool)
    at = np.array([n.position for n in nodes], dtype=float)
    seen = np.array([o.position for o in observations], dtype=float)
    offset = seen[None, :, :] - at[:, None, :]  # (nodes, observations, xyz)
    other = np.array([[o.category != n.category for o in observations] for n in nodes])
    there = (np.hypot(offset[..., 0], offset[..., 1]) <= radius) & (np.abs(offset[..., 2]) <= _TAKEN_RISE)
    unseen = np.array([n.last_seen is None for n in nodes])
    return unseen & (other & there).any(axis=1)


def place_held(frame: RGBDFrame, nodes: Sequence[Node], margin: float,
               detections: Sequence[Detection] = ()) -> np.ndarray:
    """Per node: the frame shows something furniture-high and undetected where the node stands.

    Held: the depth at the node's centre is no more than ``margin`` beyond it, no detection
    of the node's category covers that pixel (a detected object of its kind there explains
    it: the node is a duplicate or a neighbour's, and its miss counts as ever; one of another
    kind is what hides it, like the table in front of a chair), and either the view above
    it is not filled too (a wall would fill both: the highest of ``_WALL_RISES`` above the
    centre that the image shows must be seen past; when none of them is in the image, the
    wall test cannot be made) or the surface there stands more than ``margin`` in front of
    the centre. A false detection on a wall has its centre on the wall's face, so any view
    of it meets the face there; a surface in front of the centre hides the place instead (a
    door's node at the end of its leaf, seen past the jamb). A point without valid depth
    holds nothing.
    """
    centres = np.array([n.position for n in nodes], dtype=float).reshape(-1, 3)
    u, v, _, filled = _filled(frame, centres, margin)
    in_front = _filled(frame, centres, -margin)[3]
    categories = np.array([n.category for n in nodes], dtype=object)
    for d in detections:
        mine = filled & (categories == d.category)
        mine[mine] = _covers(d, u[mine], v[mine])
        filled &= ~mine
    judged = np.zeros(len(centres), dtype=bool)
    clear_above = np.zeros(len(centres), dtype=bool)
    for rise in _WALL_RISES:
        _, _, inside, wall = _filled(frame, centres + np.array([0.0, 0.0, rise]), margin)
        pick = inside & ~judged
        clear_above[pick] = ~wall[pick]
        judged |= inside
    return filled & (clear_above | in_front)


def _filled(frame: RGBDFrame, points: np.ndarray,
            margin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixel columns and rows of map-frame ``points``, whether each is inside the image, and
    whether its pixel has valid depth no more than ``margin`` beyond it (a negative margin:
    at least that much in front of it)."""
    u, v, z, inside = pixels(frame, points)
    with np.errstate(invalid="ignore"):
        out = inside & (frame.depth[v, u] <= z + margin)  # NaN compares False
    return u, v, inside, out


def _covers(detection: Detection, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per pixel (column ``u``, row ``v``): inside the detection's mask, or its box without one."""
    if detection.mask is not None:
        return detection.mask[v, u]
    x0, y0, x1, y1 = detection.box
    return (u >= x0) & (u <= x1) & (v >= y0) & (v <= y1)
