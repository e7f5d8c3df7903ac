"""Choosing the next frontier: Dynamic Window Frontier Exploration and the explore_lite baseline.

DWFE (the paper's Algorithm 1) looks at the frontiers within a local radius ``r_l`` of the
robot first (a frontier is "within" a radius when its cell nearest the robot is). While
there are at least ``T_l`` of them the robot finishes its neighbourhood before leaving
it, which is what avoids the back-and-forth of a global greedy choice. When fewer remain,
the window widens to the global radius ``r_g``; if even that holds fewer than ``T_g``
frontiers, exploration is over. (The algorithm only checks ``T_g`` after the local
window fails, so a full local window never terminates; we do the same.)

Inside the window the choice is ``argmin alpha * distance - beta * length``.

Sign convention: the paper prints ``argmin(alpha * distance + beta * size)``, which with
a positive ``beta`` would *prefer small frontiers* -- slivers behind furniture over open
doorways -- and contradicts the authors' implementation (explore_lite's
``potential_scale * distance - gain_scale * size``, sorted ascending). We follow the code:
``beta >= 0`` *rewards* frontier length, so at equal distance the bigger frontier wins.
Size is measured as length in metres (cells times resolution), so ``alpha`` and ``beta``
do not change meaning with the map resolution.

The baseline is explore_lite (Hörner 2016) as the paper compares against it: every
reachable frontier, cost ``potential_scale * distance * resolution - gain_scale * size *
resolution``, stopping when none is left. explore_lite's ``min_distance`` is already in
metres and its ``frontierCost`` still multiplies it by the resolution; we mirror that
exactly, because it is what makes the baseline favour large far frontiers at 5 cm maps.

Goals that failed (navigation aborted, or no progress for ``progress_timeout`` seconds of
robot time) go on a :class:`~bomc_bt.exploration.blacklist.Blacklist`; frontiers near an
active entry are skipped by both explorers (entries are re-admitted when the map around
them changes). Keeping that bookkeeping and the time limit here keeps Algorithm 1 in one
place; the behaviour that drives the robot only supplies frontiers, pose and elapsed time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from bomc_bt.algorithm_params import ExplorationParams
from bomc_bt.exploration.blacklist import Blacklist
from bomc_bt.exploration.frontiers import Frontier

__all__ = ["Blacklist", "Choice", "ExplorationParams", "choose_frontier"]


@dataclass
class Choice:
    """The outcome of one planning step: a frontier to visit, or why exploration is over."""

    frontier: Frontier | None
    window: Literal["local", "global", "none"]
    cost: float  # inf when frontier is None
    reason: str


def distance_to(frontier: Frontier, robot_xy: tuple[float, float]) -> float:
    """Robot -> frontier's nearest cell, in metres (equals ``frontier.distance`` when the
    frontier was found from ``robot_xy``; recomputed so a slightly moved robot is handled)."""
    dx = frontier.nearest[0] - float(robot_xy[0])
    dy = frontier.nearest[1] - float(robot_xy[1])
    return math.sqrt(dx * dx + dy * dy)


def dwfe_cost(frontier: Frontier, distance: float, params: ExplorationParams) -> float:
    """``alpha * distance - beta * length``: near and long frontiers are cheap."""
    return params.alpha * distance - params.beta * frontier.length


def baseline_cost(frontier: Frontier, distance: float, params: ExplorationParams) -> float:
    """explore_lite's ``frontierCost``, including its extra ``resolution`` on the distance term."""
    return (params.potential_scale * distance * frontier.resolution
            - params.gain_scale * frontier.length)


def choose_frontier(frontiers: list[Frontier], robot_xy: tuple[float, float], params: ExplorationParams,
                    blacklist: Blacklist | None = None, *, elapsed: float = 0.0) -> Choice:
    """One step of Algorithm 1 (or of the baseline): the frontier to explore next.

    ``frontiers`` should come from ``find_frontiers`` at ``robot_xy`` with
    ``params.min_size_cells(resolution)``. ``elapsed`` is robot time since exploration
    started; at ``max_time`` (when set) or later the result is a termination.
    """
    if params.time_limit is not None and elapsed >= params.max_time:
        return Choice(None, "none", math.inf,
                      f"time limit reached ({elapsed:.0f} s >= {params.max_time:.0f} s)")
    candidates = blacklist.filter(frontiers) if blacklist is not None else list(frontiers)
    if not candidates:
        reason = (f"all {len(frontiers)} remaining frontier(s) are blacklisted" if frontiers
                  else "no frontiers left")
        return Choice(None, "none", math.inf, reason)
    scored = [(f, distance_to(f, robot_xy)) for f in candidates]
    if params.explorer == "baseline":
        return _best(scored, baseline_cost, params, "global",
                     f"baseline: best of {len(scored)} frontier(s)")
    local = [(f, d) for f, d in scored if d <= params.local_radius]
    if len(local) >= params.local_threshold:
        return _best(local, dwfe_cost, params, "local",
                     f"{len(local)} frontier(s) within r_l={params.local_radius:g} m "
                     f"(T_l={params.local_threshold})")
    wide = [(f, d) for f, d in scored if d <= params.global_radius]
    if len(wide) < params.global_threshold:
        return Choice(None, "none", math.inf,
                      f"only {len(wide)} frontier(s) within r_g={params.global_radius:g} m, "
                      f"below T_g={params.global_threshold}")
    return _best(wide, dwfe_cost, params, "global",
                 f"only {len(local)} frontier(s) within r_l={params.local_radius:g} m "
                 f"(< T_l={params.local_threshold}); widened to {len(wide)} within "
                 f"r_g={params.global_radius:g} m")


def _best(scored: list[tuple[Frontier, float]], cost_fn, params: ExplorationParams,
          window: Literal["local", "global"], reason: str) -> Choice:
    """Lowest cost; ties go to the nearer frontier, then the lower centroid (deterministic)."""
    costs = [(cost_fn(f, d, params), d, f.centroid, i) for i, (f, d) in enumerate(scored)]
    cost, _, _, i = min(costs)
    return Choice(scored[i][0], window, cost, reason)
