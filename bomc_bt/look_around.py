"""Look Around: the head turns a waypoint makes so the camera confirms nearby nodes.

At a waypoint the robot turns towards nodes this pass has not confirmed (or confirmed so
long ago that they may have gone since, see :func:`bomc_bt.monitoring.unverified_headings`),
and faces each heading for ``dwell`` seconds of robot time so frames confirm the node or
count a miss. :class:`HeadTurns` is that plan as a plain object: which heading comes next,
whether the robot is still dwelling, when the look-around has run out of time. The
``LookAround`` leaf only sends the turns it hands out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import OccupancyGrid
from bomc_bt.monitoring import unverified_headings
from bomc_bt.node_sight import camera_clear, sees_target


@dataclass
class LookAroundParams:
    """Settings of Look Around (the ``LookAround`` leaf's ``params`` in ``trees/traverse.yaml``)."""

    radius: float = 5.0  # [m] nodes this close are worth a look (the leaf uses projection.expect_range)
    max_turns: int = 2  # [count] headings per waypoint at most
    dwell: float = 1.5  # [s] robot time facing each heading (frames to confirm or miss)
    timeout: float = 30.0  # [s] robot time for the whole look-around
    # [s] robot time: a node this pass confirmed longer ago gets a look again, in case it
    # was taken away after the camera passed (0: only nodes not confirmed yet)
    refresh_after: float = 600.0
    # turn also towards first sightings the pass has not confirmed (an object the camera caught
    # in one frame on the way; :meth:`~bomc_bt.graph.ObjectGraph.unconfirmed_sightings`)
    unconfirmed: bool = True

    def __post_init__(self) -> None:
        if self.radius <= 0 or self.max_turns < 0 or self.dwell < 0 or self.timeout <= 0:
            raise ValueError("need radius > 0, max_turns >= 0, dwell >= 0 and timeout > 0")
        if self.refresh_after < 0:
            raise ValueError("refresh_after must be >= 0 (0: no refresh)")


@dataclass
class HeadTurns:
    """The headings still to face at one waypoint, the dwell after each turn and the deadline."""

    headings: list[float]
    dwell: float  # robot seconds facing a heading once the turn succeeded
    deadline: float  # robot time after which no new turn starts (and a turn in flight is dropped)
    dwell_until: float | None = field(default=None)
    # unconfirmed first sightings the headings face (the leaf marks them looked at, one look each)
    faced: list = field(default_factory=list)

    def dwelling(self, now: float) -> bool:
        """True while the robot faces the last heading it turned to."""
        return self.dwell_until is not None and now < self.dwell_until

    def turned(self, now: float) -> None:
        """The turn succeeded: face that way for ``dwell`` seconds."""
        self.dwell_until = now + self.dwell

    def timed_out(self, now: float) -> bool:
        return now >= self.deadline

    def next_heading(self, now: float) -> float | None:
        """The next heading to turn to; None when there is none left or time is up."""
        if not self.headings or self.timed_out(now):
            return None
        self.dwell_until = None
        return self.headings.pop(0)


def plan_head_turns(graph, pose: Pose2D | None, session: int, grid: OccupancyGrid, params: LookAroundParams,
                    hfov_deg: float, now: float) -> HeadTurns:
    """The head turns for a waypoint reached at ``pose`` (none without a pose). While a node
    a near, clear view has just missed lies in front of the camera, the robot first holds
    the heading it arrived with for ``dwell`` (:func:`pending_in_front`)."""
    fov = math.radians(hfov_deg)
    sightings = graph.unconfirmed_sightings() if params.unconfirmed and pose is not None else []
    headings = [] if pose is None else unverified_headings(
        graph, pose, session, grid, params.radius, fov, params.max_turns,
        now=now, stale_after=params.refresh_after, sightings=[t.position for t in sightings])
    hold = pose is not None and pending_in_front(graph, pose, grid, params.radius, fov)
    faced = [t for t in sightings if _faced(pose, t.position, headings, params.radius, fov)]
    return HeadTurns(headings, params.dwell, now + params.timeout, now + params.dwell if hold else None, faced)


def _faced(pose: Pose2D, place, headings: list[float], radius: float, fov: float) -> bool:
    """Whether ``place`` lies within ``radius`` and half ``fov`` of one of ``headings`` from ``pose``."""
    dx, dy = float(place[0]) - pose.x, float(place[1]) - pose.y
    bearing = math.atan2(dy, dx)
    return math.hypot(dx, dy) <= radius and any(abs(wrap_angle(bearing - h)) <= fov / 2 for h in headings)


def pending_in_front(graph, pose: Pose2D, grid: OccupancyGrid, radius: float, fov: float) -> bool:
    """A node missed by a near, clear view since its last detection (a run of misses weighing
    1 or more, :mod:`bomc_bt.graph.evidence`) lies within ``radius`` and half the camera's
    ``fov`` of the heading, in the camera's line of sight (:func:`~bomc_bt.node_sight.camera_clear`).
    The frames of the next ``dwell`` decide it: its misses run on to a removal or a detection
    confirms it. Turning away at once, as the robot did at a stop planned to face such a
    node, left a table taken away from a wall on the map for passes: its misses counted only
    over the arrival's few frames."""
    clear = camera_clear(grid)
    for vid in graph.pending():
        node = graph.nodes.get(vid)
        if node is None or not graph.missed_up_close(vid):
            continue
        dx, dy = node.position[0] - pose.x, node.position[1] - pose.y
        distance = math.hypot(dx, dy)
        if not 0.5 <= distance <= radius or abs(wrap_angle(math.atan2(dy, dx) - pose.yaw)) > fov / 2:
            continue
        if sees_target(grid, clear, (pose.x, pose.y), node.position, node.footprint):
            return True
    return False
