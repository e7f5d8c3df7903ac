"""The monitor pass's coverage plan, offline: how many stops and headings, how far, how much floor.

Plans ``traversal.plan: coverage`` (bomc_bt/coverage_plan.py) from the dock on each floor's
map -- generated offices (``bomc world office``, ground-truth map, the world's start) and
any saved sites given (their map and the first pose of their trajectory) -- without
driving, and prints one row per floor: stops, headings (waypoints), the tour's path
length (the planner's legs, dock to the last stop, as the robot would drive them), the
floor the plan's model of sight sees (stops all around, legs facing ahead, measured on the
final tour), the floor it faces (the same with each stop seen only through its headings'
field of view, as the robot turns), and the CPU seconds planning took. ``--set`` changes
traversal parameters, e.g. to compare with the stops no longer dropped:

    python benchmarks/bench_coverage_plan.py --office 93x90:41 --office 36x28:7
    python benchmarks/bench_coverage_plan.py --office 93x90:41 --set drop_redundant=false
    python benchmarks/bench_coverage_plan.py --site /path/to/site --shared office-s --shared lab-b
    python benchmarks/bench_coverage_plan.py --shared office-s --shared lab-b --known
    python benchmarks/bench_coverage_plan.py --office 93x90:41 --reach 8

``--reach`` plans for a camera whose detections count as evidence that far (the pass's
``projection.expect_range``, 5 m by default): how long a tour a longer-reaching detector
would need.

``--known`` gives the plan the world's objects as the graph's nodes (as a later session
has them), each to be looked at once from within ``projection.miss_full_range``
(bomc_bt/coverage_known.py); the ``near`` column counts the nodes so looked at. A node is
shown by the floor near it that sees a face of its box; ``--centre-only`` gives the nodes no
box, so floor across the wall a door or a table stands against shows it too (before session 81).

A real pass also sees floor while turning and drives smoother legs; Cover Gaps and the
refresh tour come on top (``bomc monitor`` reports the whole pass).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from shared_folder import SHARED

from bomc_bt.config import load_config
from bomc_bt.coverage_plan import _leg, plan_coverage
from bomc_bt.geometry import Pose2D, wrap_angle
from bomc_bt.grid import load_map
from bomc_bt.planner import GridPlanner
from bomc_bt.sight import Sight, along_paths, faced, lattice_places
from bomc_bt.turn_order import end_direction
from bomc_bt.viewpoints import floor_mask
from bomc_bt.world import load_world


def seen_share(grid, start: Pose2D, plan, params, planner_params, view_range: float) -> tuple[float, float]:
    """Shares of the floor the tour sees: (stops all around, stops facing their headings),
    both with the legs driven facing ahead. The robot turns only to a stop's headings, so
    floor the first share counts and the second does not is left to the gap viewpoints."""
    k = max(1, int(round(params.target_step / grid.resolution)))
    floor = floor_mask(grid, params.shadow)[::k, ::k]
    sight = Sight(grid, floor, k, view_range, params.min_range, params.shadow)
    planner = GridPlanner(grid, planner_params)
    stops = plan.viewpoints
    nodes = [np.asarray(start.xy, float)] + [np.asarray(p, float) for p in stops]
    paths = [_leg(planner, a, b) for a, b in zip(nodes[:-1], nodes[1:], strict=True)]
    hfov = math.radians(params.hfov_deg)
    around = np.zeros(floor.size, dtype=bool)
    around[along_paths(sight, paths, params.drive_by_step, hfov)] = True
    if stops:
        for view in sight.visible(lattice_places(sight, np.asarray(stops, float))):
            around[view] = True
    poses = np.array([(w.x, w.y, w.yaw) for w in plan.plan.waypoints], dtype=float).reshape(-1, 3)
    facing = faced(sight, paths, poses, params.drive_by_step, hfov)
    total = max(floor.sum(), 1)
    return float(around.sum() / total), float(len(facing) / total)


def leg_length(grid, start: Pose2D, stops: list, planner_params) -> float:
    planner = GridPlanner(grid, planner_params)
    nodes = [np.asarray(start.xy, float)] + [np.asarray(p, float) for p in stops]
    total = 0.0
    for a, b in zip(nodes[:-1], nodes[1:], strict=True):
        path = _leg(planner, a, b)
        path = np.array([a, b]) if path is None else np.asarray(path)
        total += float(np.hypot(*np.diff(path, axis=0).T).sum())
    return total


def turning(grid, start: Pose2D, waypoints: list[Pose2D], planner_params) -> float:
    """Radians the robot turns on the spot driving the plan: at each stop through its
    headings, and at each end of a leg between the leg's direction there and the heading
    it leaves from or arrives at (a differential-drive robot faces its path to drive)."""
    planner = GridPlanner(grid, planner_params)
    total, yaw, at = 0.0, start.yaw, np.asarray(start.xy, float)
    for w in waypoints:
        to = np.asarray(w.xy, float)
        if np.hypot(*(to - at)) > 1e-9:
            path = _leg(planner, at, to)
            path = np.array([at, to]) if path is None else np.asarray(path)
            leave, arrive = end_direction(path, True), end_direction(path, False)
            if leave is not None and arrive is not None:
                total += abs(wrap_angle(leave - yaw))
                yaw = arrive
        total += abs(wrap_angle(w.yaw - yaw))
        yaw, at = w.yaw, to
    return total


def world_objects(world_yaml: Path) -> tuple[np.ndarray, list]:
    """(N, 2) positions of a world's objects, the known nodes of ``--known``, and their boxes."""
    world = load_world(world_yaml)
    objects = list(world.objects.values())
    boxes = [np.concatenate([o.footprint().min(axis=0), o.footprint().max(axis=0)]) for o in objects]
    return np.array([o.position[:2] for o in objects], dtype=float).reshape(-1, 2), boxes


