"""How far change F1 can go when objects look alike: the best a map keyed by position could
report, from the world files alone.

A chair carried to another room and a chair taken away while another was brought in look
the same to any detector that labels "chair": the robot sees one chair gone and one chair
new. ``bomc evaluate`` scores the first as one ``moved`` and the second as one ``removed``
plus one ``added`` (CONTRACTS; `bomc_bt/change_evaluation.py`), so part of the change F1 is
out of reach of perception, however perfect. This benchmark measures that part on
generated worlds (``bomc world office``, seeds given on the command line), scoring with the
project's own change evaluation an *ideal reporter*: every object seen, every position
exact, every removal and addition found, and identity kept where position can keep it:

* a move within ``association.move_radius`` keeps its id (the pass's own move rule);
* a farther move is a removal at the old place plus an addition at the new one;
* then, with ``relocation_radius`` > 0, removals and additions are paired as when a pass
  ends (:func:`bomc_bt.graph.relocations.relocation_pairs`: one category, each the other's
  nearest within the radius).

It prints, per floor, the mean and lowest per-session change F1 and the summed tp / fp /
fn for each pairing radius, and the shares of true moves farther than ``move_radius``:
    python benchmarks/bench_change_ceiling.py --office 36x28:201:12 --office 93x90:301:3
``--per-session`` adds each session's ceiling at the configured radius, to set beside the
change F1 per pass that ``bench_passes.py`` prints for the same world. ``--world`` takes any
world file instead, e.g. a furnished real map that ``bench_passes.py --map M --keep DIR``
left in ``DIR/world.yaml``:
    python benchmarks/bench_change_ceiling.py --world DIR/world.yaml --per-session
The radii compared default to 0 (no pairing), 3, 5, 8, 12 m and unbounded.

``--looks`` gives the ideal reporter eyes for colour too (worlds whose objects have a
``colour``, as both generators write them): a removal and an addition whose looks differ are
neither a pair by position nor each other's nearest, and the removals and additions left
are paired by look as a pass does when it ends
(:func:`bomc_bt.graph.looks.look_pairs`, ``association.colour_tolerance``):
    python benchmarks/bench_change_ceiling.py --office 36x28:7503:12 --radius 5 --looks --per-session
An addition within ``association.return_radius`` of where an object of its kind and look went
in an earlier session (and stayed gone) is that object brought back, never paired
(:mod:`bomc_bt.graph.brought_back`); ``--return-radius 0`` leaves that out.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from bomc_bt.change_evaluation import ObjectChange, score_changes, true_changes
from bomc_bt.config import load_config
from bomc_bt.graph import Node, ObjectGraph
from bomc_bt.graph.brought_back import brought_back
from bomc_bt.graph.looks import look_pairs, looks_apart
from bomc_bt.graph.relocations import relocation_pairs
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.world import load_world


def ideal_report(truth: list[ObjectChange], move_radius: float, radius: float,
                 looks: dict[str, np.ndarray] | None = None, tolerance: float = 0.0,
                 population: list[Node] = (), gone: list[Node] = (), return_radius: float = 0.0
                 ) -> list[ObjectChange]:
    """What a perfect robot that tells objects apart only by position would report (with
    ``looks``, each object's chromaticity by name: also by how they look, as a pass ends;
    ``gone``: objects earlier sessions took away, as nodes, for the returns)."""
    out = [c for c in truth if c.kind != "moved" or float(np.hypot(*(c.new - c.old)[:2])) <= move_radius]
    far = [c for c in truth if c.kind == "moved" and c not in out]
    removed = [c for c in out if c.kind == "removed"] + [ObjectChange("removed", c.key, c.category, c.old, None)
                                                        for c in far]
    added = [c for c in out if c.kind == "added"] + [ObjectChange("added", c.key, c.category, None, c.new)
                                                    for c in far]
    out = [c for c in out if c.kind == "moved"]
    as_node = {id(c): Node(k, c.category, c.old if c.old is not None else c.new, 1.0, 1, 1,
                           colour=(looks or {}).get(str(c.key))) for k, c in enumerate(removed + added)}
    olds, news = [as_node[id(c)] for c in removed], [as_node[id(c)] for c in added]
    back = {n.id for n, _ in brought_back(news, gone, return_radius, tolerance)}
    news = [n for n in news if n.id not in back]
    pairs = relocation_pairs(olds, news, radius, lambda a, b: looks_apart(a, b, tolerance))
    paired = {n.id for pair in pairs for n in pair}
    pairs += look_pairs([n for n in olds if n.id not in paired], [n for n in news if n.id not in paired], tolerance,
                        population)
    paired = {n.id for pair in pairs for n in pair}
    by_id = {as_node[id(c)].id: c for c in removed + added}
    out += [ObjectChange("moved", 0, a.category, by_id[a.id].old, by_id[b.id].new) for a, b in pairs]
    out += [c for c in removed + added if as_node[id(c)].id not in paired]
    return [ObjectChange(c.kind, k, c.category, c.old, c.new) for k, c in enumerate(out)]  # keyed like nodes


def world_looks(world) -> dict[str, np.ndarray]:
    """Each object's chromaticity, by name, as a camera would measure its colour (those with one)."""
    out = {}
    for n in range(1, max(world.sessions, default=1) + 1):
        for state in (world.objects_in_session(n), world.ground_truth(n)):
            for name, o in state.items():
                if o.colour is not None and sum(o.colour) > 0:
                    out[name] = np.asarray(o.colour[:2], dtype=float) / float(sum(o.colour))
    return out


