"""``bomc world office``: command-line values to :class:`OfficeParams`, and a one-line summary.

Bad values are one :class:`BomcError` naming the option (``--size``, ``--churn``, ...),
so the command exits 2 with one line and no traceback.
"""

from __future__ import annotations

import re
import time
from argparse import Namespace
from collections import Counter

from bomc_bt.errors import BomcError
from bomc_bt.officegen.generate import draft_office, write_office
from bomc_bt.officegen.params import OfficeParams, walls_at

_OPTION = {"width": "--size", "height": "--size", "seed": "--seed", "sessions": "--sessions",
           "churn": "--churn", "resolution": "--resolution", "corridor_chair_every": "--corridor-chairs",
           "hot_rooms": "--hot-rooms"}
_SIZE = re.compile(r"\s*([0-9]+(?:\.[0-9]*)?)\s*[xX]\s*([0-9]+(?:\.[0-9]*)?)\s*")


def params_from_args(args: Namespace) -> OfficeParams:
    """Checked parameters from parsed ``bomc world office`` options."""
    m = _SIZE.fullmatch(args.size)
    if not m:
        raise BomcError(f"expected WxH in metres (e.g. 93x90), got {args.size!r}", None, "--size")
    if args.static and getattr(args, "corridor_chairs", 0):
        raise BomcError("a static world has no changes: give --static or --corridor-chairs, not both", None,
                        "--corridor-chairs")
    if args.static and args.churn is not None:
        raise BomcError("a static world has no churn: give --static or --churn, not both", None, "--churn")
    params = OfficeParams(width=float(m.group(1)), height=float(m.group(2)), resolution=args.resolution,
                          seed=args.seed, sessions=args.sessions, static=args.static,
                          churn=0.05 if args.churn is None else args.churn,
                          corridor_chair_every=getattr(args, "corridor_chairs", 0),
                          hot_rooms=getattr(args, "hot_rooms", 0.0), **walls_at(args.resolution))
    try:
        return params.check()
    except BomcError as exc:
        raise BomcError(exc.message, None, _OPTION.get(exc.field or "", exc.field)) from None


def generate_from_args(args: Namespace) -> str:
    """Generate and write the world; the summary line the command prints."""
    t0 = time.perf_counter()
    draft = draft_office(params_from_args(args))
    world = write_office(draft, args.out, force=args.force)
    counts = Counter(o.category for o in world.objects.values())
    mix = ", ".join(f"{n} {c}" for c, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))
    changes = sum(len(c.remove) + len(c.move) + len(c.add) for c in world.sessions.values()) + len(world.during)
    p = draft.params
    return (f"office {p.width:g} x {p.height:g} m: {len(draft.plan.corridors)} corridors, "
            f"{len(draft.plan.rooms)} rooms; {len(world.objects)} objects ({mix}); "
            f"{p.sessions} sessions, {changes} object changes, {len(draft.timeline.blocked)} corridor closures; "
            f"wrote {world.path} and {world.map_path} in {time.perf_counter() - t0:.1f} s")
