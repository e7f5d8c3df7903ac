"""Plan the monitor pass: the waypoints, then the gap viewpoints, then the refresh stops.

Each phase's planner is library code (:mod:`bomc_bt.traversal`, :mod:`bomc_bt.viewpoints`,
:mod:`bomc_bt.refresh`); the pass's bookkeeping and its resume are
:mod:`bomc_bt.monitor_pass`. Each leaf plans its phase once per pass and succeeds also
when the phase brings nothing (nothing unseen, nothing stale): an empty phase is no
failure, and the visit loop that follows simply finds no waypoint left.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from py_trees.common import Status

from bomc_bt.budget_pass import budget_key, last_full_pass_seconds, load_model, plan_budget_pass
from bomc_bt.budget_plan import PassBudget
from bomc_bt.coverage_plan import order_stops, plan_coverage
from bomc_bt.graph import PRESENT
from bomc_bt.monitor_pass import extend_pass, open_pass
from bomc_bt.monitoring import GAPS, LAST_LOOKS, REFRESH
from bomc_bt.planner import DrivenLengths, GridPlanner
from bomc_bt.refresh import (
    RefreshParams,
    added_times,
    displaced_nodes,
    object_boxes_by_id,
    refresh_viewpoints,
    sighting_looks,
    stale_nodes,
)
from bomc_bt.site import write_json
from bomc_bt.traversal import TraversalPlan, load_trajectory, plan_traversal, snap_to_free
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register
from bomc_bt.viewpoints import GapParams, gap_viewpoints

EXPECT_RANGE = "projection.expect_range"  # where a frame counts a miss: as far as a viewpoint plans to see
MISS_FULL_RANGE = "projection.miss_full_range"  # where a miss counts fully: each known node is looked at from there


@dataclass
class PlanTraversalParams:
    clearance: float = 0.45  # [m] paper plan: waypoints closer to a wall are moved into the open
    view_range: float = 5.0  # [m] coverage plan: the camera's planned reach (projection.expect_range)
    close_range: float = 2.5  # [m] coverage plan: each known node is seen once from this near (miss_full_range)
    known_radius: float = 0.5  # [m] coverage plan: floor this near a known node shows it (bomc_bt.coverage_known)
    budget: float = 0.0  # [s] robot time for the pass; 0: the configuration's budget.seconds (0 there: a full pass)

    def __post_init__(self) -> None:
        if not (self.close_range >= 0 and self.known_radius > 0):
            raise ValueError("need close_range >= 0 and known_radius > 0")


@register("PlanTraversal")
class PlanTraversal(Leaf):
    """Plans the pass as ``traversal.plan`` says: viewpoints that see the saved map's floor
    in a short tour (coverage), or waypoints sampled along the build trajectory (paper);
    on ``--resume``, picks up the saved pass at its next waypoint instead. With a budget
    (``budget`` here, else ``budget.seconds``, ``bomc monitor --budget``) it plans the tour
    of :mod:`bomc_bt.budget_pass` instead, which ends at the dock in time."""

    Params = PlanTraversalParams
    config_params = {"view_range": EXPECT_RANGE, "close_range": MISS_FULL_RANGE}

    def update(self) -> Status:
        ctx = self.context
        if ctx.traverse is None:
            ctx.traverse = open_pass(ctx.store, ctx.session, ctx.resume, self.plan)
            ctx.plan = ctx.traverse.plan
            saved = ctx.store.get_progress(budget_key(ctx.session)) if ctx.budget is None else None
            if saved:  # a resumed budgeted pass keeps the budget it planned with
                ctx.budget = PassBudget.from_json(saved)
        ctx.progress.waypoints = len(ctx.traverse.states)
        ctx.progress.waypoint = ctx.traverse.done_count
        length = ctx.plan.grid_length or ctx.plan.euclidean_length
        self.feedback_message = f"{len(ctx.plan.waypoints)} waypoints, {length:.0f} m"
        return Status.SUCCESS

    def plan(self) -> TraversalPlan:
        seconds = self.params.budget or self.context.config.budget.seconds
        return self.budget_plan(seconds) if seconds > 0 else self.full_plan()

    def budget_plan(self, seconds: float) -> TraversalPlan:
        """The budgeted tour; the full plan when the budget covers the site's last full pass."""
        ctx = self.context
        p, pose = ctx.config.budget, ctx.robot.pose()
        record = next((s for s in ctx.store.sessions() if s.number == ctx.session), None)
        started = record.started_stamp if record and record.started_stamp is not None else ctx.now()
        full = last_full_pass_seconds([s for s in ctx.store.sessions() if s.number != ctx.session])
        if full is not None and seconds >= full * (1.0 - p.full_tolerance):
            ctx.budget = PassBudget(seconds, p.strategy, p.speed, p.heading_time, started=started, full_pass=True)
            plan = self.full_plan()
        else:
            grid = ctx.robot.live_map()
            model = load_model(ctx.store, grid, ctx.config)
            plan, ctx.budget = plan_budget_pass(grid, ctx.dock or pose, pose, ctx.config, model, ctx.session, seconds,
                                                ctx.now() - started, started, self.params.view_range, self.full_plan)
            ctx.budget.odometer = ctx.robot.distance_travelled  # the way back counts from here
            write_json(ctx.site.plan_json, plan.to_json())
        ctx.store.set_progress(budget_key(ctx.session), ctx.budget.to_json())
        return plan

    def known_nodes(self) -> tuple[np.ndarray, list]:
        """(N, 2) positions of the graph's present nodes, each to be seen once from near, and
        their footprints (None where a node has none)."""
        graph = self.context.graph
        nodes = [n for n in (graph.nodes.values() if graph is not None else ()) if n.state == PRESENT]
        return np.array([n.position[:2] for n in nodes], dtype=float).reshape(-1, 2), [n.footprint for n in nodes]

    def full_plan(self) -> TraversalPlan:
        ctx = self.context
        if ctx.config.traversal.plan == "coverage":
            known, footprints = self.known_nodes()
            covering = plan_coverage(ctx.robot.live_map(), ctx.robot.pose(), self.params.view_range,
                                     ctx.config.traversal, ctx.config.sim.planner, known,
                                     self.params.close_range, self.params.known_radius, footprints)
            write_json(ctx.site.plan_json, covering.plan.to_json())
            return covering.plan
        grid = ctx.robot.live_map()
        trajectory = load_trajectory(ctx.site.trajectory_csv)
        planner = GridPlanner(grid, ctx.config.sim.planner)
        plan = plan_traversal(trajectory, ctx.robot.pose(), ctx.config.traversal, grid_distance=planner.distance)
        plan.waypoints = snap_to_free(grid, plan.waypoints, self.params.clearance)
        write_json(ctx.site.plan_json, plan.to_json())
        return plan


