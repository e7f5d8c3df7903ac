"""``bomc evaluate``'s change section: session N's reported changes against the world's.

Both sides compare the end of the previous *recorded* pass with the end of pass N, so a
session that was never run in between does not split the changes in two: the truth is
what stood in the building when each pass ended (intra-session changes up to then
included, as the object protocol does), the map is the store's history replayed to the
end of each pass. Before session 1 there is no pass and no map: it is scored against the
empty map. The rules are in :mod:`bomc_bt.change_evaluation`; the JSON extends
CONTRACTS.md section 4 with a ``changes`` key.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bomc_bt.change_evaluation import (
    CHANGE_KINDS,
    ChangeResult,
    ObjectChange,
    first_seen_count,
    raw_event_counts,
    reported_changes,
    retracted_nodes,
    score_changes,
    true_changes,
    undone_changes,
)
from bomc_bt.config import Config
from bomc_bt.errors import BomcError
from bomc_bt.evaluation import ClassScores
from bomc_bt.graph import Event, ObjectGraph
from bomc_bt.site_reader import open_graph
from bomc_bt.store import SessionRecord
from bomc_bt.world import World, load_world


def evaluate_changes(world: str | Path | World, site_dir: str | Path, session: int, config: Config) -> ChangeResult:
    """Score the net changes pass ``session`` made against the true ones since the previous pass."""
    world = world if isinstance(world, World) else load_world(world)
    with open_graph(site_dir) as store:  # a site directory or a postgresql:// floor
        recorded = {s.number: s for s in store.sessions()}
        if session not in recorded:
            known = ", ".join(map(str, sorted(recorded))) or "none"
            raise BomcError(f"session {session} was not recorded (recorded: {known})", store.path, "--session")
        history = store.events(until=session)
    threshold = ObjectGraph(config.association).threshold
    previous = max((n for n in recorded if n < session), default=None)
    before = None if previous is None else _score(world, recorded, history, previous, threshold, [])
    # the first pass is scored against the empty map: an object it missed was no change in the
    # building, so a later pass reporting it "added" is a phantom, not a late change; what the
    # building did during it (its intra-session changes) is real all the same
    missed_before = [] if before is None else _undone(world, recorded, before.previous, previous, threshold)
    if before is not None and before.previous is not None:
        missed_before += before.missed
    return _score(world, recorded, history, session, threshold, missed_before)


def _present(objects) -> dict[str, tuple[str, np.ndarray]]:
    return {name: (o.category, np.asarray(o.position, dtype=float)) for name, o in objects.items()}


def _undone(world: World, recorded: dict[int, SessionRecord], previous: int | None, session: int,
            threshold: Callable[[str], float]) -> list[ObjectChange]:
    """The changes undone between the end of pass ``previous`` (before session 1: the empty
    map it is scored against, so what stood when session 1 began and went during it counts)
    and the end of pass ``session``, from each state of the building to the next
    (:func:`~bomc_bt.change_evaluation.undone_changes`)."""
    states = [{}] if previous is None else []
    for m in range(previous or 1, session + 1):
        ended = recorded[m].ended_stamp if m in recorded else None
        ended = float("inf") if ended is None else ended
        if m == previous:
            states.append(_present(world.ground_truth(m, at=ended)))
        else:
            states.append(_present(world.objects_in_session(m)))
        times = [d.at for d in world.during_changes(m) if (d.at > ended if m == previous else d.at <= ended)]
        states += [_present(world.ground_truth(m, at=t)) for t in times]
    return undone_changes(states, threshold)


def _score(world: World, recorded: dict[int, SessionRecord], history: list[Event], session: int,
           threshold: Callable[[str], float], missed_before: list[ObjectChange]) -> ChangeResult:
    """Pass ``session`` against the previous recorded one (``history``: events up to at least its end)."""
    previous = max((n for n in recorded if n < session), default=None)
    history = [e for e in history if e.session <= session]

    def truth_at_end(n: int | None) -> dict[str, tuple[str, np.ndarray]]:
        return {} if n is None else _present(world.ground_truth(n, at=recorded[n].ended_stamp))

    truth = true_changes(truth_at_end(previous), truth_at_end(session), threshold)
    net = reported_changes(history, previous, threshold)
    events = [e for e in history if e.session == session]
    undone = _undone(world, recorded, previous, session, threshold)
    result = score_changes(truth, net, threshold, session, previous, raw_event_counts(events), missed_before, undone)
    result.first_seen = first_seen_count(history, previous, threshold)
    result.retracted = retracted_nodes(history, previous, threshold)
    return result


def _r(x: float | None) -> float | None:
    return None if x is None else round(x, 3)


def _kind_json(s: ClassScores) -> dict[str, Any]:
    return {"true": s.gt, "net": s.mapped, "tp": s.tp, "fp": s.fp, "fn": s.fn,
            "precision": _r(s.precision), "recall": _r(s.recall), "f1": _r(s.f1)}


def changes_to_json(result: ChangeResult) -> dict[str, Any]:
    """The ``changes`` key of ``bomc evaluate --json`` (numbers to 3 decimals)."""
    out: dict[str, Any] = {"previous_session": result.previous}
    out.update({kind: _kind_json(result.kinds[kind]) for kind in CHANGE_KINDS})
    out["overall"] = _kind_json(result.overall)
    out["phantom"] = result.phantom
    out["late"] = len(result.late)
    out["transient"] = len(result.transient)
    out["raw_events"] = dict(result.raw_events)
    out["first_seen"] = result.first_seen
    out["retracted"] = result.retracted
    return out


def format_changes(result: ChangeResult) -> str:
    """A plain-text table of the pass's change scores, then what it missed and its phantoms."""
    def f(x):
        return "-" if x is None else f"{x:.3f}"

    def describe(c) -> str:
        ends = [", ".join(f"{v:.2f}" for v in p[:2]) for p in (c.old, c.new) if p is not None]
        who = c.key if isinstance(c.key, str) else f"node {c.key}"
        return f"{c.kind} {who} ({c.category}) at (" + ") -> (".join(ends) + ")"

    since = "the empty map" if result.previous is None else f"session {result.previous}"
    lines = [f"changes since {since}",
             f"{'change':<16} {'true':>4} {'net':>4} {'tp':>4} {'fp':>4} {'fn':>4} {'prec':>6} {'rec':>6} {'f1':>6}"]
    for name, s in [*((k, result.kinds[k]) for k in CHANGE_KINDS), ("overall", result.overall)]:
        lines.append(f"{name:<16} {s.gt:>4} {s.mapped:>4} {s.tp:>4} {s.fp:>4} {s.fn:>4} "
                     f"{f(s.precision):>6} {f(s.recall):>6} {f(s.f1):>6}")
    raw = ", ".join(f"{k} {v}" for k, v in result.raw_events.items())
    lines.append(f"phantom {result.phantom}; late {len(result.late)} (the previous pass's misses); "
                 f"transient {len(result.transient)} (changes undone before the pass ended); "
                 f"first seen {result.first_seen} (new to the map, not scored); "
                 f"retracted {result.retracted} (seen too seldom to trust, not scored); "
                 f"raw events {raw or 'none'}")
    label = ({id(c): "phantom:" for c in result.phantoms} | {id(c): "late:   " for c in result.late}
             | {id(c): "transient:" for c in result.transient})
    lines += [f"  missed:  {describe(c)}" for c in result.missed]
    lines += [f"  {label.get(id(c), 'wrong:  ')} {describe(c)}" for c in result.wrong]
    return "\n".join(lines)
