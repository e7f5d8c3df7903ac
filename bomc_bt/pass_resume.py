"""Exact resume of a monitor pass: what is committed with its progress, and putting it back.

A killed pass resumed with ``bomc monitor --resume`` must be the uninterrupted pass
continued, not replayed: an intra-session change applied before the kill stays applied
(a chair moved during the pass is not put back), robot time goes on from where it was,
and the detector sees what it would have seen. So every commit of the pass -- each
frame's graph update (:meth:`Perception.process <bomc_bt.monitoring.Perception.process>`)
and each waypoint's bookkeeping (:func:`bomc_bt.monitor_pass.save_pass`) -- writes, in the
same SQLite transaction, a *resume point* (progress key ``resume/<session>`` and the rows of its
parts below it, each written only when it changed: :mod:`bomc_bt.resume_rows`):

* ``robot``: the robot's own state where it can give one (the simulator: robot time,
  true pose, the world's applied changes, random streams; :mod:`bomc_bt.sim.checkpoint`);
  a real robot gives none and keeps its own time and place;
* ``graph``: what the object graph holds in memory only (last seen times, pending
  misses, move candidates, first sightings; :meth:`ObjectGraph.pass_state`);
* ``frames`` and ``fov_since``: frames processed and the view polygons since the last
  coverage snapshot, which the waypoint commit writes (``coverage/<session>``, packed), so
  the camera's observed area survives the kill too; ``looked_since`` and ``looked/<session>``
  likewise for the part of it within ``projection.expect_range`` (:mod:`bomc_bt.first_seen`),
  and ``sighted_since`` and ``sightings/<session>`` for where its detections put objects
  (:mod:`bomc_bt.sightings`).

The plan's position (``traverse/<session>``) is the waypoint in flight: a resumed pass
drives on to it from the restored pose. Only the frames after the last commit are lost.
"""

from __future__ import annotations

import base64
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.graph.history import withdrawn_nodes
from bomc_bt.json_text import JSONMemo
from bomc_bt.looked_sides import looked_sides_key
from bomc_bt.resume_rows import load_resume_point, resume_key


def coverage_key(session: int) -> str:
    return f"coverage/{session}"


def looked_key(session: int) -> str:
    """The floor the pass saw within ``projection.expect_range`` (:mod:`bomc_bt.first_seen`)."""
    return f"looked/{session}"


def sightings_key(session: int) -> str:
    """Where the pass's detections put objects, per category (:mod:`bomc_bt.sightings`)."""
    return f"sightings/{session}"


def near_key(session: int) -> str:
    """The snapshot of the coverage's ``near`` part (what the change model counts as looked at)."""
    return f"coverage_near/{session}"


def resume_point(perception, robot, memo: JSONMemo | None = None) -> dict[str, Any]:
    """The pass's state at this moment (see the module docstring; ``memo``: the graph's maps
    as text, :meth:`ObjectGraph.pass_state <bomc_bt.graph.ObjectGraph.pass_state>`)."""
    checkpoint = getattr(robot, "checkpoint", None)
    return {
        "robot": checkpoint() if callable(checkpoint) else None,
        "graph": perception.graph.pass_state(memo),
        "frames": perception.frames,
        "fov_since": perception.fov_since,
        "looked_since": perception.looked_since,
        "sighted_since": perception.sightings.since,
    }


def frame_progress(perception, robot) -> dict[str, Any]:
    """The progress rows a frame's commit writes: the resume point's that changed
    (:class:`~bomc_bt.resume_rows.ResumeRows`; call its ``written`` once they are)."""
    rows = perception.resume_rows
    return rows.rows(perception.session, resume_point(perception, robot, rows.graph))


def waypoint_progress(perception, robot) -> dict[str, Any]:
    """The progress keys a waypoint's commit writes besides the plan: a coverage snapshot
    and the resume point (whose lists of view polygons start again after the snapshot)."""
    perception.fov_since, perception.looked_since, perception.sightings.since = [], [], []
    return {**coverage_masks(perception), **frame_progress(perception, robot)}


