"""How often a view is judged a patch of a wall: views of true objects against false boxes.

Renders frames of a generated office from random free poses and headings, runs the
simulated ``realistic`` detector and segmenter with its false-positive rate raised (so that
there are enough false boxes to count; the boxes themselves are the preset's: a random
patch of background, any category), and projects every detection one at a time, as a pass
does, with ``projection.patch_share`` at its configured value and off. It prints, for views
of true objects (those of ``projection.flush_categories`` apart: exempt) and for false
boxes, how many gave an observation with the test off and how many of those the test
drops (:mod:`bomc_bt.perception.surface_patch`):

    python benchmarks/bench_wall_patches.py --size 93x90 --seed 9652 --frames 5000
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.config import load_config  # noqa: E402
from bomc_bt.geometry import Pose2D  # noqa: E402
from bomc_bt.officegen import OfficeParams, generate_office  # noqa: E402
from bomc_bt.perception.projection import ProjectionStats, detections_to_observations  # noqa: E402
from bomc_bt.sim.detector import SimDetector  # noqa: E402
from bomc_bt.sim.factory import SimRobots  # noqa: E402


def judged(world: Path, frames: int, seed: int, fp_rate: float) -> Counter:
    """Counts keyed (group, "kept off" | "dropped"): views that give an observation with the
    test off, and those of them the configured test drops as wall patches."""
    config = load_config([])
    robots = SimRobots(world, seed=seed)
    robots.prepare(config)
    robot = robots.monitor_robot(config, 1)
    objects = list(robot._objects.values())
    detector = SimDetector(replace(config.detector, false_positive_rate=fp_rate), seed=seed)
    categories = sorted({o.category for o in objects})
    rng = np.random.default_rng(seed)
    grid, walls = robot.world.grid, robot.world.walls()
    centres = np.array([o.position[:2] for o in objects])
    (x0, y0), (x1, y1) = grid.cell_to_world(0, 0), grid.cell_to_world(*(np.array(grid.data.shape) - 1))
    on, off = config.projection, replace(config.projection, patch_share=1.1)
    out: Counter = Counter()
    done = 0
    while done < frames:
        x, y = rng.uniform(min(x0, x1), max(x0, x1)), rng.uniform(min(y0, y1), max(y0, y1))
        if grid.value_at(x, y) != 0 or np.min(np.hypot(*(centres - [x, y]).T)) <= 0.6:
            continue
        done += 1
        pose = Pose2D(x, y, rng.uniform(-math.pi, math.pi))
        frame = robot.camera.render(walls, grid, robot.world.wall_height, objects, list(robot.scene.obstacles), [],
                                    pose, pose, 1000.0 + done)
        for det in detector.segment(frame, detector.detect(frame, categories)):
            source = detector.source(frame, det)
            flush = det.category in on.flush_categories
            group = "false box" if source == 0 else ("flush (exempt)" if flush else "true object")
            if not detections_to_observations(frame, [det], off):
                continue
            out[group, "kept off"] += 1
            stats = ProjectionStats()
            detections_to_observations(frame, [det], on, stats)
            out[group, "dropped"] += stats.on_wall
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="93x90", help="WxH of the generated office, metres")
    ap.add_argument("--seed", type=int, default=9652)
    ap.add_argument("--frames", type=int, default=5000)
    ap.add_argument("--fp-rate", type=float, default=0.5, help="false boxes per frame (the preset's 0.01 is too few)")
    args = ap.parse_args(argv)
    width, height = (float(v) for v in args.size.lower().split("x"))
    with tempfile.TemporaryDirectory() as tmp:
        world = Path(tmp) / "office.yaml"
        generate_office(OfficeParams(width=width, height=height, seed=args.seed, sessions=1), world)
        counts = judged(world, args.frames, args.seed, args.fp_rate)
    print(f"# office {args.size} seed {args.seed}, {args.frames} frames, false boxes at {args.fp_rate} a frame")
    print(f"{'views':<16} {'observations':>12} {'wall patches':>12} {'share':>7}")
    for group in ("true object", "flush (exempt)", "false box"):
        kept, dropped = counts[group, "kept off"], counts[group, "dropped"]
        print(f"{group:<16} {kept:>12} {dropped:>12} {dropped / kept if kept else 0.0:>7.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
