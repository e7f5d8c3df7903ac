"""Session bookkeeping: a monitor pass opens a numbered session and closes it with a report.

The store records the start, the end, the outcome and the counts; the per-session report
(JSON, Markdown and a PNG of the semantic map) is written into ``sessions/<n>/``.
"""

from __future__ import annotations

from dataclasses import dataclass

from py_trees.common import Status

from bomc_bt.first_seen import first_seen_verdicts, gone_before
from bomc_bt.graph import Event
from bomc_bt.graph.brought_back import BACK_OF
from bomc_bt.monitoring import Perception
from bomc_bt.report import write_session_report
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@register("StartSession")
class StartSession(Leaf):
    """Opens session N in the site store (or picks it up again on --resume)."""

    def update(self) -> Status:
        ctx = self.context
        info = {"stamp": ctx.now(), "seed": ctx.seed, "mission": "monitor"}
        resumed = ctx.store.begin_session(ctx.session, info)
        ctx.progress.nodes = len(ctx.graph.nodes)
        verb = "resumed" if resumed else "started"
        self.feedback_message = f"session {ctx.session} {verb}: {len(ctx.graph.nodes)} nodes in the graph"
        return Status.SUCCESS


@register("PairRelocations")
class PairRelocations(Leaf):
    """Before the session closes: a move of this pass that a node added later at the old
    place undoes is taken back (:mod:`bomc_bt.graph.returns`: a neighbour found late, not
    the object gone), and a removal and an addition of this pass that were one object moved
    become one move (:mod:`bomc_bt.graph.relocations`), and a node that shifted only because
    the pass saw more of it is marked refined (:mod:`bomc_bt.graph.refinement`), written to
    the store at once. Each node the pass added is first judged again where it now stands,
    first seen or added (:meth:`~bomc_bt.first_seen.SeenBefore.final_verdicts`). A node first
    seen in this pass (no earlier pass saw its place) is no arrival, nor is one standing where
    an earlier pass saw one of its kind and look go (:mod:`bomc_bt.graph.brought_back`)."""

    def update(self) -> Status:
        ctx = self.context
        verdicts = self._final_verdicts()  # first: a node first seen where it stands is no arrival
        if verdicts:
            ctx.store.record(verdicts, ctx.graph.drain_changed())
        history = ctx.store.events(session=ctx.session)
        first_seen = {nid for nid, new in first_seen_verdicts(history).items() if new}
        taken_back = ctx.graph.take_back_moves(ctx.session, ctx.now(), history)
        gone = gone_before(ctx.store, ctx.session)
        paired = ctx.graph.pair_relocations(ctx.session, ctx.now(), lambda n: n.id not in first_seen, gone)
        events = taken_back + paired + ctx.graph.mark_refinements(ctx.session, ctx.now())
        if isinstance(ctx.perception, Perception) and ctx.perception.store is not None:
            ctx.perception.commit(events, ctx.graph.drain_changed())  # the state the next pass carries
        elif events:
            ctx.store.record(events, ctx.graph.drain_changed())
        if ctx.perception is not None:
            ctx.perception.events.extend(verdicts + events)
        moves = [f"{e.category} #{e.node_id}" for e in paired if e.kind == "moved"]
        self.feedback_message = f"{len(moves)} removal(s) paired with an addition as moved" + (
            f": {', '.join(moves[:5])}" if moves else "")
        if taken_back:
            back = [f"{e.category} #{e.node_id}" for e in taken_back[::2]]
            self.feedback_message += f"; {len(back)} move(s) taken back: {', '.join(back[:5])}"
        returned = [f"{e.category} #{e.node_id}" for e in paired if e.kind == "updated" and BACK_OF in (e.detail or {})]
        if returned:
            self.feedback_message += f"; {len(returned)} brought back: {', '.join(returned[:5])}"
        if verdicts:
            self.feedback_message += f"; {len(verdicts)} addition(s) judged again where they stand"
        return Status.SUCCESS

    def _final_verdicts(self) -> list[Event]:
        """An ``updated`` event per node this pass added whose verdict, first seen or added,
        is another at its final place (:meth:`~bomc_bt.first_seen.SeenBefore.final_verdicts`)."""
        ctx = self.context
        seen = ctx.perception.seen_before if ctx.perception is not None else None
        if seen is None:
            return []
        arrivals = [n for n in ctx.graph.nodes.values() if n.first_session == ctx.session]
        events = []
        for node, verdict in seen.final_verdicts(arrivals, ctx.store.events(session=ctx.session)):
            events.append(ctx.graph.report("updated", node, ctx.session, ctx.now()))
            events[-1].detail = verdict
        return events


@dataclass
class EndSessionParams:
    outcome: str = "completed"


@register("EndSession")
class EndSession(Leaf):
    """Closes the session with its outcome and writes the session report.

    An outcome a leaf already decided (``ended_early``: the pass gave up on being stuck,
    :mod:`behaviours.recover`) is kept; ``params.outcome`` is the outcome otherwise.
    """

    Params = EndSessionParams

    def update(self) -> Status:
        ctx = self.context
        ctx.outcome = ctx.outcome or self.params.outcome  # a leaf that ended the pass early said why
        summary = write_session_report(ctx)
        self.feedback_message = (f"session {ctx.session} {ctx.outcome}: {summary['nodes']} nodes, "
                                 f"coverage {summary['coverage']['fraction']:.0%}")
        return Status.SUCCESS