def coverage_masks(perception) -> dict[str, str]:
    """The progress keys of the pass's coverage masks, packed: the whole view fans, their
    parts within reach, and the coverage's ``near`` part where it has one (a waypoint's
    snapshot, and the final masks the session's end writes)."""
    session, coverage = perception.session, perception.coverage
    extra = {near_key(session): pack_mask(coverage.near)} if coverage.near is not coverage.seen else {}
    sides = getattr(perception, "looked_sides", None)
    if sides is not None:  # and from which sides it looked (bomc_bt.looked_sides)
        extra[looked_sides_key(session)] = sides.packed()
    return {coverage_key(session): pack_mask(coverage.seen), looked_key(session): pack_mask(perception.looked.seen),
            sightings_key(session): perception.sightings.packed(), **extra}


def _earlier_graphs(store, session: int) -> Iterator[dict]:
    """The graph states (:meth:`~bomc_bt.graph.ObjectGraph.pass_state`) the earlier passes with a
    resume point saved last, the latest first."""
    for earlier in sorted((s.number for s in store.sessions() if s.number < session), reverse=True):
        point = load_resume_point(store, earlier)
        if isinstance(point, dict):
            yield point.get("graph") or {}


def earlier_co_observed(store, session: int) -> list[tuple[int, int]]:
    """The node pairs the latest earlier pass with a resume point saw as two objects in one
    frame (:mod:`bomc_bt.graph.co_observed`; that pass's own and those it carried); none
    before the first pass or where no earlier pass saved one."""
    for graph in _earlier_graphs(store, session):
        state = graph.get("co_observed") or {}
        if state.get("pairs") is not None:
            return [(int(a), int(b)) for a, b in state["pairs"]]
    return []


def earlier_sides(store, session: int) -> dict | None:
    """The per-side detection counts (:mod:`bomc_bt.graph.view_sides`) the latest earlier pass
    with a resume point ended with; None where it saved none (before the first pass, or a pass
    run without them)."""
    return next((graph.get("sides") for graph in _earlier_graphs(store, session)), None)


def earlier_looks(store, session: int) -> set[int]:
    """The nodes the latest earlier pass with a resume point ended awaiting a second look, or
    began with an earlier pass's look at that no detection ended since
    (:meth:`~bomc_bt.graph.evidence.MissEvidence.looks_json`; ``association.miss_spacing``)."""
    state = next((graph.get("second_looks") or {} for graph in _earlier_graphs(store, session)), {})
    return {int(i) for i in [*state.get("before", []), *state.get("awaiting", [])]}