def _population(state: dict, looks: dict[str, np.ndarray]) -> list[Node]:
    """The objects standing when the previous pass ended, as nodes with their looks (ids
    clear of the report's): what the map holds to judge how common a look is."""
    return [Node(-1 - k, category, position, 1.0, 1, 1, colour=looks.get(name))
            for k, (name, (category, position)) in enumerate(sorted(state.items()))]


def _gone(states: list[dict], k: int, looks: dict[str, np.ndarray] | None) -> list[Node]:
    """The objects standing at the end of some session before ``k - 1`` and not at its end,
    where they last stood (ids clear of the report's): what a perfect robot saw go."""
    last: dict = {}
    for state in states[:k - 2]:
        last.update(state)
    return [Node(-100_000 - j, category, position, 1.0, 1, 1, colour=(looks or {}).get(name))
            for j, (name, (category, position)) in enumerate(sorted(last.items())) if name not in states[k - 2]]


def floor_rows(world_path: Path, radii: list[float], config, use_looks: bool = False
               ) -> tuple[int, int, int, int, list[tuple]]:
    """(session pairs, true changes, true moves, moves beyond move_radius, one row per radius)."""
    world = load_world(world_path)
    looks = world_looks(world) if use_looks else None
    threshold = ObjectGraph(config.association).threshold
    move_radius = config.association.move_radius
    states = []
    for n in range(1, max(world.sessions, default=1) + 1):
        present = world.ground_truth(n)
        states.append({name: (o.category, np.asarray(o.position, dtype=float)) for name, o in present.items()})
    truths = [true_changes(a, b, threshold) for a, b in zip(states[:-1], states[1:], strict=True)]
    moves = [c for t in truths for c in t if c.kind == "moved"]
    far = sum(float(np.hypot(*(c.new - c.old)[:2])) > move_radius for c in moves)
    rows = []
    for radius in radii:
        f1s, totals = session_f1s(truths, move_radius, radius, threshold, looks, config.association.colour_tolerance,
                                  states, config.association.return_radius)
        rows.append((radius, float(np.mean(f1s)), float(np.min(f1s)), *totals.tolist()))
    return len(truths), sum(len(t) for t in truths), len(moves), far, rows


