"""What the executive shows in RViz and to other nodes while a mission runs.

* the object graph as a ``visualization_msgs/MarkerArray``: per node a shape (cube) and a
  text label, coloured by category (a stable hash, so a category keeps its colour);
* the current frontiers (build) and the traversal waypoints (monitor) as markers;
* the tree as a text snapshot (``std_msgs/String``, the terminal view's lines);
* change events of the graph as ``std_msgs/String`` JSON, one per raw event while the pass
  runs (for debugging), and at the end of the pass one summary (:func:`summary_json`): the
  net change per node since the previous pass, with its evidence -- what the operator acts on.

:class:`MissionPublisher` is a tick hook: it publishes every ``publish_period`` s of ROS
time, so a fast tick rate never floods the network.
"""

from __future__ import annotations

import colorsys
import json
import zlib
from collections.abc import Iterable
from typing import Any

import numpy as np

from bomc_bt.mission import MissionContext
from bomc_bt.ros.params import RosParams

STATE_COLOURS = {
    "pending": (0.6, 0.6, 0.6),
    "visited": (0.1, 0.8, 0.2),
    "detoured": (1.0, 0.7, 0.0),
    "missed": (0.9, 0.1, 0.1),
}


def category_colour(category: str) -> tuple[float, float, float]:
    """A bright colour that depends only on the category's name."""
    hue = (zlib.crc32(category.encode()) % 360) / 360.0
    return colorsys.hsv_to_rgb(hue, 0.8, 0.95)


def _marker(
    frame: str,
    stamp: Any,
    ns: str,
    ident: int,
    kind: int,
    xyz: Iterable[float],
    rgb: tuple[float, float, float],
    scale: tuple[float, float, float],
) -> Any:
    from visualization_msgs.msg import Marker

    m = Marker()
    m.header.frame_id, m.header.stamp = frame, stamp
    m.ns, m.id, m.type, m.action = ns, int(ident), kind, Marker.ADD
    m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in xyz)
    m.pose.orientation.w = 1.0
    m.scale.x, m.scale.y, m.scale.z = scale
    m.color.r, m.color.g, m.color.b, m.color.a = (*rgb, 0.9)
    return m


def graph_markers(nodes: Iterable[Any], frame: str, stamp: Any) -> Any:
    """One cube and one text label per present node; a DELETEALL first drops removed nodes."""
    from visualization_msgs.msg import Marker, MarkerArray

    out = MarkerArray()
    clear = Marker()
    clear.action = Marker.DELETEALL
    clear.header.frame_id = frame
    out.markers.append(clear)
    for node in nodes:
        if getattr(node, "state", "present") != "present":
            continue
        rgb = category_colour(node.category)
        p = np.asarray(node.position, dtype=float)
        out.markers.append(_marker(frame, stamp, "objects", node.id, Marker.CUBE, p, rgb, (0.3, 0.3, 0.3)))
        label = _marker(
            frame,
            stamp,
            "labels",
            node.id,
            Marker.TEXT_VIEW_FACING,
            p + [0.0, 0.0, 0.35],
            rgb,
            (0.0, 0.0, 0.2),
        )
        label.text = f"{node.category} #{node.id}"
        out.markers.append(label)
    return out


def point_markers(
    points: Iterable[tuple[float, float]],
    frame: str,
    stamp: Any,
    ns: str,
    colours: Iterable[tuple[float, float, float]] | None = None,
    size: float = 0.25,
) -> Any:
    """Spheres at planar points (frontier targets, waypoints), with a DELETEALL first."""
    from visualization_msgs.msg import Marker, MarkerArray

    out = MarkerArray()
    clear = Marker()
    clear.action, clear.ns = Marker.DELETEALL, ns
    clear.header.frame_id = frame
    out.markers.append(clear)
    pts = list(points)
    cols = list(colours) if colours is not None else [(0.2, 0.5, 1.0)] * len(pts)
    for i, ((x, y), rgb) in enumerate(zip(pts, cols, strict=True)):
        out.markers.append(_marker(frame, stamp, ns, i, Marker.SPHERE, (x, y, 0.1), rgb, (size, size, size)))
    return out


