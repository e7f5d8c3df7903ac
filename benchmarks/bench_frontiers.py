"""Frontier search speed on a building-sized map: vectorised vs breadth-first reference.

The grid is the size of the paper's Environment A (93 x 90 m at 0.05 m = 1860 x 1800
cells), made by tiling a real SLAM map (the AWS hospital map) at its native resolution so
corridor widths and wall thicknesses stay realistic. A partially explored state is
simulated by keeping only cells within a radius of a start point known and making the
rest unknown; several radii show how both versions scale with the explored area.

Run:  .venv/bin/python benchmarks/bench_frontiers.py [--map PATH] [--runs N] [--ref-runs N]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from shared_folder import SHARED

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.exploration.frontiers import find_frontiers, find_frontiers_reference  # noqa: E402
from bomc_bt.grid import FREE, UNKNOWN, OccupancyGrid, load_map  # noqa: E402

HEIGHT, WIDTH = 1800, 1860  # 90 m x 93 m at 0.05 m
MIN_SIZE = 10  # explore_lite's default min_frontier_size 0.5 m at 0.05 m


def building_grid(map_path: Path) -> OccupancyGrid:
    """Tile a real map (cropped) to HEIGHT x WIDTH cells at its own resolution."""
    source = load_map(map_path)
    reps = (-(-HEIGHT // source.height), -(-WIDTH // source.width))
    data = np.tile(source.data, reps)[:HEIGHT, :WIDTH].copy()
    return OccupancyGrid(data, source.resolution, (0.0, 0.0))


def start_point(grid: OccupancyGrid) -> tuple[float, float]:
    """The free cell nearest the grid centre (a neutral, map-independent choice)."""
    free = np.argwhere(grid.data == FREE)
    centre = np.array([grid.height / 2, grid.width / 2])
    r, c = free[np.argmin(((free - centre) ** 2).sum(axis=1))]
    x, y = grid.cell_to_world(r, c)
    return float(x), float(y)


def partially_explored(grid: OccupancyGrid, start: tuple[float, float], radius: float) -> OccupancyGrid:
    """Only cells within ``radius`` metres of ``start`` are known."""
    rows, cols = np.mgrid[0:grid.height, 0:grid.width]
    x, y = grid.cell_to_world(rows, cols)
    out = grid.copy()
    out.data[(x - start[0]) ** 2 + (y - start[1]) ** 2 > radius**2] = UNKNOWN
    return out


def median_ms(fn, runs: int) -> tuple[float, object]:
    times, result = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    shared = SHARED
    parser.add_argument("--map", type=Path, default=shared / "maps" / "hospital.yaml")
    parser.add_argument("--runs", type=int, default=21, help="timed runs of the fast version")
    parser.add_argument("--ref-runs", type=int, default=3, help="timed runs of the reference")
    parser.add_argument("--radii", type=float, nargs="+", default=[10.0, 25.0, 45.0],
                        help="known radius around the start, metres (1000 = whole map known)")
    args = parser.parse_args()

    base = building_grid(args.map)
    start = start_point(base)
    print(f"map {args.map.name} tiled to {base.width} x {base.height} cells "
          f"({base.width * base.resolution:.0f} x {base.height * base.resolution:.0f} m at "
          f"{base.resolution} m), start {start[0]:.2f}, {start[1]:.2f} m, min_size {MIN_SIZE} cells")
    header = (f"{'grid (W x H)':>13} {'known r m':>9} {'known %':>7} {'fast ms':>8} {'ref ms':>9} "
              f"{'speed-up':>8} {'frontiers':>9} {'agree':>5}")
    print(header)
    print("-" * len(header))
    for radius in args.radii:
        grid = partially_explored(base, start, radius)
        known = 100.0 * np.count_nonzero(grid.data != UNKNOWN) / grid.data.size
        fast_ms, fast = median_ms(lambda g=grid: find_frontiers(g, start, MIN_SIZE), args.runs)
        ref_ms, ref = median_ms(lambda g=grid: find_frontiers_reference(g, start, MIN_SIZE), args.ref_runs)
        agree = len(fast) == len(ref) and all(
            a.size == b.size and np.array_equal(a.cells, b.cells) for a, b in zip(fast, ref, strict=True))
        print(f"{f'{grid.width} x {grid.height}':>13} {radius:>9g} {known:>7.1f} {fast_ms:>8.1f} "
              f"{ref_ms:>9.0f} {ref_ms / fast_ms:>7.0f}x {len(fast):>9d} {'yes' if agree else 'NO':>5}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