def session_f1s(truths: list[list[ObjectChange]], move_radius: float, radius: float, threshold,
                looks: dict[str, np.ndarray] | None = None, tolerance: float = 0.0, states: list[dict] = (),
                return_radius: float = 0.0) -> tuple[list[float], np.ndarray]:
    """The ideal reporter's change F1 per session (from session 2 on) and the summed tp / fp / fn."""
    f1s, totals = [], np.zeros(3, dtype=int)
    for k, truth in enumerate(truths, start=2):
        population = _population(states[k - 2], looks) if looks is not None else []
        gone = _gone(states, k, looks) if return_radius > 0 else []
        report = ideal_report(truth, move_radius, radius, looks, tolerance, population, gone, return_radius)
        o = score_changes(truth, report, threshold, k, k - 1).overall
        f1s.append(o.f1 if o.f1 is not None else 1.0)
        totals += (o.tp, o.mapped - o.tp, o.gt - o.tp)
    return f1s, totals


def per_session_line(world_path: Path, config, use_looks: bool = False) -> str:
    """The ceiling per session at the configured ``relocation_radius``: what a pass's change
    F1 in ``bench_passes.py`` (same world, same session) compares with."""
    world = load_world(world_path)
    threshold = ObjectGraph(config.association).threshold
    states = [{name: (o.category, np.asarray(o.position, dtype=float)) for name, o in world.ground_truth(n).items()}
              for n in range(1, max(world.sessions, default=1) + 1)]
    truths = [true_changes(a, b, threshold) for a, b in zip(states[:-1], states[1:], strict=True)]
    a = config.association
    looks = world_looks(world) if use_looks else None
    f1s, _ = session_f1s(truths, a.move_radius, a.relocation_radius, threshold, looks, a.colour_tolerance, states,
                         a.return_radius)
    return "  per session: " + " ".join(f"{k}:{f:.3f}" for k, f in enumerate(f1s, start=2))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--office", action="append", default=[], metavar="WxH:SEED:SESSIONS",
                   help="a generated office (default: 36x28:201:12 and 93x90:301:3)")
    p.add_argument("--world", action="append", default=[], metavar="WORLD.yaml", help="an existing world file")
    p.add_argument("--radius", action="append", type=float, help="pairing radius, m (repeatable; inf: unbounded)")
    p.add_argument("--per-session", action="store_true",
                   help="also print each session's ceiling at the configured relocation_radius")
    p.add_argument("--looks", action="store_true",
                   help="the ideal reporter also tells objects apart by colour (worlds whose objects have one; "
                        "association.colour_tolerance)")
    p.add_argument("--return-radius", type=float, metavar="M",
                   help="association.return_radius for the returns (default: the configured one; 0: off)")
    args = p.parse_args(argv)
    offices = args.office or ([] if args.world else ["36x28:201:12", "93x90:301:3"])
    radii = args.radius or [0.0, 3.0, 5.0, 8.0, 12.0, float("inf")]
    config = load_config()
    if args.return_radius is not None:
        config.association.return_radius = args.return_radius
    print(f"# ideal reporter: move_radius {config.association.move_radius} m, configured relocation_radius "
          f"{config.association.relocation_radius} m, return_radius {config.association.return_radius} m"
          + (f", by look too (colour_tolerance {config.association.colour_tolerance})" if args.looks else ""))
    print(f"{'floor':16} {'sessions':>8} {'changes':>7} {'moves':>5} {'far':>4} {'radius m':>8} "
          f"{'mean F1':>7} {'min F1':>6} {'tp':>4} {'fp':>4} {'fn':>4}")
    with tempfile.TemporaryDirectory() as tmp:
        floors = [(str(w), Path(w)) for w in args.world]
        for spec in offices:
            size, seed, sessions = spec.split(":")
            width, height = (float(v) for v in size.lower().split("x"))
            path = Path(tmp) / f"office-{seed}.yaml"
            generate_office(OfficeParams(width=width, height=height, seed=int(seed), sessions=int(sessions)), path)
            floors.append((f"{size} s{seed}", path))
        for name, path in floors:
            n_steps, n_changes, n_moves, n_far, rows = floor_rows(path, radii, config, args.looks)
            for radius, mean, low, tp, fp, fn in rows:
                print(f"{name:16} {n_steps:>8} {n_changes:>7} {n_moves:>5} {n_far:>4} "
                      f"{radius:>8.1f} {mean:>7.3f} {low:>6.3f} {tp:>4} {fp:>4} {fn:>4}", flush=True)
            if args.per_session:
                print(per_session_line(path, config, args.looks), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
