"""Save Map: the occupancy map and the build summary, whatever way exploration ended."""

from __future__ import annotations

from py_trees.common import Status

from bomc_bt.grid import save_map
from bomc_bt.site import write_json
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@register("SaveMap")
class SaveMap(Leaf):
    """Writes the live map in map_server format and flushes the trajectory.

    Both writes are atomic (temporary file + rename), so the previous map survives a
    crash in the middle of a save.
    """

    def update(self) -> Status:
        grid = self.save(self.context)
        self.feedback_message = f"saved {self.context.site.map_yaml} ({grid.free_area():.0f} m² free)"
        return Status.SUCCESS

    @staticmethod
    def save(ctx):
        """Save the map and the summary (also called on Ctrl-C, outside any tick)."""
        grid = ctx.robot.live_map()
        save_map(grid, ctx.site.map_yaml)
        pose = ctx.robot.pose()
        if ctx.trajectory is not None and pose is not None:
            ctx.trajectory.record(ctx.now(), pose.x, pose.y, pose.yaw, force=True)
        ctx.progress.explored_area = grid.free_area()
        write_json(ctx.site.build_json, build_summary(ctx))
        return grid


def build_summary(ctx) -> dict:
    explorer = ctx.explorer
    return {
        "explorer": ctx.config.exploration.explorer,
        "explored_area_m2": round(ctx.progress.explored_area, 2),
        "path_length_m": round(ctx.progress.path_length, 2),
        "sim_time_s": round(ctx.now(), 2),
        "termination": explorer.status if explorer else "not started",
        "reason": explorer.reason if explorer else "",
        "goals": explorer.goals if explorer else 0,
        "failed_goals": explorer.failures if explorer else 0,
        "trajectory_points": ctx.trajectory.rows if ctx.trajectory else 0,
        "seed": ctx.seed,
    }
