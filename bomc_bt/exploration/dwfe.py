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

from bomc_bt.exploration.blacklist import Blacklist
from bomc_bt.exploration.frontiers import Frontier

__all__ = ["Blacklist", "Choice", "ExplorationParams", "choose_frontier"]


@dataclass
class ExplorationParams:
    """Tunables of the exploration step (filled from ``config/*.yaml`` via ``params.from_mapping``)."""

    explorer: Literal["dwfe", "baseline"] = "dwfe"
    # r_l: a few metres is one room or one corridor segment for a Fetch-class base: about
    # what its laser clears well from one stop (indoor returns are dense up to ~5 m), and
    # small enough that the window does not reach into the next room through a wall.
    local_radius: float = 4.0
    # r_g: effectively the whole building; the global window is the fallback.
    global_radius: float = 1000.0
    # T_l: stay local while at least two frontiers remain nearby; a single leftover local
    # frontier is often a sliver (behind a chair, a laser shadow) not worth finishing first.
    local_threshold: int = 2
    # T_g: stop when no frontier is left anywhere (the paper's termination count).
    global_threshold: int = 1
    # alpha, beta: 1 m of extra travel is worth 2 m of extra frontier length, so a 1 m
    # doorway 1 m further away still beats a 0.5 m sliver close by, but the robot does not
    # cross the window for a long frontier when a decent one is next to it.
    alpha: float = 1.0
    beta: float = 0.5
    potential_scale: float = 3.0  # explore_lite defaults
    gain_scale: float = 1.0
    min_frontier_size: float = 0.5  # [m] explore_lite's min_frontier_size (boundary length)
    max_time: float = 0.0  # [s] robot-time limit of a build; 0 = none, explore until no reachable frontier is left
    blacklist_radius: float = 0.5  # [m] frontiers this close to a failed goal are skipped
    progress_timeout: float = 30.0  # [s] of robot time without progress -> goal blacklisted
    # A build that maps less than min_progress_area in no_progress_time ends ("no_progress"):
    # the guard against a runaway, instead of a fixed time limit.
    no_progress_time: float = 600.0  # [s] of robot time without new mapped area -> exploration ends
    min_progress_area: float = 2.0  # [m2] new known-free area that counts as progress
    # A failed goal is tried again when the known area within blacklist_readmit_radius of it
    # changed by more than blacklist_readmit_area, or when the robot comes within
    # blacklist_near_radius of it; at most blacklist_max_retries times per place.
    blacklist_readmit_radius: float = 1.0  # [m] neighbourhood of a failed goal watched for map changes
    blacklist_readmit_area: float = 0.25  # [m2] change of known area there that re-admits it
    blacklist_near_radius: float = 1.5  # [m] robot this close to a failed goal re-admits it
    blacklist_max_retries: int = 2  # [count] re-admissions per place
    # A robot that fails goals without moving backs out along its trajectory and replans
    # before it is declared stuck.
    backout_distance: float = 1.5  # [m] along the trajectory driven, back to where it came from
    max_backouts: int = 2  # [count] back-outs without progress before "stuck" may be declared
    # Frontiers count only where the planner can take the robot (its clearance, unknown
    # treated as a wall); the others are reported as unreachable border, never chosen.
    planner_reachable: bool = True  # [bool] filter frontiers by the planner's reachable area

    def __post_init__(self) -> None:
        if self.explorer not in ("dwfe", "baseline"):
            raise ValueError(f"explorer: must be 'dwfe' or 'baseline', got {self.explorer!r}")
        _positive(self, "local_radius", "global_radius", "progress_timeout", "no_progress_time",
                  "blacklist_readmit_radius", "blacklist_near_radius")
        _non_negative(self, "alpha", "beta", "potential_scale", "gain_scale", "min_frontier_size",
                      "blacklist_radius", "max_time", "min_progress_area", "blacklist_readmit_area",
                      "backout_distance")
        if self.global_radius < self.local_radius:
            raise ValueError("global_radius: must be at least local_radius "
                             f"({self.global_radius} < {self.local_radius})")
        for name, low in (("local_threshold", 1), ("global_threshold", 1), ("blacklist_max_retries", 0),
                          ("max_backouts", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < low:
                raise ValueError(f"{name}: must be a whole number >= {low}, got {value!r}")

    @property
    def time_limit(self) -> float | None:
        """``max_time`` in seconds, or None when there is no limit (0)."""
        return self.max_time if self.max_time > 0 else None

    def blacklist(self) -> Blacklist:
        """An empty blacklist with these re-admission rules."""
        return Blacklist(self.blacklist_radius, self.blacklist_readmit_radius, self.blacklist_readmit_area,
                         self.blacklist_near_radius, int(self.blacklist_max_retries))

    def min_size_cells(self, resolution: float) -> int:
        """``min_frontier_size`` as a cell count for :func:`find_frontiers` (explore_lite keeps
        frontiers with ``size * resolution >= min_frontier_size``)."""
        return max(1, math.ceil(self.min_frontier_size / resolution - 1e-9))


def _positive(params: ExplorationParams, *names: str) -> None:
    for name in names:
        value = getattr(params, name)
        if not (value > 0) or math.isnan(value) or (math.isinf(value) and name != "global_radius"):
            raise ValueError(f"{name}: must be a positive number, got {value!r}")


def _non_negative(params: ExplorationParams, *names: str) -> None:
    for name in names:
        value = getattr(params, name)
        if not (value >= 0) or not math.isfinite(value):
            raise ValueError(f"{name}: must be a finite number >= 0, got {value!r}")


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
