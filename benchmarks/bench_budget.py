"""Passes with a budget: does looking first where things change find more of them?

A generated office with hot rooms (``--hot-rooms``: most changes happen in a few rooms,
the rest change rarely) is built once, mapped by one full pass (session 1) and given
``--history`` more full passes (the site's history the change model learns from; 0: the
model starts uniform and learns only from the arm's own passes). Then each arm runs
``--passes`` more passes on its own copy of that site:

* ``full``: the full pass (the default, no budget);
* for each budget (a share of the full pass's robot time, measured in this run):
  ``expected_changes`` (the change model's orienteering tour, ``bomc monitor --budget``),
  ``uniform`` (the same tour with every region alike: most floor per second) and ``cut``
  (the paper's plan, ``traversal.plan: paper``, in its order, cut when the budget is spent).

The budgets are shares of what a full pass of the site takes (the median of its last
three full passes, as ``bomc monitor --budget`` reckons it); a budget that covers it runs
a full pass (budget_pass.py) whatever the strategy, which the first strategy's 100 % arm
checks by running.

Per arm it prints: the share of the true changes (objects removed, moved, added between
two sessions, by name in the world file) that the pass right after them found (an
added / removed / moved event of the same category within ``--radius`` of where the
change happened), the true changes a pass noticed first whatever their age (a change
waiting since an earlier pass counts: what the budgeted plan maximises), the mean passes
until a change was noticed (0: by the next pass; one
never noticed counts as the passes left, and is listed apart), object F1 (``bomc
evaluate``) averaged over the passes, and the robot time used against the budget; the
ratio columns compare with the cut paper plan at the same budget, measured in this run.

    python benchmarks/bench_budget.py                      # 36x28, 3 + 12 passes, budgets 25/50/100 %
    python benchmarks/bench_budget.py --size 50x45 --passes 6 --budgets 25
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bomc_bt import run  # noqa: E402
from bomc_bt.budget_pass import last_full_pass_seconds  # noqa: E402
from bomc_bt.cli import main as bomc  # noqa: E402
from bomc_bt.evaluate_site import evaluate_session  # noqa: E402
from bomc_bt.store import SiteStore  # noqa: E402
from bomc_bt.world import load_world  # noqa: E402

CHANGE_KINDS = ("added", "removed", "moved")


@dataclass
class TrueChange:
    session: int
    category: str
    places: list[tuple[float, float]]  # where a pass can see it happened
    noticed: int | None = None  # the session whose pass found it


@dataclass
class Arm:
    name: str
    strategy: str | None  # None: full pass
    share: float  # of the full pass's robot time (1.0 for full)
    times: list[float] = field(default_factory=list)
    f1: list[float] = field(default_factory=list)
    changes: list[TrueChange] = field(default_factory=list)
    wall: float = 0.0


def true_changes(world, sessions: range) -> list[TrueChange]:
    """Changes between consecutive sessions, by object name (during-pass changes left out)."""
    out = []
    for s in sessions:
        before, after = world.objects_in_session(s - 1), world.objects_in_session(s)
        for name, o in before.items():
            if name not in after:
                out.append(TrueChange(s, o.category, [o.position[:2]]))
            elif math.dist(o.position[:2], after[name].position[:2]) > 0.5:
                out.append(TrueChange(s, o.category, [o.position[:2], after[name].position[:2]]))
        out += [TrueChange(s, o.category, [o.position[:2]]) for name, o in after.items() if name not in before]
    return out


def mark_noticed(changes: list[TrueChange], site: Path, session: int, radius: float) -> None:
    with SiteStore(site, readonly=True) as store:
        events = [e for e in store.events(session=session) if e.kind in CHANGE_KINDS]
    for c in changes:
        if c.noticed is not None or c.session > session:
            continue
        for e in events:
            spots = [e.position[:2]] + ([e.previous[:2]] if e.previous is not None else [])
            if e.category == c.category and any(math.dist(p, q) <= radius for p in spots for q in c.places):
                c.noticed = session
                break


def run_arm(arm: Arm, world_path: Path, base: Path, root: Path, full_s: float, last: int, args) -> None:
    site = root / arm.name
    shutil.copytree(base, site)
    world = load_world(world_path)
    first = args.history + 2
    arm.changes = true_changes(world, range(first, last + 1))
    t0 = time.perf_counter()
    for s in range(first, last + 1):
        config = run.build_config([])
        if arm.strategy is not None:
            config.budget.seconds = round(arm.share * full_s, 1)
            config.budget.strategy = arm.strategy
            if arm.strategy == "cut":
                config.traversal.plan = "paper"
        result = run.run_monitor(world_path, site, s, seed=args.seed, config=config)
        arm.times.append(result.sim_time)
        mark_noticed(arm.changes, site, s, args.radius)
        f1 = evaluate_session(world_path, site, s, config).overall.f1
        arm.f1.append(f1 if f1 is not None else 0.0)
        print(f"  {arm.name} session {s}: {result.sim_time:.0f} s robot time, F1 {arm.f1[-1]:.3f}, "
              f"{time.perf_counter() - t0:.0f} s wall", flush=True)
    arm.wall = time.perf_counter() - t0


def found_share(arm: Arm) -> float:
    """Mean over passes of the share of that session's changes its own pass found."""
    shares = []
    for s in sorted({c.session for c in arm.changes}):
        mine = [c for c in arm.changes if c.session == s]
        shares.append(sum(c.noticed == s for c in mine) / len(mine))
    return sum(shares) / len(shares) if shares else float("nan")