def _budgeted(ctx) -> bool:
    """A pass with a budget spends it on its tour: the later phases would overrun it."""
    return ctx.budget is not None and not ctx.budget.full_pass


class PlanPhase(Leaf):
    """A leaf that appends one phase's viewpoints to the pass, once per pass."""

    phase = ""

    def extend(self, views: list) -> None:
        ctx = self.context
        extend_pass(ctx.store, ctx.session, ctx.traverse, self.phase, views, ctx.perception)
        ctx.progress.waypoints = len(ctx.traverse.states)


@register("PlanGapViewpoints")
class PlanGapViewpoints(PlanPhase):
    """After the waypoints: adds viewpoints that see the floor the camera has not seen
    (see :mod:`bomc_bt.viewpoints`), in the order of a short open tour over path lengths
    from where the robot stands (:func:`bomc_bt.coverage_plan.order_stops`)."""

    Params = GapParams
    config_params = {"view_range": EXPECT_RANGE}
    phase = GAPS

    def update(self) -> Status:
        ctx = self.context
        if _budgeted(ctx):
            self.feedback_message = "a pass with a budget: no gap viewpoints"
            return Status.SUCCESS
        if ctx.traverse.planned(GAPS) or ctx.perception is None:
            self.feedback_message = "gaps already covered" if ctx.traverse.planned(GAPS) else "no perception"
            return Status.SUCCESS
        grid, pose = ctx.robot.live_map(), ctx.robot.pose()
        views = gap_viewpoints(grid, ctx.perception.coverage.seen, pose, self.params)
        if pose is not None and len(views) > 1:
            views = order_stops(GridPlanner(grid, ctx.config.sim.planner), pose.xy, views, ctx.config.traversal)
        self.extend(views)
        self.feedback_message = f"{len(views)} gap viewpoints"
        return Status.SUCCESS


