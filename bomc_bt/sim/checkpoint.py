"""The simulated robot's state at a moment of a pass, and putting it back: exact resume.

A monitor pass commits its progress with every frame (:mod:`bomc_bt.pass_resume`). When
the process is killed the simulated world dies with it, so the commit must carry what the
world was: the session's robot time (the clock's step count), the robot's true pose and
odometry, how many of the session's ``during`` changes were applied (they stay applied;
one scheduled earlier is never applied twice), the localization estimate's error, the
people walking about, the obstacle layer, the random streams' states, and when the camera
and obstacle layer last fired. The detector, the camera noise and the lidar noise draw
from streams keyed by the seed and the robot time, so restoring the clock restores them.

The goal being driven to is restored with its path and the navigator's timers; the
resumed tree sends the same goal again and the robot drives on. Not restored: a
relocalization in flight (a pass commits only once localized), and, like the recovery's
own log and the floor it watches, a map a stuck pass refreshed (``refresh_map``): the
resumed pass navigates on the saved map until it finds the same again.
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.pass_resume import pack_mask
from bomc_bt.sim.navigation import NavHandle
from bomc_bt.sim.tiled_mask import TiledMaskText, decode


def robot_state(robot) -> dict[str, Any]:
    """``robot`` (a :class:`~bomc_bt.sim.robot.SimRobot`) at this step, JSON-able."""
    t = robot._true
    layer = robot._obstacles
    obstacles = None if layer is None else {**_tiles_of(layer).encode(layer.mask, layer.version, layer.changed_since),
                                            "version": int(layer.version)}
    return {
        "kind": "sim",
        "session": robot.session,
        "steps": int(robot.clock.steps),
        "true_pose": _pose(t),
        "distance_travelled": float(robot.distance_travelled),
        "during_applied": int(robot._during_applied),
        "localized": bool(robot._localized),
        "offset": robot._offset.tolist(),
        "lost": bool(robot._lost),
        "estimate": None if robot._estimate is None else _pose(robot._estimate),
        "last_frame": None if robot._last_frame == -np.inf else float(robot._last_frame),
        "next_obstacle_update": float(robot._next_obstacle_update),
        "people": {"positions": robot.people.positions.tolist(), "headings": robot.people.headings.tolist()},
        "obstacles": obstacles,
        "rng": {name: getattr(robot, name).bit_generator.state for name in _STREAMS},
        "stuck": bool(robot._stuck),
        "navigation": _navigation_state(robot.navigator),
    }


def _navigation_state(nav) -> dict[str, Any] | None:
    """The goal being driven to, its path and the navigator's timers (None: no goal in flight)."""
    if not nav.active:
        return None
    def finite(v):
        return None if v is None or not np.isfinite(v) else float(v)

    return {"goal": _pose(nav.handle.goal), "path": None if nav.path is None else nav.path.tolist(),
            "best": finite(nav._best), "last_progress": finite(nav._last_progress),
            "next_check": finite(nav._next_check), "fail_at": finite(nav._fail_at),
            "stuck_since": finite(nav._stuck_since), "backup_until": finite(nav._backup_until),
            "no_plan_since": finite(nav._no_plan_since),
            "at_position": bool(nav._at_position),
            "progress_marks": nav._marks.tolist()}


def _restore_navigation(robot, saved: dict[str, Any] | None) -> None:
    """Put the goal in flight back: the tree sends it again and drives on (SimRobot.navigate)."""
    if saved is None:
        return
    nav = robot.navigator
    nav.handle = NavHandle(Pose2D(*(float(v) for v in saved["goal"])))
    nav.path = None
    if saved["path"] is not None:
        nav._set_path(np.asarray(saved["path"], dtype=float).reshape(-1, 2))
    def value(key: str, default: float) -> float:
        return default if saved[key] is None else float(saved[key])

    nav._best, nav._last_progress = value("best", np.inf), value("last_progress", 0.0)
    nav._next_check, nav._fail_at = value("next_check", 0.0), value("fail_at", np.inf)
    nav._stuck_since = None if saved["stuck_since"] is None else float(saved["stuck_since"])
    nav._backup_until = value("backup_until", -np.inf)
    no_plan = saved.get("no_plan_since")  # absent in checkpoints saved before plan_patience
    nav._no_plan_since = None if no_plan is None else float(no_plan)
    nav._at_position = bool(saved["at_position"])
    marks = saved.get("progress_marks") or []  # absent in checkpoints saved before they were kept
    nav._marks = np.asarray(marks, dtype=float).reshape(-1, 3)
    robot._resumed_navigation = nav.handle


_STREAMS = ("_nav_rng", "_noise_rng", "_reloc_rng")
_TILED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # obstacle layer -> its TiledMaskText


def _tiles_of(layer) -> TiledMaskText:
    """The tile encoder of ``layer``'s mask, kept while the layer lives: a checkpoint is
    saved with every frame, and only the tiles a scan changed are compressed again."""
    if layer not in _TILED:
        _TILED[layer] = TiledMaskText()
    return _TILED[layer]


def _pose(p: Pose2D) -> list[float]:
    return [float(p.x), float(p.y), float(p.yaw)]


def restore_robot(robot, state: dict[str, Any]) -> None:
    """Put ``robot`` (fresh, for the same world, session and seed, its map in use) back
    where :func:`robot_state` saw it."""
    if state.get("kind") != "sim" or state.get("session") != robot.session:
        raise ValueError("the saved robot state is not of this simulated session")
    robot.clock.steps = int(state["steps"])
    while robot._during_applied < int(state["during_applied"]) and robot._pending:
        robot._apply_next_during()
    x, y, yaw = (float(v) for v in state["true_pose"])
    robot._true = Pose2D(x, y, yaw)
    robot.distance_travelled = float(state["distance_travelled"])
    robot._localized = bool(state["localized"])
    robot._offset = np.asarray(state["offset"], dtype=float).reshape(3)
    robot._lost = bool(state["lost"])
    robot._last_frame = -np.inf if state["last_frame"] is None else float(state["last_frame"])
    robot._next_obstacle_update = float(state["next_obstacle_update"])
    people = state["people"]
    robot.people.positions = np.asarray(people["positions"], dtype=float).reshape(-1, 2)
    robot.people.headings = np.asarray(people["headings"], dtype=float).reshape(-1, 2)
    saved = state.get("obstacles")
    if saved is not None and robot._obstacles is not None:
        layer = robot._obstacles
        # "mask": the whole mask packed (checkpoints saved before the tiles)
        packed = saved["mask"] if "mask" in saved else pack_mask(decode(saved, layer.mask.shape))
        layer.load(packed, saved["version"])
        robot.planners.use_map(robot._map, robot._obstacles)
    for name, value in state["rng"].items():
        if name in _STREAMS:
            getattr(robot, name).bit_generator.state = value
    robot._stuck = bool(state.get("stuck", False))
    _restore_navigation(robot, state.get("navigation"))
    robot._take_scan()
    estimate = state.get("estimate")
    robot._estimate = None if estimate is None else Pose2D(*(float(v) for v in estimate))
