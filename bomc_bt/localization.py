"""Relocalizing a robot in a saved map from one laser scan (the simulator's AMCL).

A monitor mission starts with the robot somewhere in a map built days earlier. On ROS,
AMCL answers "where am I"; in the simulator this module does, by correlative scan
matching against a likelihood field (Olson 2009, scored by :mod:`bomc_bt.scan_likelihood`):
every beam endpoint scores ``exp(-d^2 / 2 sigma^2)`` where ``d`` is its distance to the
nearest occupied cell, and a pose scores the mean over its beams. This module is the
search: which poses to score, and when the best one is trustworthy.

The search is coarse to fine so that it fits inside a tick loop: a coarse grid over the
search window (cell-aligned positions, so every beam is an integer cell offset and a
whole yaw is one gather), then finer grids around the best few candidates with bilinear
interpolation, each following its peak if it lies on the grid's edge. The field peaks on
wall *faces* (inside a wall the distance to the free side counts), and refinement also
zeroes a beam whose last 0.1-0.3 m cross an occupied cell, so a pose cannot slide through
a thin wall to score on its far face; the surviving poses get a full ray test ("does any
beam pass through a mapped wall?"). "Confident" needs two things, as a human reading
AMCL's particle cloud would: a high score, and no clearly different pose (far away, or
facing elsewhere) that explains the scan almost as well. The second check is what
rejects long featureless corridors and repeated identical rooms.

The map is days old and the floor has changed since: chairs brought in stop beams short
in what the map says is open floor, chairs taken away let beams through what it says is
occupied. The score a verdict reads therefore leaves out beams that end in mapped free
floor far from every mapped surface (``change_gap``: AMCL's "short" readings), and a beam
through a furniture-sized blob is scored where it ends; only a beam through a wall fails.
At least ``min_explained`` of the beams must be left to score.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import OccupancyGrid
from bomc_bt.relocalization_params import RelocalizationParams
from bomc_bt.robot import LaserScan
from bomc_bt.scan_likelihood import Beams, LikelihoodField, to_world, valid_beams

# [count] best coarse entries the distinct peaks are drawn from: all of a local window's
# (about 16,000); with only the best 500, every one lay on one wrong peak a metre from the
# dock on a floor changed round it, and the true pose's region was never refined
POOL = 20_000


@dataclass
class RelocalizationResult:
    """The best pose, its score (mean beam likelihood in [0, 1]) and whether to trust it."""

    pose: Pose2D
    score: float
    confident: bool
    message: str
    runner_up: Pose2D | None = None  # best clearly different pose, for diagnostics
    runner_up_score: float = 0.0


@dataclass
class _Level:
    """One refinement grid: +-half around the current pose in steps (metres, radians)."""

    lin_half: float
    lin_step: float
    ang_half: float
    ang_step: float
    sigma: float
    beams: int  # how many beams to score with


@dataclass
class ScanMatcher:
    """Correlative scan matching of a :class:`LaserScan` against one saved map."""

    grid: OccupancyGrid
    params: RelocalizationParams = field(default_factory=RelocalizationParams)

    def __post_init__(self) -> None:
        self.likelihood = LikelihoodField(self.grid)
        self._candidate_cells: tuple[np.ndarray, np.ndarray] | None = None

    # -- public ----------------------------------------------------------------------
    def match(self, scan: LaserScan, hint: Pose2D | None,
              global_search: bool = False) -> RelocalizationResult:
        """Estimate the robot's pose in the map from ``scan``.

        With a ``hint`` (and not ``global_search``) only poses within ``search_radius`` and
        ``search_angle`` of it are considered; otherwise every free place of the map is.
        """
        p = self.params
        beams = valid_beams(scan)
        fallback = hint if hint is not None else Pose2D(*self.grid.cell_to_world(0, 0), 0.0)
        if beams.count < p.min_beams:
            return RelocalizationResult(fallback, 0.0, False,
                                        f"only {beams.count} valid beams (need {p.min_beams})")
        window = None  # a local search answers within its window round the hint
        if hint is None or global_search:
            rows, cols = self._global_cells()
            yaws = np.arange(-math.pi, math.pi, p.global_angular_step)
            usable = beams.for_grid(p.global_sigma, p.global_angular_step, p.min_beams)
            coarse = (p.global_sigma, usable.subsample(p.global_beams))
            levels = [_Level(p.global_linear_step, p.linear_step, p.global_angular_step, p.angular_step,
                             p.coarse_sigma, p.max_beams)]
            n_keep = p.global_candidates
        else:
            rows, cols = self._local_cells(hint)
            yaws = hint.yaw + np.arange(-p.search_angle, p.search_angle + 1e-9, p.angular_step)
            coarse = (p.coarse_sigma,
                      beams.for_grid(p.coarse_sigma, p.angular_step, p.min_beams).subsample(p.max_beams))
            levels = []
            n_keep = p.local_candidates
            window = hint
        if rows.size == 0:
            return RelocalizationResult(fallback, 0.0, False,
                                        "no candidate position inside the map's free space")
        # Halving steps: coarse -> half the coarse step -> fine -> final, each searching
        # +-1 previous step (more when the peak is off the edge, see _refine).
        mid_lin, mid_ang = 0.5 * p.linear_step, 0.5 * p.angular_step
        levels += [
            _Level(p.linear_step, mid_lin, p.angular_step, mid_ang, p.sigma, p.max_beams),
            _Level(mid_lin, p.fine_linear_step, mid_ang, p.fine_angular_step, p.sigma, p.max_beams),
            _Level(p.fine_linear_step, p.final_linear_step, p.fine_angular_step, p.final_angular_step,
                   p.sigma, p.final_beams),
        ]
        return self._search(rows, cols, yaws, coarse, beams, levels, n_keep, window)

    def score(self, scan: LaserScan, pose: Pose2D) -> float:
        """The score :meth:`match` reports for ``scan`` taken at ``pose`` (0 without valid beams).

        Mean beam likelihood over the beams the map can judge, a beam through a wall
        counting as 0 (:meth:`judged`).
        """
        return self.judged(pose, valid_beams(scan).subsample(self.params.final_beams))[0]

    def judged(self, pose: Pose2D, beams: Beams) -> tuple[float, float]:
        """(score, share of the beams scored) of ``pose`` in a floor that may have changed.

        Left out: beams ending in mapped free floor farther than ``change_gap`` from every
        mapped surface (something new stands there). A beam through a wall scores 0; one
        through a furniture-sized blob only (``furniture_area``) is scored where it ends.
        """
        if beams.count == 0:
            return 0.0, 0.0
        p = self.params
        wx, wy = to_world(pose, beams.xy)
        lik = self.likelihood.lookup(wx, wy, p.sigma)
        length = np.hypot(beams.xy[:, 0], beams.xy[:, 1]) - p.see_through_tolerance
        through = self.likelihood.crosses_wall(pose, wx, wy, length, self.likelihood.walls(p.furniture_area))
        rows, cols = self.grid.world_to_cell(wx, wy)
        inside = self.grid.in_bounds(rows, cols)
        new_thing = np.zeros(beams.count, dtype=bool)
        r, c = rows[inside], cols[inside]
        new_thing[inside] = (self.grid.data[r, c] == 0) & (self.likelihood.surface_distance[r, c] > p.change_gap)
        scored = ~new_thing | through
        if not scored.any():
            return 0.0, 0.0
        return float(np.mean(np.where(through, 0.0, lik)[scored])), float(np.mean(scored))

    # -- search ----------------------------------------------------------------------
    def _search(self, rows, cols, yaws, coarse, beams, levels, n_keep,
                window: Pose2D | None = None) -> RelocalizationResult:
        """The best refined candidate (by :meth:`_checked`), judged against the best clearly
        different one (by :meth:`_judged`, as the verdict judges it). ``window``: the hint
        of a local search; a candidate refined out of its window is dropped."""
        p = self.params
        sigma_c, beams_c = coarse
        scores = self.likelihood.coarse_scores(rows, cols, yaws, beams_c, sigma_c)  # (Y, N)
        xs, ys = self.grid.cell_to_world(rows, cols)
        nms = (0.5 * p.ambiguity_distance, 0.5 * p.ambiguity_angle)
        cand = _top_distinct(scores, xs, ys, yaws, n_keep, *nms)
        # Candidates and rivals go through the first refinement level only, and are
        # compared there (same beams, same grid); only the winner is refined further.
        first, rest = levels[:-2], levels[-2:]
        mid = beams.subsample(p.max_beams)
        refined = [self._checked(self._refine(pose, beams, first)[0], mid) for pose in cand]
        if window is not None:
            refined = [r for r in refined if self._in_window(r[0], window)]
            if not refined:
                return RelocalizationResult(window, 0.0, False, "the best matches lie outside the search window")
        best_pose, _ = max(refined, key=lambda r: r[1])
        best_score = self._judged(best_pose, mid)[1]
        # The runner-up: the best coarse peaks clearly different from the winner.
        far = _far_mask(xs, ys, yaws, best_pose, p.ambiguity_distance, p.ambiguity_angle)
        masked = np.where(far, scores, -np.inf)
        rivals = _top_distinct(masked, xs, ys, yaws, p.rivals, *nms)
        rivals = [self._refine(pose, beams, first)[0] for pose in rivals] + [pose for pose, _ in refined]
        runner = max((self._judged(pose, mid) for pose in rivals if _is_far(pose, best_pose, p)),
                     key=lambda r: r[1], default=None)
        final_pose, _ = self._refine(best_pose, beams, rest)
        final_score, scored = self.judged(final_pose, beams.subsample(p.final_beams))
        return _verdict(final_pose, final_score, scored, best_score, runner, beams.count, p)

    def _in_window(self, pose: Pose2D, hint: Pose2D) -> bool:
        """Within a local search's window (one coarse step of slack): a refinement that
        climbed out of it found a place the hint does not vouch for."""
        p = self.params
        return (pose.distance_to(hint) <= p.search_radius + p.linear_step
                and abs(wrap_angle(pose.yaw - hint.yaw)) <= p.search_angle + p.angular_step)

    def _judged(self, pose: Pose2D, beams: Beams) -> tuple[Pose2D, float]:
        """``pose`` and the score the verdict gives it (:meth:`judged`), 0 when fewer than
        ``min_explained`` of the beams can be judged. Whether a rival is as good as the
        winner is asked this way: on a floor changed since the build (a table and a chair
        brought in beside the dock, five passes of churn) 42 % of the true pose's beams end
        on things the map lacks and more pass through furniture that has gone; counted as
        misses, a rival a metre off looked as good, and a global search then settled 10 m
        off."""
        score, share = self.judged(pose, beams)
        return pose, score if share >= self.params.min_explained else 0.0

    def _checked(self, pose: Pose2D, beams: Beams) -> tuple[Pose2D, float]:
        """``pose`` and its score, where a beam that passes through a mapped wall scores 0.

        The likelihood field only asks "does each endpoint lie on a wall"; a wrong pose
        can satisfy that while its beams cross walls. Checking the crossings for the few
        poses that survive the search is what keeps many wrong places from looking
        confident. (No-returns are not checked: real lidars drop beams on glass and black
        surfaces, and a missing return must not veto a correct pose.)
        """
        if beams.count == 0:
            return pose, 0.0
        wx, wy = to_world(pose, beams.xy)
        lik = self.likelihood.lookup(wx, wy, self.params.sigma)
        length = np.hypot(beams.xy[:, 0], beams.xy[:, 1]) - self.params.see_through_tolerance
        through = self.likelihood.crosses_wall(pose, wx, wy, length)
        return pose, float(np.mean(np.where(through, 0.0, lik)))


    def _refine(self, pose: Pose2D, beams: Beams, levels: list[_Level]) -> tuple[Pose2D, float]:
        """Grid search around ``pose`` at each level in turn (bilinear field lookups)."""
        score = -1.0
        for lv in levels:
            n_lin = max(1, int(round(lv.lin_half / lv.lin_step)))
            n_ang = max(1, int(round(lv.ang_half / lv.ang_step)))
            used = beams.for_grid(lv.sigma, lv.ang_step, self.params.min_beams).subsample(lv.beams)
            # Hill-climb: while the best lies on the window's edge the peak is further out
            # (flat corridors make coarse peaks drift), so recentre and search again.
            for _ in range(self.params.max_recentre + 1):
                offs = np.arange(-n_lin, n_lin + 1)
                di, dj = np.meshgrid(offs, offs, indexing="ij")
                xy = np.stack([pose.x + lv.lin_step * di.ravel(), pose.y + lv.lin_step * dj.ravel()], axis=1)
                yaws = pose.yaw + np.arange(-n_ang, n_ang + 1) * lv.ang_step
                s = self.likelihood.bilinear_scores(yaws, xy, used, lv.sigma, self.params.wall_probe)
                iy, ix = np.unravel_index(int(np.argmax(s)), s.shape)
                pose = Pose2D(float(xy[ix, 0]), float(xy[ix, 1]), wrap_angle(float(yaws[iy])))
                score = float(s[iy, ix])
                on_edge = max(abs(di.ravel()[ix]), abs(dj.ravel()[ix])) == n_lin or abs(iy - n_ang) == n_ang
                if not on_edge:
                    break
        return pose, score

    # -- candidate positions -----------------------------------------------------------
    def _local_cells(self, hint: Pose2D) -> tuple[np.ndarray, np.ndarray]:
        """Cell-aligned positions on the coarse step inside the search disc and the map."""
        p = self.params
        k = max(1, int(round(p.linear_step / self.likelihood.resolution)))
        n = int(math.ceil(p.search_radius / (k * self.likelihood.resolution)))
        r0, c0 = self.grid.world_to_cell(hint.x, hint.y)
        dr, dc = np.meshgrid(np.arange(-n, n + 1) * k, np.arange(-n, n + 1) * k, indexing="ij")
        rows, cols = (int(r0) + dr).ravel(), (int(c0) + dc).ravel()
        xs, ys = self.grid.cell_to_world(rows, cols)
        keep = self.grid.in_bounds(rows, cols) & (np.hypot(xs - hint.x, ys - hint.y) <= p.search_radius)
        rows, cols = rows[keep], cols[keep]
        # Prefer known-free places, but do not insist: a hint next to a wall must still work.
        free = self.grid.data[rows, cols] == 0
        return (rows[free], cols[free]) if free.any() else (rows, cols)

    def _global_cells(self) -> tuple[np.ndarray, np.ndarray]:
        """Free cells with clearance on a coarse lattice: where the robot can stand."""
        if self._candidate_cells is None:
            p = self.params
            k = max(1, int(round(p.global_linear_step / self.likelihood.resolution)))
            ok = (self.grid.data == 0) & (self.likelihood.surface_distance >= p.global_clearance)
            lattice = np.zeros_like(ok)
            lattice[k // 2::k, k // 2::k] = True
            self._candidate_cells = np.nonzero(ok & lattice)
        return self._candidate_cells

    # -- scoring -----------------------------------------------------------------------

# -- helpers -------------------------------------------------------------------------------

def _top_distinct(scores, xs, ys, yaws, n, min_dist, min_angle) -> list[Pose2D]:
    """Up to ``n`` best (yaw, position) entries that are pairwise distinct (greedy NMS)."""
    flat = scores.ravel()
    m = min(flat.size, max(50 * n, POOL))
    top = np.argpartition(-flat, m - 1)[:m] if m < flat.size else np.arange(flat.size)
    top = top[np.argsort(-flat[top], kind="stable")]
    kept: list[Pose2D] = []
    for t in top:
        if not np.isfinite(flat[t]):
            break
        iy, ix = divmod(int(t), scores.shape[1])
        pose = Pose2D(float(xs[ix]), float(ys[ix]), wrap_angle(float(yaws[iy])))
        if all(pose.distance_to(k) > min_dist or abs(wrap_angle(pose.yaw - k.yaw)) > min_angle for k in kept):
            kept.append(pose)
            if len(kept) == n:
                break
    return kept


def _far_mask(xs, ys, yaws, pose: Pose2D, distance: float, angle: float) -> np.ndarray:
    """(Y, N) mask of coarse candidates clearly different from ``pose``."""
    far_pos = np.hypot(xs - pose.x, ys - pose.y) > distance
    dyaw = np.abs((yaws - pose.yaw + math.pi) % (2 * math.pi) - math.pi)
    return far_pos[None, :] | (dyaw > angle)[:, None]


def _is_far(a: Pose2D, b: Pose2D, p: RelocalizationParams) -> bool:
    return a.distance_to(b) > p.ambiguity_distance or abs(wrap_angle(a.yaw - b.yaw)) > p.ambiguity_angle


def _verdict(best: Pose2D, score: float, scored: float, comparable: float, runner, n_beams: int,
             p: RelocalizationParams) -> RelocalizationResult:
    """Confident = a good score over enough beams and no clearly different pose that scores almost as well.

    ``scored``: the share of the beams the map could judge (:meth:`ScanMatcher.judged`);
    ``comparable`` is the winner's score at the rivals' refinement level (same beams).
    """
    r_pose, r_score = runner if runner is not None else (None, 0.0)
    where = f"score {score:.2f} over {n_beams} beams"
    if scored < 1.0:
        where += f" ({1.0 - scored:.0%} ending on things the map lacks)"
    if r_pose is not None:
        where += f", runner-up {r_score:.2f} at {r_pose.distance_to(best):.1f} m"
    if scored < p.min_explained:
        return RelocalizationResult(best, score, False, f"too much has changed: {where} (min_explained "
                                    f"{p.min_explained})", r_pose, r_score)
    if score < p.min_score:
        return RelocalizationResult(best, score, False, f"poor match: {where} (min_score {p.min_score})",
                                    r_pose, r_score)
    if r_score > (1.0 - p.min_margin) * comparable:
        return RelocalizationResult(best, score, False, f"ambiguous: {where}", r_pose, r_score)
    return RelocalizationResult(best, score, True, f"localized: {where}", r_pose, r_score)
