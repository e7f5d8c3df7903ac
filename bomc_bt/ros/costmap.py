"""move_base's global costmap as the robot port's obstacle layer (``RobotPort.obstacle_layer``).

A pass that keeps failing waypoints clears the obstacle layer, and from its next recovery
round reads what the layer marks again (:mod:`bomc_bt.stuck`). On ROS that is the lethal
cells of the global costmap. move_base sends the full costmap once to each new subscriber
and then, unless the costmap's ``always_send_full_costmap`` is set, only incremental
updates on ``<topic>_updates``, which are not read here; so a costmap stamped before the
last clear is never used: it would show the obstacles the clear was meant to drop as
"marked again". Without newer full costmaps the diagnosis uses the scan alone.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from bomc_bt.ros.convert import decimal_resolution, grid_from_msg, lethal_cells


class GlobalCostmap:
    """The newest full costmap message (a subscriber callback keeps it) and its lethal cells."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._msg: Any = None
        self._cells: np.ndarray | None = None  # lethal cells of ``_msg``, computed on first use
        self._cleared_at = -math.inf  # [s] ROS time of the last clear_costmaps

    def on_message(self, msg: Any) -> None:
        """Subscriber callback (a rospy thread)."""
        with self._lock:
            self._msg, self._cells = msg, None

    def cleared(self, now: float) -> None:
        """The obstacle layer was cleared at ROS time ``now``: older costmaps no longer count."""
        with self._lock:
            self._cleared_at = now

    def cells(self) -> np.ndarray:
        """(N, 2) map-frame centres of the lethal cells of the newest costmap stamped after
        the last clear; empty when there is none."""
        with self._lock:
            msg, cells, cleared_at = self._msg, self._cells, self._cleared_at
        if msg is None or msg.header.stamp.to_sec() <= cleared_at:
            return np.zeros((0, 2))
        if cells is None:
            cells = lethal_cells(decimal_resolution(grid_from_msg(msg)))
            with self._lock:
                if self._msg is msg:
                    self._cells = cells
        return cells
