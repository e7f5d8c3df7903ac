"""``bomc evaluate``: score the graph saved after session N against the world's truth.

The graph is replayed from the store's history as it stood at the end of session N
(history is never overwritten), and compared with the ground truth present when that
pass ended (intra-session changes up to then included), with the association distances
of the configuration (CONTRACTS.md section 4).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bomc_bt.config import Config
from bomc_bt.errors import BomcError
from bomc_bt.evaluation import EvaluationResult, evaluate
from bomc_bt.graph import ObjectGraph
from bomc_bt.miss_causes import Miss, miss_causes
from bomc_bt.site_reader import open_graph
from bomc_bt.world import World, load_world


def evaluate_session(world: str | Path | World, site_dir: str | Path, session: int, config: Config) -> EvaluationResult:
    return _scored(world, site_dir, session, config)[0]


def session_misses(world: str | Path | World, site_dir: str | Path, session: int, config: Config) -> list[Miss]:
    """Session ``session``'s false negatives, each with its cause (:mod:`bomc_bt.miss_causes`)."""
    result, nodes, truth, removed, threshold = _scored(world, site_dir, session, config)
    return miss_causes(result, nodes, removed, truth, threshold)


def _scored(world: str | Path | World, site_dir: str | Path, session: int, config: Config):
    world = world if isinstance(world, World) else load_world(world)
    store = open_graph(site_dir)  # a site directory or a postgresql:// floor (bomc_bt.site_reader)
    try:
        recorded = {s.number: s for s in store.sessions()}
        if session not in recorded:
            known = ", ".join(map(str, sorted(recorded))) or "none"
            raise BomcError(f"session {session} was not recorded (recorded: {known})", store.path, "--session")
        nodes = store.graph_after(session)
        ended_at = recorded[session].ended_stamp
        present_ids = {n.id for n in nodes}
        removed = [(e.category, e.position) for e in store.events(session=session)
                   if e.kind == "removed" and e.node_id not in present_ids]
    finally:
        store.close()
    # The truth is what stood in the building when the pass ended: a change scheduled
    # after the robot finished has not happened yet for this session's map.
    present = world.ground_truth(session, at=ended_at)
    truth = [(o.category, np.asarray(o.position, dtype=float)) for o in present.values()]
    threshold = ObjectGraph(config.association).threshold
    return evaluate(nodes, truth, threshold, session), nodes, truth, removed, threshold


def format_result(result: EvaluationResult) -> str:
    """A plain-text table of one session's scores."""
    def f(x):
        return "-" if x is None else f"{x:.3f}"

    lines = [f"session {result.session}",
             f"{'class':<16} {'gt':>4} {'map':>4} {'tp':>4} {'fp':>4} {'fn':>4} {'prec':>6} {'rec':>6} {'f1':>6}"]
    rows = [*sorted(result.classes.items()), ("overall", result.overall)]
    for name, s in rows:
        lines.append(f"{name:<16} {s.gt:>4} {s.mapped:>4} {s.tp:>4} {s.fp:>4} {s.fn:>4} "
                     f"{f(s.precision):>6} {f(s.recall):>6} {f(s.f1):>6}")
    return "\n".join(lines)
