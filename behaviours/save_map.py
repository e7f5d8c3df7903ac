"""Save Map: the occupancy map and the build summary, whatever way exploration ended."""

from __future__ import annotations

from py_trees.common import Status

from bomc_bt.build_record import save_build
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.registry import register


@register("SaveMap")
class SaveMap(Leaf):
    """Writes the live map in map_server format, the build record, and flushes the trajectory."""

    def update(self) -> Status:
        grid = save_build(self.context)
        self.feedback_message = f"saved {self.context.site.map_yaml} ({grid.free_area():.0f} m² free)"
        return Status.SUCCESS
