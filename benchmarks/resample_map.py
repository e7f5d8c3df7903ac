"""A map_server map at another resolution: the same building as another robot's SLAM would draw it.

The project is judged on real maps of other buildings at other resolutions. This writes a
copy of a map (YAML + PGM, trinary) with cells ``--resolution`` metres wide: coarser cells take
the most occupied of the cells they cover (occupied over unknown over free, so no wall
opens), finer cells repeat the cell they lie in.

    python benchmarks/resample_map.py ../shared/maps/bookstore.yaml --resolution 0.025 --out /tmp/bookstore025.yaml
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bomc_bt.errors import BomcError  # noqa: E402
from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, load_map, save_map  # noqa: E402

RANK = {FREE: 0, UNKNOWN: 1, OCCUPIED: 2}  # which cell wins when several become one


def resample(grid: OccupancyGrid, resolution: float) -> OccupancyGrid:
    """``grid`` with cells ``resolution`` metres wide, the same origin and extent (see the module docstring)."""
    trinary = np.where(grid.data >= 65, OCCUPIED, np.where(grid.data == FREE, FREE, UNKNOWN)).astype(np.int8)
    h = max(int(round(grid.height * grid.resolution / resolution)), 1)
    w = max(int(round(grid.width * grid.resolution / resolution)), 1)
    # every source cell goes to the target cell its centre lies in; a target cell no source
    # centre falls in (a finer grid) takes the source cell under its own centre
    rows = np.minimum(((np.arange(grid.height) + 0.5) * grid.resolution / resolution).astype(int), h - 1)
    cols = np.minimum(((np.arange(grid.width) + 0.5) * grid.resolution / resolution).astype(int), w - 1)
    rank = np.vectorize(RANK.get)(trinary)
    best = np.full((h, w), -1, dtype=np.int8)
    np.maximum.at(best, (rows[:, None], cols[None, :]), rank.astype(np.int8))
    centre_r = np.minimum(((np.arange(h) + 0.5) * resolution / grid.resolution).astype(int), grid.height - 1)
    centre_c = np.minimum(((np.arange(w) + 0.5) * resolution / grid.resolution).astype(int), grid.width - 1)
    under = rank[centre_r[:, None], centre_c[None, :]]
    best = np.where(best < 0, under, best)
    data = np.select([best == 2, best == 0], [OCCUPIED, FREE], UNKNOWN).astype(np.int8)
    return OccupancyGrid(data, resolution, grid.origin)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Write a map_server map at another resolution.")
    ap.add_argument("map", type=Path, help="the map's YAML")
    ap.add_argument("--resolution", type=float, required=True, help="metres per cell of the copy (0.01 to 1)")
    ap.add_argument("--out", type=Path, required=True, help="the copy's YAML (its PGM is written beside it)")
    args = ap.parse_args(argv)
    if not 0.01 <= args.resolution <= 1.0:
        print(f"--resolution: must be 0.01 to 1 m, got {args.resolution:g}", file=sys.stderr)
        return 2
    try:
        grid = load_map(args.map)
    except BomcError as e:
        print(e, file=sys.stderr)
        return 2
    out = resample(grid, args.resolution)
    save_map(out, args.out)
    print(f"{args.out}: {out.width} x {out.height} cells of {out.resolution:g} m (from {grid.width} x {grid.height} "
          f"of {grid.resolution:g} m)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
