"""Association time per frame: the paper's linear scan vs the hash-grid index.

Graphs of 1k / 10k / 100k nodes (uniform over 100 x 100 m, 10 categories), frames of 20
observations (12 re-detections of nodes in view with 0.1 m noise, 8 new objects). The
expected set is the nodes inside a 60 degree, 8 m field-of-view triangle, cut to the 20
nearest to the camera (a stand-in for the caller's occlusion check). Each method runs the
same frames on its own copy of the graph; paper-mode results are checked to be identical.

Columns: association ms/frame (paper linear scan, paper indexed, robust indexed), the FoV
query ms/frame (scan over all nodes vs index), and the ratios linear / indexed.

Run: .venv/bin/python benchmarks/bench_association.py [--frames 20]
"""

from __future__ import annotations

import argparse
import copy
import math
import time

import numpy as np

from bomc_bt.graph import AssociationParams, Node, ObjectGraph, Observation
from bomc_bt.graph.reference import associate_linear_scan, nodes_in_polygon_linear

CATEGORIES = [f"class{i}" for i in range(10)]


def make_nodes(n: int, rng: np.random.Generator) -> list[Node]:
    xy = rng.uniform(0, 100, (n, 2))
    z = rng.uniform(0, 2, n)
    cats = rng.integers(0, len(CATEGORIES), n)
    return [Node(i, CATEGORIES[c], np.array([x, y, h]), 0.9, 1, 1) for i, ((x, y), h, c) in
            enumerate(zip(xy, z, cats, strict=True))]


def fov(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    cam = rng.uniform(10, 90, 2)
    yaw = rng.uniform(-math.pi, math.pi)
    left, right = yaw + math.pi / 6, yaw - math.pi / 6
    poly = np.array([cam, cam + 8 * np.array([math.cos(left), math.sin(left)]),
                     cam + 8 * np.array([math.cos(right), math.sin(right)])])
    return cam, poly


def make_frames(graph: ObjectGraph, n_frames: int, rng: np.random.Generator):
    frames = []
    for _ in range(n_frames):
        cam, poly = fov(rng)
        in_view = graph.nodes_in_polygon(poly)
        in_view.sort(key=lambda v: float(np.linalg.norm(v.position[:2] - cam)))
        expected = [v.id for v in in_view[:20]]
        seen = [graph.nodes[i] for i in expected[:12]]
        obs = [Observation(v.category, v.position + rng.normal(0, 0.1, 3), 0.8) for v in seen]
        while len(obs) < 20:
            r, a = rng.uniform(1, 8), rng.uniform(-math.pi / 6, math.pi / 6)
            p = np.append(cam + r * np.array([math.cos(a), math.sin(a)]), rng.uniform(0, 2))
            obs.append(Observation(CATEGORIES[int(rng.integers(len(CATEGORIES)))], p, 0.8))
        frames.append((poly, expected, obs))
    return frames


def time_frames(graph: ObjectGraph, frames, fn) -> tuple[float, list]:
    events = []
    t0 = time.perf_counter()
    for k, (_, expected, obs) in enumerate(frames):
        events.append(fn(graph, obs, expected, 2, float(k)))
    return (time.perf_counter() - t0) * 1000 / len(frames), events


def time_fov(graph: ObjectGraph, frames, fn) -> float:
    t0 = time.perf_counter()
    for poly, _, _ in frames:
        fn(graph, poly)
    return (time.perf_counter() - t0) * 1000 / len(frames)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1_000, 10_000, 100_000])
    args = ap.parse_args()
    print(f"{args.frames} frames of 20 observations; ms per frame (lower is better)\n")
    print("| nodes | paper linear | paper indexed | ratio | robust indexed"
          " | FoV linear | FoV indexed | ratio |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in args.sizes:
        rng = np.random.default_rng(n)
        nodes = make_nodes(n, rng)
        base = ObjectGraph(AssociationParams(mode="paper"), nodes)
        frames = make_frames(base, args.frames, rng)
        linear_ms, ev_lin = time_frames(copy.deepcopy(base), frames, associate_linear_scan)
        indexed_ms, ev_idx = time_frames(
            copy.deepcopy(base), frames, lambda g, o, e, s, t: g.associate(o, e, s, t)
        )
        same = [[(e.kind, e.node_id) for e in f] for f in ev_lin] == [[(e.kind, e.node_id) for e in f]
                                                                     for f in ev_idx]
        assert same, "paper mode with the index must give the linear scan's events"
        robust = ObjectGraph(AssociationParams(mode="robust"), copy.deepcopy(nodes))
        robust_ms, _ = time_frames(robust, frames, lambda g, o, e, s, t: g.associate(o, e, s, t))
        fov_lin = time_fov(base, frames, nodes_in_polygon_linear)
        fov_idx = time_fov(base, frames, lambda g, p: g.nodes_in_polygon(p))
        print(f"| {n:,} | {linear_ms:.3f} | {indexed_ms:.3f} | {linear_ms / indexed_ms:.0f}x"
              f" | {robust_ms:.3f} | {fov_lin:.3f} | {fov_idx:.3f} | {fov_lin / fov_idx:.0f}x |")


if __name__ == "__main__":
    main()
