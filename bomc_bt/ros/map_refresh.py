"""The map a stuck pass navigates on, published where the robot's navigation reads its map.

When a table gone since the build hems the robot in, the recovery clears the floor the
lidar saw from the map in use (:mod:`bomc_bt.stale_map`) and hands it to the port
(``RobotPort.refresh_map``). On ROS the map is map_server's, so the refreshed copy is
published, latched, on ``refreshed_map_topic`` (default ``/map``): move_base's static layer
takes every new map on its topic, while AMCL keeps the map it asked map_server for (unless
its ``use_map_topic`` is set). The publisher is made on the first refresh, so a pass that
never needs one never publishes on map_server's topic. "" turns it off. The sim-over-ROS
bridge navigates on the map it receives there from the tick it was published in: the
robot counts the maps it published with the other requests it announces with its ticks
(a new latched publisher connects when the bridge hears of it, many quick ticks later).
"""

from __future__ import annotations

from typing import Any

from bomc_bt.grid import OccupancyGrid
from bomc_bt.ros.convert import fill_grid
from bomc_bt.ros.params import RosParams


class MapRefresh:
    """Publishes refreshed maps on ``params.refreshed_map_topic`` (latched)."""

    def __init__(self, rospy: Any, params: RosParams):
        self.rospy, self.params = rospy, params
        self._pub: Any = None
        self.published = 0

    def publish(self, grid: OccupancyGrid) -> bool:
        """Publish ``grid`` stamped now in the map frame; False when turned off."""
        topic = self.params.refreshed_map_topic
        if not topic:
            return False
        from nav_msgs.msg import OccupancyGrid as GridMsg
        from rospy.numpy_msg import numpy_msg

        cls = numpy_msg(GridMsg)
        if self._pub is None:
            self._pub = self.rospy.Publisher(topic, cls, queue_size=1, latch=True)
        msg: Any = cls()
        msg.header.frame_id = self.params.map_frame
        msg.header.stamp = msg.info.map_load_time = self.rospy.Time.now()
        fill_grid(msg, grid)
        self._pub.publish(msg)
        self.published += 1
        return True

    def close(self) -> None:
        if self._pub is not None:
            self._pub.unregister()
            self._pub = None
