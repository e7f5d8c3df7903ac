"""``bomc publish SITE``: a finished site's map and objects, latched for RViz.

Publishes once, latched, on a running roscore (``ROS_MASTER_URI``): the saved map as a
``nav_msgs/OccupancyGrid`` and the objects (now, or at the end of ``--session N``) as a
``visualization_msgs/MarkerArray`` -- a DELETEALL, then a cube and a text label per object,
coloured by category, as the executive shows a live graph (:mod:`bomc_bt.ros.publish`).
Latched messages reach every subscriber that connects while the node lives, so the
command stays up until Ctrl-C (or ``--duration`` seconds). The site is only read.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bomc_bt.graph import AssociationParams
from bomc_bt.grid import load_map
from bomc_bt.ros.convert import fill_grid
from bomc_bt.ros.node import ensure_node
from bomc_bt.ros.publish import graph_markers
from bomc_bt.site.query import open_site

NODE_NAME = "bomc_publish"


@dataclass(frozen=True)
class PublishTopics:
    """Where the site goes (``bomc publish --map-topic / --objects-topic / --frame``)."""

    map_topic: str = "/bomc/site_map"
    objects_topic: str = "/bomc/site_objects"
    frame: str = "map"


def publish_site(root: str | Path, topics: PublishTopics, session: int | None = None, duration: float = 0.0,
                 association: AssociationParams | None = None, announce=None) -> int:
    """Latch the site's map and objects; keep the node up ``duration`` s (0: until Ctrl-C)."""
    with open_site(root, association) as site:
        grid = load_map(site.site.map_yaml)
        objects = site.objects(session=session)
    rospy = ensure_node(NODE_NAME)
    from nav_msgs.msg import OccupancyGrid as GridMsg
    from rospy.numpy_msg import numpy_msg
    from visualization_msgs.msg import MarkerArray

    grid_cls = numpy_msg(GridMsg)
    map_pub = rospy.Publisher(topics.map_topic, grid_cls, queue_size=1, latch=True)
    objects_pub = rospy.Publisher(topics.objects_topic, MarkerArray, queue_size=1, latch=True)
    stamp = rospy.Time.now()
    msg: Any = grid_cls()
    msg.header.frame_id, msg.header.stamp = topics.frame, stamp
    msg.info.map_load_time = stamp
    fill_grid(msg, grid)
    map_pub.publish(msg)
    objects_pub.publish(graph_markers(objects, topics.frame, stamp))
    (announce or _say)(f"publishing the map ({grid.width}x{grid.height} cells) on {topics.map_topic} and "
                       f"{len(objects)} object(s) on {topics.objects_topic}, latched"
                       + ("; Ctrl-C to stop" if duration <= 0 else ""))
    deadline = None if duration <= 0 else time.monotonic() + duration
    try:
        while not rospy.is_shutdown() and (deadline is None or time.monotonic() < deadline):
            time.sleep(0.1)
    except KeyboardInterrupt:  # Ctrl-C is how an operator ends it: a success
        pass
    finally:
        rospy.signal_shutdown("bomc publish ended")
    return 0


def _say(line: str) -> None:
    print(line, flush=True)  # a script waiting on the pipe reads it at once