@register("PlanRefreshStops")
class PlanRefreshStops(PlanPhase):
    """Before the pass ends: adds stops that look again at the nodes confirmed longest ago.

    An object taken away after the camera passed it is only noticed if the camera looks
    again (see :mod:`bomc_bt.refresh`). The nodes the stops were planned to decide are
    kept with the pass (``TraversalState.looked_for``) for Plan Last Looks.
    """

    Params = RefreshParams
    config_params = {"view_range": EXPECT_RANGE, "look_range": MISS_FULL_RANGE, "stale_after": "mission.stale_after",
                     "arrival_tolerance": "sim.planner.goal_tolerance"}
    phase = REFRESH

    def update(self) -> Status:
        ctx = self.context
        if _budgeted(ctx):
            self.feedback_message = "a pass with a budget: no refresh stops"
            return Status.SUCCESS
        pose = ctx.robot.pose()
        if ctx.traverse.planned(REFRESH) or ctx.graph is None or pose is None:
            planned = ctx.traverse.planned(REFRESH)
            self.feedback_message = "refresh already planned" if planned else "nothing to refresh"
            return Status.SUCCESS
        now = ctx.now()
        stale = stale_nodes(ctx.graph.nodes.values(), now, self.params.stale_after)
        second_looks, unresolved, sighted = self.targets()
        ctx.traverse.looked_for = {"nodes": sorted({n.id for n, _ in second_looks} | {n.id for n in unresolved})}
        stops = self.plan_stops(stale, second_looks + [(n, None) for n in unresolved] + [(s, None) for s in sighted])
        self.feedback_message = f"{len(stops)} refresh stops for {len(stale)} stale nodes" + (
            f" and {len(second_looks)} awaiting a second look" if second_looks else "") + (
            f" and {len(unresolved)} left unresolved" if unresolved else "") + (
            f" and {len(sighted)} unconfirmed sightings" if sighted else "")
        return Status.SUCCESS

    def targets(self) -> tuple[list, list, list]:
        """What a look must decide: nodes awaiting a second look (each with the place of its
        misses), nodes left unresolved or maybe moved to one the pass added, and the first
        sightings never confirmed (as :class:`~bomc_bt.refresh.SightingLook`)."""
        ctx = self.context
        second_looks = ctx.graph.awaiting_second_look()
        waiting = {n.id for n, _ in second_looks}
        unresolved = [n for n in ctx.graph.unresolved(ctx.session) if n.id not in waiting] \
            if self.params.unresolved else []
        if self.params.unresolved:  # and those that may have moved to a node this pass added
            events = ctx.perception.events if ctx.perception is not None else []
            added_at = added_times(events)
            taken = waiting | {n.id for n in unresolved}
            unresolved += [n for n in displaced_nodes(ctx.graph.nodes.values(), added_at, ctx.session,
                                                      ctx.graph.params.relocation_radius) if n.id not in taken]
        near = self.params.look_range if self.params.look_range > self.params.min_range else self.params.view_range
        sighted = sighting_looks(ctx.graph.unconfirmed_sightings(near)) if self.params.unconfirmed else []
        return second_looks, unresolved, sighted

    def plan_stops(self, stale: list, looks: list) -> list:
        """Plan the stops for ``stale`` nodes and ``looks`` within the budget; append them as this phase."""
        ctx = self.context
        grid = ctx.robot.live_map()
        distances = DrivenLengths(grid, ctx.config.sim.planner)
        budget = self.params.budget * (ctx.plan.grid_length or ctx.plan.euclidean_length)
        boxes, ids = object_boxes_by_id(ctx.graph) if looks else (None, None)
        stops = refresh_viewpoints(grid, stale, ctx.now(), ctx.traverse.reached(), ctx.robot.pose(), budget,
                                   distances, self.params, looks, ctx.graph.params.miss_spacing, boxes, ids)
        self.extend(stops)
        return stops


@register("PlanLastLooks")
class PlanLastLooks(PlanRefreshStops):
    """After the refresh stops: one look at the nodes that came up while the robot drove them.

    The refresh tour looks at the nodes the pass added on their confirming sightings alone
    and matched in no frame since (two false detections at one place), and at the nodes of
    earlier passes that may have moved to one it added, but it is planned before it is
    driven: such a node added on the way was decided by nobody, and the map kept it for a
    pass (93 x 90 m office, seed 7921, pass 3: a potted plant added at a refresh stop
    stayed, a phantom addition). This leaf plans stops for those two kinds of target the
    refresh tour was not planned for (``TraversalState.looked_for``), within its own budget.
    Not for first sightings or nodes missed up close on the way: Look Around turns to those
    at the next stops, and a stop for each (most sightings are false positives, most misses
    a detector's) made office-s's passes 1-3 % longer for nothing found.
    """

    phase = LAST_LOOKS

    def update(self) -> Status:
        ctx = self.context
        if ctx.traverse.planned(LAST_LOOKS) or not ctx.traverse.planned(REFRESH) or ctx.graph is None \
                or ctx.robot.pose() is None:
            self.feedback_message = "last looks already planned" if ctx.traverse.planned(LAST_LOOKS) \
                else "no refresh tour before"
            return Status.SUCCESS
        planned = set(ctx.traverse.looked_for.get("nodes", []))
        looks = [(n, None) for n in self.new_doubts() if n.id not in planned]
        stops = self.plan_stops([], looks) if looks else []
        if not looks:
            self.extend(stops)  # planned, and empty
        self.feedback_message = f"{len(stops)} last looks for {len(looks)} nodes new since the refresh plan"
        return Status.SUCCESS

    def new_doubts(self) -> list:
        """Nodes this pass added and matched in at most ``retract_observations`` frames, and
        nodes of earlier passes that may have moved to one it added (none with ``unresolved: false``)."""
        ctx, graph = self.context, self.context.graph
        if not self.params.unresolved:
            return []
        barely = graph.params.retract_observations
        added = [n for n in graph.unresolved(ctx.session) if n.first_session == ctx.session
                 and n.observations <= barely]
        events = ctx.perception.events if ctx.perception is not None else []
        moved = displaced_nodes(graph.nodes.values(), added_times(events), ctx.session, graph.params.relocation_radius)
        taken = {n.id for n in added}
        return added + [n for n in moved if n.id not in taken]