def noticed_per_pass(arm: Arm) -> float:
    """Mean over passes of the true changes (of any age: a change waiting since an earlier
    pass counts) that the pass noticed first: what the budgeted plan maximises."""
    sessions = sorted({c.session for c in arm.changes})
    return sum(c.noticed is not None for c in arm.changes) / len(sessions) if sessions else float("nan")


def mean_delay(arm: Arm, last: int) -> tuple[float, int]:
    delays = [(c.noticed if c.noticed is not None else last + 1) - c.session for c in arm.changes]
    return (sum(delays) / len(delays) if delays else float("nan")), sum(c.noticed is None for c in arm.changes)


def table(arms: list[Arm], full_s: float, last: int) -> str:
    cut = {a.share: found_share(a) for a in arms if a.strategy == "cut"}
    cut_any = {a.share: noticed_per_pass(a) for a in arms if a.strategy == "cut"}
    full = next(a for a in arms if a.strategy is None)
    lines = ["| arm | budget | found in the next pass | x cut paper | x full | changes noticed per pass (any age) "
             "| x cut paper | mean passes to notice (never) | object F1 "
             "| robot time / budget: mean, max (passes over) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for a in arms:
        share, per_pass = found_share(a), noticed_per_pass(a)
        delay, never = mean_delay(a, last)
        ref, ref_any = cut.get(a.share), cut_any.get(a.share)
        budget = a.share * full_s
        lines.append(f"| {a.name} | {a.share:.0%} ({budget:.0f} s) | {share:.3f} | "
                     f"{share / ref if ref else float('nan'):.2f} | {share / found_share(full):.2f} | "
                     f"{per_pass:.2f} | {per_pass / ref_any if ref_any else float('nan'):.2f} | "
                     f"{delay:.2f} ({never}) | {sum(a.f1) / len(a.f1):.3f} | "
                     f"{sum(a.times) / len(a.times) / budget:.2f}, "
                     f"{max(a.times) / budget:.2f} ({sum(t > budget + 1e-6 for t in a.times)}) |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--size", default="36x28", help="office WxH in metres")
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--passes", type=int, default=12, help="budgeted passes after the history")
    p.add_argument("--history", type=int, default=3, help="full passes after the first one, before the arms")
    p.add_argument("--budgets", default="25,50,100", help="percent of the full pass's robot time")
    p.add_argument("--strategies", default="expected_changes,uniform,cut")
    p.add_argument("--churn", type=float, default=0.1)
    p.add_argument("--hot-rooms", type=float, default=0.15)
    p.add_argument("--radius", type=float, default=1.0, help="m between a change and the event that notices it")
    p.add_argument("--keep", default=None, help="folder to keep the sites in (default: a temporary one)")
    args = p.parse_args(argv)
    root = Path(args.keep or tempfile.mkdtemp(prefix="bench_budget_"))
    root.mkdir(parents=True, exist_ok=True)
    last = args.passes + args.history + 1
    world = root / "world" / "office.yaml"
    rc = bomc(["world", "office", "--out", str(world), "--size", args.size, "--seed", str(args.seed), "--sessions",
               str(last), "--churn", str(args.churn), "--hot-rooms", str(args.hot_rooms), "--force"])
    if rc:
        return rc
    base = root / "base"
    t0 = time.perf_counter()
    run.run_build(world, base, seed=args.seed)
    for s in range(1, args.history + 2):
        run.run_monitor(world, base, s, seed=args.seed)
    with SiteStore(base, readonly=True) as store:
        full_s = last_full_pass_seconds(store.sessions())
    print(f"built, mapped and {args.history} full passes (a full pass: {full_s:.0f} s robot time) "
          f"in {time.perf_counter() - t0:.0f} s", flush=True)
    arms = [Arm("full", None, 1.0)]
    for pct in [float(b) for b in args.budgets.split(",")]:
        for strategy in args.strategies.split(","):
            arms.append(Arm(f"{strategy}@{pct:g}%", strategy, pct / 100))
            if pct >= 100:
                break  # a budget that covers a full pass runs the full pass whatever the strategy: one arm checks it
    for arm in arms:
        run_arm(arm, world, base, root, full_s, last, args)
    print(f"\n{args.size} office, seed {args.seed}, churn {args.churn}, hot rooms {args.hot_rooms}, "
          f"{args.history} full passes of history, {args.passes} passes; full pass {full_s:.0f} s robot time; "
          f"sites in {root}\n")
    print(table(arms, full_s, last))
    return 0


if __name__ == "__main__":
    sys.exit(main())