def event_json(event: Any) -> str:
    """A graph change event as one JSON object."""
    payload = {
        "kind": event.kind,
        "node": int(event.node_id),
        "category": event.category,
        "position": [round(float(v), 3) for v in event.position],
        "session": int(event.session),
        "stamp": float(event.stamp),
    }
    if event.previous is not None:
        payload["previous"] = [round(float(v), 3) for v in event.previous]
    return json.dumps(payload)


def summary_json(session: int, changes: dict[str, Any]) -> str:
    """The end-of-pass message on the events topic: ``{"kind": "summary", "session": N,
    "since_session": P, "counts": {...}, "changes": [...], "first_seen": K}`` (records as the
    session report's; ``first_seen``: nodes new to the map, listed among the records as such)."""
    return json.dumps({"kind": "summary", "session": int(session), "since_session": changes["since_session"],
                       "counts": changes["counts"], "changes": changes["nodes"],
                       "first_seen": changes.get("first_seen", 0), "retracted": changes.get("retracted", 0)})


class MissionPublisher:
    """Tick hook: markers, the tree snapshot and new events, every ``publish_period`` s."""

    def __init__(self, ctx: MissionContext, params: RosParams):
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        from bomc_bt.ros import import_ros

        self.rospy = rospy = import_ros()
        self.ctx, self.params = ctx, params
        self.pubs = {
            "objects": rospy.Publisher(params.markers_topic, MarkerArray, queue_size=1, latch=True),
            "frontiers": rospy.Publisher(params.frontiers_topic, MarkerArray, queue_size=1, latch=True),
            "waypoints": rospy.Publisher(params.waypoints_topic, MarkerArray, queue_size=1, latch=True),
            "tree": rospy.Publisher(params.tree_topic, String, queue_size=1, latch=True),
            "events": rospy.Publisher(params.events_topic, String, queue_size=100),
        }
        self._next = -np.inf
        self._events_seen = 0
        self._summary_sent = False

    def __call__(self, runner: Any) -> None:
        now = self.ctx.now()
        ended = bool(self.ctx.outcome) and self.ctx.store is not None and not self._summary_sent
        if now < self._next and not ended:
            return
        self._next = now + self.params.publish_period
        self.publish(runner.root)
        if ended:  # the session was closed on this tick: the last raw events, then the summary
            self.publish_summary()

    def publish_summary(self) -> None:
        """The pass's net changes, once, after its session was closed."""
        from std_msgs.msg import String

        from bomc_bt.report import changes_summary

        self.pubs["events"].publish(String(data=summary_json(self.ctx.session, changes_summary(self.ctx))))
        self._summary_sent = True

    def publish(self, root: Any) -> None:
        from std_msgs.msg import String

        from bomc_bt.tree.view import render_tree

        ctx, frame = self.ctx, self.params.map_frame
        stamp = self.rospy.Time.from_sec(ctx.now())
        self.pubs["tree"].publish(String(data="\n".join(render_tree(root))))
        if ctx.graph is not None:
            self.pubs["objects"].publish(graph_markers(ctx.graph.nodes.values(), frame, stamp))
        explorer = ctx.explorer
        if explorer is not None and getattr(explorer, "frontiers", None) is not None:
            self.pubs["frontiers"].publish(
                point_markers([f.centroid for f in explorer.frontiers], frame, stamp, "frontiers", size=0.2)
            )
        state = ctx.traverse
        if state is not None:
            waypoints = [state.plan.waypoints[i] for i in range(len(state.states))]
            colours = [STATE_COLOURS.get(s, (0.6, 0.6, 0.6)) for s in state.states]
            self.pubs["waypoints"].publish(
                point_markers([(w.x, w.y) for w in waypoints], frame, stamp, "waypoints", colours)
            )
        if ctx.store is not None and ctx.session:
            events = ctx.store.events(ctx.session)
            for event in events[self._events_seen :]:
                self.pubs["events"].publish(String(data=event_json(event)))
            self._events_seen = len(events)

    def close(self) -> None:
        for pub in self.pubs.values():
            pub.unregister()
