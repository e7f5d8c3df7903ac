"""The monitor pass's bookkeeping around :class:`~bomc_bt.monitoring.TraversalState`.

A pass is planned once and saved in the site store after every change, so a killed run
resumes where it stopped (``bomc monitor --resume``): :func:`open_pass` either restores
the saved plan and progress or plans anew, :func:`save_pass` writes them, and
:func:`extend_pass` appends a phase's viewpoints (gaps, refresh stops). Three decisions of
the waypoint loop live here too: :func:`pass_exhausted` (the loop's exit condition),
:func:`miss_stop` (a stop the robot cannot get to is missed with all its headings) and
:class:`DetourFinder` (another place near a blocked waypoint that still sees it).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from bomc_bt.geometry import Pose2D
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import MISSED, PENDING, TraversalState, detour_viewpoints
from bomc_bt.pass_resume import waypoint_progress
from bomc_bt.traversal import TraversalPlan


def progress_key(session: int) -> str:
    """Where a pass's waypoint bookkeeping is saved in the store (one key per session)."""
    return f"traverse/{session}"


def save_pass(store, session: int, state: TraversalState, perception=None) -> None:
    """Write the pass's progress and plan to the store (what a resume reads back); with the
    pass's ``perception``, its resume point and coverage in the same transaction
    (:mod:`bomc_bt.pass_resume`)."""
    keys = {progress_key(session): {**state.to_json(), "plan": state.plan.to_json()}}
    own = perception is not None and getattr(perception, "store", None) is store  # the pass's own store
    if own:
        keys.update(waypoint_progress(perception, perception.robot))
    store.record([], [], keys)
    if own:
        perception.resume_rows.written()


def open_pass(store, session: int, resume: bool, make_plan: Callable[[], TraversalPlan]) -> TraversalState:
    """The pass to run: the saved one when resuming (at its next waypoint), else a new plan, saved."""
    saved = store.get_progress(progress_key(session)) if resume else None
    if saved and "plan" in saved:
        state = TraversalState(TraversalPlan.from_json(saved["plan"], store.path))
        state.restore(saved)
        return state
    state = TraversalState(make_plan())
    save_pass(store, session, state)
    return state


def extend_pass(store, session: int, state: TraversalState, phase: str, views: list[Pose2D],
                perception=None) -> None:
    """Append ``phase``'s viewpoints to the pass and save it."""
    state.add_viewpoints(phase, views)
    save_pass(store, session, state, perception)


def pass_exhausted(state: TraversalState) -> bool:
    """True when :meth:`TraversalState.next` has nothing left to hand out (a pure look ahead)."""
    if PENDING in state.states[state.index:]:
        return False
    return not any(s == MISSED and i not in state.retried for i, s in enumerate(state.states))


STOP_RADIUS = 0.05  # [m] waypoints this near each other are one stop's headings (the plan gives them one place)


def give_up(state: TraversalState, indices: list[int], keep: int | None = None) -> tuple[list[int], list[int]]:
    """Give up on waypoints ``indices`` (but ``keep``): those still pending or missed are
    marked missed and get no second chance at the end of the loop. Returns (given up, of
    those the ones not tried yet). For waypoints behind obstacles seen again after a clear
    (Skip Waypoints Behind, ``trees/recover.yaml``): each would be tried twice and detoured three
    times, 15 s without progress each, for nothing (willow, pass 8: 53 such second chances,
    none reached)."""
    given = [i for i in indices if state.states[i] in (PENDING, MISSED) and i != keep]
    untried = [i for i in given if state.states[i] == PENDING]
    for i in given:
        state.mark(i, MISSED)
        if i not in state.retried:
            state.retried.append(i)
    return given, untried


def miss_stop(state: TraversalState, i: int) -> list[int]:
    """Mark waypoint ``i`` missed, with the rest of its stop; returns the others so marked.

    A coverage stop is one waypoint per heading, all at one place. When the robot could not
    get to that place (retried, detoured, missed), each further heading would be tried,
    detoured and missed in turn, for nothing: a room sealed off by a chair moved into its
    doorway cost one stop's four headings 75 s each (36 x 28 m office, seed 6615, pass 6).
    So the pending waypoints right after ``i`` at its place are missed with it, without
    driving. Like any missed waypoint they come back once at the end of the loop; when
    ``i``'s own second chance there fails too, they are not tried again either.
    """
    state.mark(i, MISSED)
    if state.states[i] != MISSED:
        return []
    second_chance = i in state.retried
    at, others = state.waypoint(i), []
    for k in range(i + 1, len(state.states)):
        w = state.waypoint(k)
        if math.hypot(w.x - at.x, w.y - at.y) > STOP_RADIUS:
            break
        if second_chance:
            if state.states[k] != MISSED or k in state.retried:
                break
            state.retried.append(k)
        else:
            if state.states[k] != PENDING:
                break
            state.states[k] = MISSED
        others.append(k)
    if others and not second_chance:
        state.index = max(state.index, others[-1] + 1)
    return others


def reached_by_detour(driven: float, expected: float, ratio: float, margin: float) -> bool:
    """A goal reached after driving more than ``ratio`` times the map's shortest path plus
    ``margin`` metres went around something the map does not have."""
    return driven > ratio * expected + margin


@dataclass
class DetourParams:
    """Where the ``FindDetour`` leaf looks for a detour around a blocked waypoint."""

    radius: float = 2.0  # [m] around the blocked waypoint
    count: int = 6  # [count] candidates considered per waypoint
    clearance: float = 0.45  # [m] from obstacles


@dataclass
class DetourFinder:
    """Proposes, one at a time, untried viewpoints near a waypoint that still see it."""

    params: DetourParams
    tried: dict[int, list[tuple[float, float]]] = field(default_factory=dict)  # waypoint -> places tried

    def next(self, grid: OccupancyGrid, index: int, target: Pose2D) -> Pose2D | None:
        """The nearest untried detour for waypoint ``index`` at ``target``, facing it; None if none is left."""
        tried = self.tried.setdefault(index, [])
        p = self.params
        options = detour_viewpoints(grid, (target.x, target.y), p.radius, p.count, p.clearance,
                                    avoid=[(target.x, target.y), *tried])
        if not options:
            return None
        x, y = options[0]
        tried.append((x, y))
        return Pose2D(x, y, math.atan2(target.y - y, target.x - x))  # look at the waypoint