def floors(args, tmp: Path) -> list[tuple[str, Path, Pose2D, tuple | None]]:
    out = []
    for spec in args.office:
        size, seed = spec.split(":")
        world = tmp / f"office-{size}-{seed}.yaml"
        subprocess.run([sys.executable, "-m", "bomc_bt.cli", "world", "office", "--out", str(world), "--size", size,
                        "--seed", seed, "--force"], check=True, capture_output=True)
        data = yaml.safe_load(world.read_text())
        out.append((f"office {size} s{seed}", tmp / data["map"], Pose2D(*data["start"][:2], 0.0),
                    world_objects(world) if args.known else None))
    shared = SHARED / "worlds"
    for name in args.shared:
        data = yaml.safe_load((shared / f"{name}.yaml").read_text())
        out.append((name, shared / data["map"], Pose2D(*data["start"][:2], 0.0),
                    world_objects(shared / f"{name}.yaml") if args.known else None))
    for site in args.site:
        with open(Path(site) / "trajectory.csv") as f:
            first = list(csv.reader(f))[1]
        out.append((Path(site).name, Path(site) / "map.yaml", Pose2D(float(first[1]), float(first[2]), 0.0), None))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--office", action="append", default=[], metavar="WxH:SEED", help="a generated office floor")
    ap.add_argument("--shared", action="append", default=[], metavar="NAME", help="a shared world (office-s, lab-b)")
    ap.add_argument("--site", action="append", default=[], metavar="DIR", help="a saved site's folder")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a traversal parameter")
    ap.add_argument("--known", action="store_true", help="the worlds' objects as known nodes, each looked at from near")
    ap.add_argument("--centre-only", action="store_true",
                    help="with --known: the nodes without footprints (floor near a node shows it across a wall)")
    ap.add_argument("--reach", type=float, default=None, metavar="M",
                    help="the camera reach [m] the plan assumes (default: projection.expect_range)")
    args = ap.parse_args(argv)
    config = load_config([])
    changes = {}
    for item in args.set:
        key, value = item.split("=", 1)
        current = getattr(config.traversal, key)
        changes[key] = value.lower() in ("1", "true", "yes") if isinstance(current, bool) else type(current)(value)
    params = dataclasses.replace(config.traversal, **changes)
    reach = config.projection.expect_range if args.reach is None else args.reach
    if not 0.0 < reach <= 30.0:
        ap.error("--reach must be in (0, 30] m")
    print(f"{'floor':18s} {'stops':>6s} {'headings':>8s} {'path km':>8s} {'floor seen':>10s} {'faced':>6s} "
          f"{'plan cpu s':>10s} {'near':>9s} {'turn rad':>8s}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, map_yaml, start, known in floors(args, Path(tmp)):
            grid = load_map(map_yaml)
            began = time.process_time()
            positions, boxes = known if known is not None else (None, None)
            plan = plan_coverage(grid, start, reach, params, config.sim.planner, positions,
                                 config.projection.miss_full_range,
                                 known_footprints=None if args.centre_only else boxes)
            cpu = time.process_time() - began
            km = leg_length(grid, start, plan.viewpoints, config.sim.planner) / 1000
            seen, faced = seen_share(grid, start, plan, params, config.sim.planner, reach)
            stops, headings = len(plan.viewpoints), len(plan.plan.waypoints)
            near = f"{plan.known_near}/{plan.known}"
            turn = turning(grid, start, plan.plan.waypoints, config.sim.planner)
            print(f"{name:18s} {stops:6d} {headings:8d} {km:8.3f} {seen:10.3f} {faced:6.3f} {cpu:10.1f} "
                  f"{near:>9s} {turn:8.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
