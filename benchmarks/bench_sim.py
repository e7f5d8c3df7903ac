"""Simulator speed: drive through goals on office-s in build mode and split the time per step.

Run: .venv/bin/python benchmarks/bench_sim.py [--world PATH] [--goals N] [--seed N]

Prints sim seconds, wall seconds, the real-time factor and the mean milliseconds per step
spent in the lidar, the mapper, planning (costmap builds, A*, path checks) and the rest
(motion, navigation bookkeeping), then the lidar against the naive per-cell ray marcher
measured in the same run on the same scan poses. No behaviour tree is involved.
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import numpy as np
from shared_folder import SHARED

from bomc_bt import planner as planner_module
from bomc_bt.geometry import Pose2D
from bomc_bt.robot import Status
from bomc_bt.sim import robot as robot_module
from bomc_bt.sim.lidar import DistanceField, _dense, naive_trace
from bomc_bt.sim.robot import SimRobot
from bomc_bt.world import load_world

DEFAULT_WORLD = SHARED / "worlds" / "office-s.yaml"
TIMES: dict[str, float] = defaultdict(float)


def timed(name: str, fn):
    def wrapper(*args, **kwargs):
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            TIMES[name] += time.perf_counter() - t
    return wrapper


def instrument(robot: SimRobot) -> None:
    robot.lidar.scan = timed("lidar", robot.lidar.scan)
    assert robot.mapper is not None
    robot.mapper.integrate = timed("mapper", robot.mapper.integrate)
    robot.planners.live = timed("planning", robot.planners.live)
    robot.planners.path_clear = timed("planning", robot.planners.path_clear)


def dense_trace(pose: Pose2D, dirs: np.ndarray, field: DistanceField, range_max: float) -> np.ndarray:
    """Every beam sampled every half cell in one numpy gather (the vectorised naive way)."""
    res = field.resolution
    u0 = (pose.x - field.origin[0]) / res + 1.0
    v0 = (pose.y - field.origin[1]) / res + 1.0
    return _dense(field, u0, v0, dirs[:, 0], dirs[:, 1], np.zeros(len(dirs)), range_max / res) * res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default=str(DEFAULT_WORLD))
    ap.add_argument("--goals", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    world = load_world(args.world)
    robot = SimRobot(world, 1, seed=args.seed, mode="build")
    instrument(robot)
    # A* runs inside plan(), which the navigator calls directly on a planner object.
    planner_module.GridPlanner.plan = timed("planning", planner_module.GridPlanner.plan)
    rng = np.random.default_rng(args.seed)
    cells = robot.scene.free_cells(0.5)
    goals = [Pose2D(*cells[rng.integers(len(cells))]) for _ in range(args.goals)]
    scan_poses: list[Pose2D] = []
    outcomes: dict[str, int] = defaultdict(int)
    TIMES.clear()
    wall0 = time.perf_counter()
    for goal in goals:
        handle = robot.navigate(goal)
        while handle.status() is Status.RUNNING and robot.now() < 3600.0:
            robot.step()
            if robot.clock.steps % 50 == 0:
                scan_poses.append(robot.true_pose)
        outcomes[handle.status().value] += 1
    wall = time.perf_counter() - wall0
    steps = robot.clock.steps
    sim = robot.now()
    lidar_calls = robot.mapper.updates if robot.mapper else 0
    motion = wall - sum(TIMES.values())
    print(f"world {world.name}: {len(goals)} goals {dict(outcomes)}, "
          f"{robot.distance_travelled:.0f} m driven, {lidar_calls} map updates")
    print()
    print("| sim s | wall s | real-time factor | steps | ms/step total "
          "| lidar | mapper | planning | motion+rest |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    per = 1000.0 / max(steps, 1)
    print(f"| {sim:.1f} | {wall:.2f} | {sim / wall:.0f}x | {steps} | {wall * per:.3f} "
          f"| {TIMES['lidar'] * per:.3f} | {TIMES['mapper'] * per:.3f} | {TIMES['planning'] * per:.3f} "
          f"| {motion * per:.3f} |")
    print()
    # Lidar against the naive marcher on the same poses (fewer poses: the baseline is slow).
    poses = scan_poses[:: max(1, len(scan_poses) // 15)][:15]
    field, mask = robot.scene.lidar_field, robot.scene.lidar_mask
    lidar = robot_module.Lidar(robot.params.lidar)
    t = time.perf_counter()
    fast = [lidar.scan(p, field, 0.0) for p in poses]
    fast_ms = (time.perf_counter() - t) * 1000.0 / len(poses)
    t = time.perf_counter()
    slow = []
    for p in poses:
        ang = lidar.rel_angles + p.yaw
        slow.append(naive_trace(p.x, p.y, np.stack([np.cos(ang), np.sin(ang)], axis=1), robot.scene.grid,
                                mask, lidar.params.range_max))
    slow_ms = (time.perf_counter() - t) * 1000.0 / len(poses)
    t = time.perf_counter()
    for p in poses:
        ang = lidar.rel_angles + p.yaw
        dense_trace(p, np.stack([np.cos(ang), np.sin(ang)], axis=1), field, lidar.params.range_max)
    dense_ms = (time.perf_counter() - t) * 1000.0 / len(poses)
    a, b = np.concatenate([f.ranges for f in fast]), np.concatenate(slow)
    both = np.isfinite(a) & np.isfinite(b)
    diff = np.abs(a[both] - b[both])
    print("| lidar (662 beams) | ms/scan | speed-up | median abs diff (m) | beams within 5 cm |")
    print("| --- | ---: | ---: | ---: | ---: |")
    print(f"| naive per-cell marching, per beam (baseline) | {slow_ms:.2f} | 1.0x | | |")
    print(f"| per-cell marching, vectorised over beams x samples | {dense_ms:.2f} "
          f"| {slow_ms / dense_ms:.0f}x | | |")
    print(f"| sphere tracing on the distance field | {fast_ms:.3f} | {slow_ms / fast_ms:.0f}x "
          f"| {np.median(diff):.4f} | {np.mean(diff < 0.05) * 100:.1f}% |")
    print()
    print(f"scans ray-cast during the drive: {lidar_calls} map updates (scans are cast lazily, "
          f"only when the mapper or a caller reads them)")


if __name__ == "__main__":
    main()
