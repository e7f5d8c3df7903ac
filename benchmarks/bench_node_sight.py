"""How often the pass's sight test says a place sees a node that a wall hides, and the reverse.

Reads a site kept by ``bench_passes.py --keep DIR`` (its world ``DIR/office.yaml`` and the
robust site ``DIR/robust``): the site's present nodes, with their footprints, each matched
to the nearest true object of its category within 1 m in the world's last session; the
places are the built map's free cells at the points of a 0.5 m lattice, with 0.45 m of room (where a robot
stops); the pairs are those 0.5-5 m apart. The truth: some point just outside the object's
true box has a line clear of the world's walls (a face the camera can see; furniture is
not counted, the camera looks over most of it). Each rule is scored on both masks the pass
uses: the camera's (unknown cells seen through) and known free cells only.

    python benchmarks/bench_passes.py --size 36x28 --seed 7911 --sessions 12 --churn 0.05 --modes robust --keep K
    python benchmarks/bench_node_sight.py K
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt.grid import load_map  # noqa: E402
from bomc_bt.node_sight import camera_clear, face_points, line_of_sight, sees_node, sees_target  # noqa: E402
from bomc_bt.site_reader import open_graph  # noqa: E402
from bomc_bt.world.loader import load_world  # noqa: E402

TRUTH_OUTSET = 0.075  # m outside the true box: a point of the object's face, off the wall it stands on


def stop_places(grid, step: float = 0.5, room: float = 0.45) -> np.ndarray:
    """(K, 2) free cells with ``room`` of clearance within half a cell of a ``step`` lattice point."""
    free = grid.free_mask()
    clearance = cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution
    rows, cols = np.nonzero(clearance >= room)
    x, y = grid.cell_to_world(rows, cols)
    xy = np.stack([x, y], axis=1)
    on = (np.abs(xy / step - np.round(xy / step)) < 0.5 * grid.resolution / step + 1e-9).all(axis=1)
    return xy[on]


def matched(nodes, objects) -> list:
    """(node, object) pairs: the nearest true object of the node's category within 1 m."""
    pairs = []
    for n in nodes:
        same = [o for o in objects if o.category == n.category]
        d = [np.hypot(o.position[0] - n.position[0], o.position[1] - n.position[1]) for o in same]
        if d and min(d) < 1.0:
            pairs.append((n, same[int(np.argmin(d))]))
    return pairs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kept", help="directory kept by bench_passes.py --keep")
    ap.add_argument("--range", type=float, default=5.0, help="farthest pair, m (projection.expect_range)")
    args = ap.parse_args()
    kept = Path(args.kept)
    world = load_world(kept / "office.yaml")
    grid = load_map(kept / "robust" / "map.yaml")
    store = open_graph(kept / "robust")
    last = store.sessions()[-1].number
    pairs = matched(store.nodes(), list(world.objects_in_session(last).values()))
    walls_clear = ~world.walls()
    masks = {"camera": camera_clear(grid), "free": grid.free_mask()}
    rules = {"centre, 0.5 m short": lambda m, a, n: sees_node(grid, m, a, (n.position[0], n.position[1])),
             "faces of the footprint": lambda m, a, n: sees_target(grid, m, a, n.position, n.footprint)}
    places = stop_places(grid)
    counts: dict[tuple[str, str], Counter] = {(r, m): Counter() for r in rules for m in masks}
    doors: dict[tuple[str, str], int] = Counter()
    for node, obj in pairs:
        corners = obj.footprint()
        box = (*corners.min(axis=0), *corners.max(axis=0))
        faces = face_points(box, -TRUTH_OUTSET)
        d = np.hypot(places[:, 0] - node.position[0], places[:, 1] - node.position[1])
        for k in np.nonzero((d >= 0.5) & (d <= args.range))[0]:
            a = (float(places[k, 0]), float(places[k, 1]))
            real = any(line_of_sight(grid, walls_clear, a, (float(x), float(y))) for x, y in faces)
            for (rule, mask), c in counts.items():
                says = rules[rule](masks[mask], a, node)
                c["in sight, truly"] += says and real
                c["in sight, walled off"] += says and not real
                c["out of sight, face in view"] += (not says) and real
                doors[rule, mask] += says and not real and node.category == "door"
    print(f"# {kept}: {len(pairs)} nodes matched, {len(places)} places, after session {last}")
    print("| rule | mask | in sight, truly | in sight, walled off (share; doors) | out of sight, a face in view |")
    print("| --- | --- | --- | --- | --- |")
    for (rule, mask), c in counts.items():
        said = c["in sight, truly"] + c["in sight, walled off"]
        walled = c["in sight, walled off"]
        print(f"| {rule} | {mask} | {c['in sight, truly']:,} | {walled:,} ({walled / max(said, 1):.1%}; "
              f"{doors[rule, mask]:,}) | {c['out of sight, face in view']:,} |")


if __name__ == "__main__":
    main()
