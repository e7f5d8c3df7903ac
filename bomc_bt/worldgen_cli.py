"""``bomc world map``: a world of many sessions over an occupancy map the user already has.

The office generator draws its own floor; operators and researchers also have real maps
(a SLAM map of their building, at its own resolution). This command furnishes one with
labelled boxes and sessions of changes (:func:`bomc_bt.worldgen.generate_world`, the
churn recipe), so the same long-horizon benchmarks run on it. Bad values are one
:class:`BomcError` naming the option, exit 2, and nothing is written.
"""

from __future__ import annotations

import os
import tempfile
import time
from argparse import Namespace
from collections import Counter
from pathlib import Path

from bomc_bt.errors import BomcError
from bomc_bt.grid import load_map
from bomc_bt.worldgen import generate_world, reachable_free

DEFAULT_CATEGORIES = "chair,table,trash bin,cabinet"
FLOOR_PER_OBJECT = 20.0  # m^2 of reachable floor per object when --objects is not given (Environment A: 20)
MAX_OBJECTS = 5000


def add_parser(kinds, parser_class) -> None:
    """The ``map`` kind under ``bomc world``."""
    m = kinds.add_parser("map", help="objects and sessions of changes over an existing occupancy map")
    m.add_argument("--map", required=True, help="map_server map YAML (its image beside it)")
    m.add_argument("--out", required=True, help="world file to write (NAME.yaml)")
    m.add_argument("--seed", type=int, default=0)
    m.add_argument("--objects", type=int, default=None,
                   help=f"how many objects (default one per {FLOOR_PER_OBJECT:g} m^2 of reachable floor)")
    m.add_argument("--categories", default=DEFAULT_CATEGORIES, help=f"comma-separated (default {DEFAULT_CATEGORIES})")
    m.add_argument("--sessions", type=int, default=3)
    m.add_argument("--churn", type=float, default=None,
                   help="share of the objects changed before each session (default 0.05)")
    m.add_argument("--static", action="store_true", help="nothing ever changes (all sessions identical)")
    m.add_argument("--force", action="store_true", help="replace an existing world file")


def _check(args: Namespace) -> tuple[list[str], float]:
    if args.static and args.churn is not None:
        raise BomcError("a static world has no churn: give --static or --churn, not both", None, "--churn")
    churn = 0.0 if args.static else (0.05 if args.churn is None else args.churn)
    if not 0.0 <= churn <= 0.5:
        raise BomcError(f"must be 0 to 0.5, got {churn!r}", None, "--churn")
    if not 1 <= args.sessions <= 100:
        raise BomcError(f"must be 1 to 100, got {args.sessions}", None, "--sessions")
    if not 0 <= args.seed < 2**32:
        raise BomcError(f"must be 0 to 2**32-1, got {args.seed}", None, "--seed")
    if args.objects is not None and not 1 <= args.objects <= MAX_OBJECTS:
        raise BomcError(f"must be 1 to {MAX_OBJECTS}, got {args.objects}", None, "--objects")
    categories = [c.strip() for c in args.categories.split(",") if c.strip()]
    if not categories:
        raise BomcError("give at least one category", None, "--categories")
    return categories, churn


def generate_from_args(args: Namespace) -> str:
    """Generate and write the world; the summary line the command prints."""
    t0 = time.perf_counter()
    categories, churn = _check(args)
    out = Path(args.out)
    if out.exists() and not args.force:
        raise BomcError("already exists (use --force to replace it)", out)
    grid = load_map(args.map)  # a BomcError naming the map file when it is not one
    floor = float(reachable_free(grid).sum()) * grid.resolution ** 2
    n = args.objects or max(1, int(round(floor / FLOOR_PER_OBJECT)))
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.stem}.", suffix=".yaml")
        os.close(fd)
    except OSError as exc:
        raise BomcError(f"cannot write the world ({exc.strerror or type(exc).__name__})", out) from None
    try:
        world = generate_world(args.map, args.seed, n, categories, tmp, sessions=args.sessions, churn=churn,
                               name=out.stem)
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    counts = Counter(o.category for o in world.objects.values())
    mix = ", ".join(f"{k} {c}" for c, k in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))
    changes = sum(len(c.remove) + len(c.move) + len(c.add) for c in world.sessions.values()) + len(world.during)
    return (f"map {Path(args.map).name} ({grid.resolution:g} m cells, {floor:.0f} m^2 reachable): {n} objects "
            f"({mix}); {args.sessions} sessions, {changes} object changes; wrote {out} in "
            f"{time.perf_counter() - t0:.1f} s")
