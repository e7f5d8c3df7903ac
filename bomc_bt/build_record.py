"""What a build leaves besides the trajectory: the saved map and ``build.json``.

Saving is a library function, not only a leaf, because it must also run outside any tick:
on Ctrl-C, and after a custom tree that never saved (a build never loses its map).
"""

from __future__ import annotations

from typing import Any

from bomc_bt.grid import OccupancyGrid, save_map
from bomc_bt.site import write_json


def save_build(ctx) -> OccupancyGrid:
    """Save the live map and the build summary of the mission context ``ctx``.

    Both writes are atomic (temporary file + rename), so the previous map survives a
    crash in the middle of a save. The robot's last pose is forced into the trajectory.
    """
    grid = ctx.robot.live_map()
    save_map(grid, ctx.site.map_yaml)
    pose = ctx.robot.pose()
    if ctx.trajectory is not None and pose is not None:
        ctx.trajectory.record(ctx.now(), pose.x, pose.y, pose.yaw, force=True)
    ctx.progress.explored_area = grid.free_area()
    write_json(ctx.site.build_json, build_summary(ctx))
    return grid


def build_summary(ctx) -> dict[str, Any]:
    """The build record (``build.json``): area, path, robot time and how exploration ended."""
    explorer = ctx.explorer
    pose = ctx.robot.pose()
    return {
        "explorer": ctx.config.exploration.explorer,
        "explored_area_m2": round(ctx.progress.explored_area, 2),
        "path_length_m": round(ctx.progress.path_length, 2),
        "sim_time_s": round(ctx.now(), 2),
        "termination": explorer.status if explorer else "not started",
        "reason": explorer.reason if explorer else "",
        "goals": explorer.goals if explorer else 0,
        "failed_goals": explorer.failures if explorer else 0,
        "backouts": explorer.backouts if explorer else 0,
        "time_limit_s": explorer.max_time if explorer else None,
        # robot time at which 99 % of the final explored area was mapped: how long the tail took
        "area_99_s": _round(explorer.area.time_to(0.99)) if explorer else None,
        # the unknown border left: frontiers (count, metres) the planner can and cannot reach
        "frontiers_left": explorer.border(ctx.robot.live_map(), (pose.x, pose.y) if pose else None)
        if explorer else {},
        "trajectory_points": ctx.trajectory.rows if ctx.trajectory else 0,
        "seed": ctx.seed,
    }


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 2)
