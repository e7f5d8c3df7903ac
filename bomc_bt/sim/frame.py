"""The simulated camera's frame: an RGB-D frame plus the simulator's ground truth.

The simulated detector does not look at pixels' colours: it reads which object each pixel
shows. That ground truth exists only in the simulator, so it lives here, on a subclass
of the core :class:`~bomc_bt.robot.RGBDFrame`, and a real camera's frame has none of it.
The rest of the pipeline (projection, association) sees an ordinary RGBDFrame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bomc_bt.robot import RGBDFrame


@dataclass(kw_only=True)
class SimFrame(RGBDFrame):
    """A rendered frame with its per-pixel instance ids and their categories."""

    instances: np.ndarray  # int32 (H, W): instance id per pixel, 0 = none
    instance_categories: dict[int, str] = field(default_factory=dict)  # labelled instances only
    # Pixels each instance would cover if nothing occluded it (its occluded fraction drives
    # the simulated detector's miss rate).
    instance_unoccluded: dict[int, int] = field(default_factory=dict)
    # A stable number per world (crc32 of its name; 0: unknown, as in frames that came over ROS): the
    # ``hard`` detector's look-alikes and dark zones are fixed per world, whatever the pass's seed.
    world_key: int = 0

    @classmethod
    def of(cls, frame: RGBDFrame, instances: np.ndarray, categories: dict[int, str],
           unoccluded: dict[int, int]) -> SimFrame:
        """``frame`` with ground truth that came separately (the sim-over-ROS bridge's channel)."""
        return cls(stamp=frame.stamp, rgb=frame.rgb, depth=frame.depth, K=frame.K, T_map_base=frame.T_map_base,
                   T_base_camera=frame.T_base_camera, depth_range=frame.depth_range, instances=instances,
                   instance_categories=categories, instance_unoccluded=unoccluded)
