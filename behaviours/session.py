"""Session bookkeeping: a monitor pass opens a numbered session and closes it with a report.

The store records the start, the end, the outcome and the counts; the per-session report
(JSON, Markdown and a PNG of the semantic map) is written into ``sessions/<n>/``.
"""

from __future__ import annotations

from dataclasses import dataclass

from py_trees.common import Status

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