def restore_pass(store, session: int, robot, perception) -> bool:
    """Put a killed pass's saved state back into ``robot`` and ``perception`` (and its
    graph); False when nothing was saved (the pass was killed before its first commit)."""
    point = load_resume_point(store, session)
    if not isinstance(point, dict):
        return False
    restore = getattr(robot, "restore", None)
    with _corrupt(store, f"the saved resume point of session {session} (or a part below it) is not one this "
                         f"pass can take up", resume_key(session)):
        if point.get("robot") is not None and callable(restore):
            restore(point["robot"])
        removed = {n.id: n for n in store.nodes(include_removed=True) if n.state != "present"}
        perception.graph.restore_pass_state(point.get("graph") or {}, removed)
    if isinstance(getattr(perception.graph.policy, "withdrawn", None), set):  # robust: what it retracted
        perception.graph.policy.withdrawn = withdrawn_nodes(store.events(session=session))
    perception.frames = int(point.get("frames", 0))
    coverage = perception.coverage
    snapshot = saved_mask(store, session, coverage_key(session), coverage.seen.shape)
    if snapshot is not None:
        coverage.seen[:] = snapshot
    near = saved_mask(store, session, near_key(session), coverage.near.shape, "near coverage")
    if coverage.near is not coverage.seen and (near if near is not None else snapshot) is not None:
        coverage.near[:] = near if near is not None else snapshot  # older: all seen
    looked = saved_mask(store, session, looked_key(session), perception.looked.seen.shape, "looked-at floor")
    if looked is not None:
        perception.looked.seen[:] = looked
    sides = getattr(perception, "looked_sides", None)
    if sides is not None and looked is not None:
        with _corrupt(store, f"the saved looked-at sides of session {session} are not of this map",
                      looked_sides_key(session)):
            sides.restore(store.get_progress(looked_sides_key(session)), perception.looked.seen)
    sightings = store.get_progress(sightings_key(session))
    if isinstance(sightings, dict):
        with _corrupt(store, f"the saved sightings of session {session} are not masks of this map",
                      sightings_key(session)):
            perception.sightings.restore(sightings)
    perception.sightings.add_points(point.get("sighted_since", []))
    for polygon in point.get("fov_since", []):
        coverage.add(np.asarray(polygon, dtype=float))
    for polygon in point.get("looked_since", []):
        perception.looked.add(np.asarray(polygon, dtype=float))
        if sides is not None:
            sides.add(np.asarray(polygon, dtype=float))
    perception.fov_since = list(point.get("fov_since", []))
    perception.looked_since = list(point.get("looked_since", []))
    perception.events = list(store.events(session=session))
    return point.get("robot") is not None and callable(restore)


@contextmanager
def _corrupt(store, what: str, key: str) -> Iterator[None]:
    """A saved value that does not unpack is a corrupt store: one line naming its progress key."""
    try:
        yield
    except (ValueError, TypeError, KeyError, IndexError, zlib.error) as exc:  # binascii.Error is a ValueError
        raise BomcError(f"corrupt site store: {what} ({type(exc).__name__}: {exc})", store.path,
                        f"progress.{key}") from None


def saved_mask(store, session: int, key: str, shape: tuple[int, ...], what: str = "coverage") -> np.ndarray | None:
    """The 0/1 mask saved under progress ``key`` (uint8, ``shape``), None when none was; one
    that is not a mask of this map is a corrupt store (one line naming the key), met before the
    pass writes anything."""
    text = store.get_progress(key)
    if text is None:
        return None
    try:
        bits = zlib.decompress(base64.b64decode(text, validate=True)) if isinstance(text, str) else None
    except (ValueError, zlib.error):  # binascii.Error is a ValueError
        bits = None
    if bits is None or len(bits) != -(-int(np.prod(shape)) // 8):
        raise BomcError(f"corrupt site store: the saved {what} of session {session} is not a mask of this "
                        f"map ({shape[-1]} x {shape[0]} cells)", store.path, f"progress.{key}")
    return np.unpackbits(np.frombuffer(bits, dtype=np.uint8))[:int(np.prod(shape))].reshape(shape)


def pack_mask(mask: np.ndarray) -> str:
    """A 0/1 mask as compressed text (a monitor map's coverage is mostly runs). Bytes and
    bools are packed as they are (``packbits`` takes any nonzero as 1), without a copy;
    zlib's level 1 is 2.5 times as fast as its 6 on an Environment-A-size coverage (0.8 against
    2.0 ms; 12.4 KB against 9.7), and a pass packs it and its like at every waypoint."""
    bits = np.packbits(mask if mask.dtype in (np.uint8, np.bool_) else mask.astype(bool))
    return base64.b64encode(zlib.compress(bits.tobytes(), 1)).decode("ascii")


def unpack_mask(text: str, shape: tuple[int, ...]) -> np.ndarray:
    bits = np.frombuffer(zlib.decompress(base64.b64decode(text)), dtype=np.uint8)
    count = int(np.prod(shape))
    if bits.size * 8 < count:
        raise ValueError("the saved coverage does not fit the map")
    return np.unpackbits(bits)[:count].reshape(shape).astype(np.uint8)
