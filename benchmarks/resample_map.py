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
from bomc_bt.yaml_io import read_yaml  # noqa: E402


def resample(grid: OccupancyGrid, resolution: float) -> OccupancyGrid:
    """``grid`` with cells ``resolution`` metres wide, the same origin and extent (see the module docstring)."""
    rank = np.where(grid.occupied_mask(), 2, np.where(grid.free_mask(), 0, 1)).astype(np.int8)  # what wins
    h = max(int(round(grid.height * grid.resolution / resolution)), 1)
    w = max(int(round(grid.width * grid.resolution / resolution)), 1)
    # every source cell goes to the target cell its centre lies in; a target cell no source
    # centre falls in (a finer grid) takes the source cell under its own centre
    rows = np.minimum(((np.arange(grid.height) + 0.5) * grid.resolution / resolution).astype(int), h - 1)
    cols = np.minimum(((np.arange(grid.width) + 0.5) * grid.resolution / resolution).astype(int), w - 1)
    best = np.full((h, w), -1, dtype=np.int8)
    np.maximum.at(best, (rows[:, None], cols[None, :]), rank)
    centre_r = np.minimum(((np.arange(h) + 0.5) * resolution / grid.resolution).astype(int), grid.height - 1)
    centre_c = np.minimum(((np.arange(w) + 0.5) * resolution / grid.resolution).astype(int), grid.width - 1)
    best = np.where(best < 0, rank[centre_r[:, None], centre_c[None, :]], best)
    data = np.select([best == 2, best == 0], [OCCUPIED, FREE], UNKNOWN).astype(np.int8)
    return OccupancyGrid(data, resolution, grid.origin)


def _refusal(source: Path, out: Path, force: bool) -> str | None:
    """Why writing ``out`` (and the PGM beside it) must not go ahead, or None: never over the
    source map or its image, and over an existing file only with ``--force``."""
    written = {out.resolve(), out.with_suffix(".pgm").resolve()}
    image = read_yaml(source, "map file").get("image", "")
    if source.resolve() in written or (source.parent / str(image)).resolve() in written:
        return f"{out}: would overwrite the source map {source}"
    existing = [p for p in (out, out.with_suffix(".pgm")) if p.exists()]
    if existing and not force:
        return f"{existing[0]}: exists (--force replaces it)"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Write a map_server map at another resolution.")
    ap.add_argument("map", type=Path, help="the map's YAML")
    ap.add_argument("--resolution", type=float, required=True, help="metres per cell of the copy (0.01 to 1)")
    ap.add_argument("--out", type=Path, required=True, help="the copy's YAML (its PGM is written beside it)")
    ap.add_argument("--force", action="store_true", help="replace an existing copy")
    args = ap.parse_args(argv)
    if not 0.01 <= args.resolution <= 1.0:
        print(f"--resolution: must be 0.01 to 1 m, got {args.resolution:g}", file=sys.stderr)
        return 2
    try:
        grid = load_map(args.map)
    except BomcError as e:
        print(e, file=sys.stderr)
        return 2
    refusal = _refusal(args.map, args.out, args.force)
    if refusal is not None:
        print(refusal, file=sys.stderr)
        return 2
    out = resample(grid, args.resolution)
    save_map(out, args.out)
    print(f"{args.out}: {out.width} x {out.height} cells of {out.resolution:g} m (from {grid.width} x {grid.height} "
          f"of {grid.resolution:g} m)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
