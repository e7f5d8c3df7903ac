"""How well single views place objects: observations of rendered views against the truth.

Renders views of a generated office's objects from random free poses facing each object
(``--end-on``: tables only, from within 26 degrees of their long axis, 2-5 m off), runs the
simulated detector and segmenter (``realistic``: masks bled by 10 %) and the projection, and
prints per category how far the observation's floor box reaches past the object's true
footprint ("past") and how far the observation stands from the object's centre ("off"),
with the range cut alone (``projection.far_part: false``, the baseline) and with the far
part (the default), on the same views. The far part moves the centre only, so "past" is the
same in both: it shows what the range cut leaves in the box.

    python benchmarks/bench_views.py --size 93x90 --seed 9922 --views 2500
    python benchmarks/bench_views.py --size 93x90 --seed 9922 --views 1500 --end-on
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.config import load_config  # noqa: E402
from bomc_bt.geometry import Pose2D  # noqa: E402
from bomc_bt.officegen import OfficeParams, generate_office  # noqa: E402
from bomc_bt.perception.projection import detections_to_observations  # noqa: E402
from bomc_bt.sim.detector import SimDetector  # noqa: E402
from bomc_bt.sim.factory import SimRobots  # noqa: E402

CATEGORIES = ("table", "chair", "cabinet", "trash bin")


def past(box: np.ndarray, o) -> float:
    """How far (m) the floor box reaches beyond the object's axis-aligned footprint."""
    c, s = abs(math.cos(o.yaw)), abs(math.sin(o.yaw))
    ex, ey = c * o.size[0] / 2 + s * o.size[1] / 2, s * o.size[0] / 2 + c * o.size[1] / 2
    x, y = o.position[0], o.position[1]
    return max(x - ex - box[0], box[2] - x - ex, y - ey - box[1], box[3] - y - ey, 0.0)


def views(world: Path, n: int, seed: int, end_on: bool):
    """Yield (object, frame, detections of it) for ``n`` views with a floor box."""
    config = load_config([])
    robots = SimRobots(world, seed=seed)
    robots.prepare(config)
    robot = robots.monitor_robot(config, 1)
    objects = list(robot._objects.values())
    detector = SimDetector(config.detector, seed=seed)
    categories = sorted({o.category for o in objects})
    rng = np.random.default_rng(seed)
    grid, walls = robot.world.grid, robot.world.walls()
    centres = np.array([o.position[:2] for o in objects])
    targets = [o for o in objects if o.category in (("table",) if end_on else CATEGORIES)]
    done = tries = 0
    while done < n and tries < 50 * n:
        tries += 1
        o = targets[rng.integers(len(targets))]
        d, a = rng.uniform(1.2, 4.0), rng.uniform(-math.pi, math.pi)
        if end_on:
            d, a = rng.uniform(2.0, 5.0), o.yaw + rng.integers(2) * math.pi + rng.uniform(-0.45, 0.45)
        x, y = o.position[0] + d * math.cos(a), o.position[1] + d * math.sin(a)
        if grid.value_at(x, y) != 0 or np.min(np.hypot(*(centres - [x, y]).T)) <= 0.6:
            continue
        pose = Pose2D(x, y, math.atan2(o.position[1] - y, o.position[0] - x) + rng.normal(0.0, 0.3))
        frame = robot.camera.render(walls, grid, robot.world.wall_height, objects, list(robot.scene.obstacles), [],
                                    pose, pose, 1000.0 + tries)
        found = detector.segment(frame, detector.detect(frame, categories))
        mine = [det for det in found if detector.source(frame, det) == objects.index(o) + 1]
        if mine:
            done += 1
            yield o, frame, mine, config.projection


def row(name: str, v: np.ndarray) -> str:
    p, off = v[:, 0], v[:, 1]
    return (f"{name:<20} {len(v):>5} {np.mean(p > 0.3):>8.3f} {np.mean(p > 0.6):>8.3f} {np.median(off):>8.2f} "
            f"{np.percentile(off, 90):>8.2f} {np.mean(off > 0.7):>8.3f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="93x90", help="WxH of the generated office, metres")
    ap.add_argument("--seed", type=int, default=9922)
    ap.add_argument("--views", type=int, default=2500)
    ap.add_argument("--end-on", action="store_true", help="tables only, seen along their long axis")
    args = ap.parse_args(argv)
    width, height = (float(v) for v in args.size.lower().split("x"))
    results: dict[tuple[str, str], list[tuple[float, float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        world = Path(tmp) / "office.yaml"
        generate_office(OfficeParams(width=width, height=height, seed=args.seed, sessions=1), world)
        for o, frame, mine, params in views(world, args.views, args.seed, args.end_on):
            for label, far in (("range cut", False), ("far part", True)):
                obs = detections_to_observations(frame, mine, replace(params, far_part=far))
                if obs and obs[0].box is not None:
                    off = float(np.hypot(obs[0].position[0] - o.position[0], obs[0].position[1] - o.position[1]))
                    results.setdefault((o.category, label), []).append((past(obs[0].box, o), off))
    print(f"# office {args.size} seed {args.seed}, {args.views} views{' end-on' if args.end_on else ''}")
    print(f"{'category/mode':<20} {'views':>5} {'past>0.3':>8} {'past>0.6':>8} {'off p50':>8} {'off p90':>8} "
          f"{'off>0.7':>8}")
    for category in CATEGORIES:
        for label in ("range cut", "far part"):
            if (category, label) in results:
                print(row(f"{category} {label}", np.array(results[(category, label)])))
        base, new = results.get((category, "range cut")), results.get((category, "far part"))
        if base and new:
            ratio = np.median(np.array(new)[:, 1]) / max(np.median(np.array(base)[:, 1]), 1e-9)
            print(f"{'  ratio off p50':<20} {'':>5} {'':>8} {'':>8} {ratio:>8.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
