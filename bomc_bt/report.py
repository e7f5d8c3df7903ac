"""Session reports: what one monitor pass did, in JSON, Markdown and a PNG of the map.

What changed is reported per node, net over the pass (:mod:`bomc_bt.net_changes`), with
the evidence: a chair removed and found again two seconds later is no change for the
operator. The raw per-frame event counts stay in the report (``events``) and every raw
event in the store's history, for debugging.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from bomc_bt.budget_pass import pass_regions
from bomc_bt.net_changes import (
    FIRST_SEEN,
    NET_KINDS,
    RETRACTED,
    NetChange,
    first_seen_count,
    net_changes,
    retracted_count,
    summarize,
)
from bomc_bt.pass_resume import coverage_masks
from bomc_bt.render import render_semantic_map, save_png
from bomc_bt.site import write_json
from bomc_bt.tree.leaf import read_key

LOCALIZED_KEY = "localized"
"""The blackboard key the Relocalize leaf writes: ``local`` or ``global`` (absent: not localized)."""


def pass_changes(ctx) -> tuple[int | None, list[NetChange]]:
    """The net changes of the pass in ``ctx`` since the previous recorded pass (None: since the empty map)."""
    if ctx.store is None or ctx.graph is None:
        return None, []
    previous = max((s.number for s in ctx.store.sessions() if s.number < ctx.session), default=None)
    return previous, net_changes(ctx.store.events(until=ctx.session), previous, ctx.graph.threshold)


def changes_summary(ctx) -> dict[str, Any]:
    """The report's ``changes`` key: counts per kind and one record per changed node; the
    first-seen and retracted nodes (not changes) are counted apart and listed with them."""
    previous, changes = pass_changes(ctx)
    return {"since_session": previous, "counts": summarize(changes), "nodes": [c.to_json() for c in changes],
            "first_seen": first_seen_count(changes), "retracted": retracted_count(changes)}


def session_summary(ctx) -> dict[str, Any]:
    """Counts, coverage, missed waypoints and timing of the pass in ``ctx``; how the robot
    was localized comes from the blackboard key :data:`LOCALIZED_KEY`."""
    events = Counter(e.kind for e in (ctx.perception.events if ctx.perception else []))
    coverage = ctx.perception.coverage if ctx.perception else None
    by_category = Counter(n.category for n in ctx.graph.nodes.values())
    return {
        "session": ctx.session,
        "outcome": ctx.outcome,
        "reason": ctx.reason,
        "sim_time_s": round(ctx.now(), 1),
        "path_length_m": round(ctx.robot.distance_travelled, 1),
        "frames": ctx.perception.frames if ctx.perception else 0,
        "nodes": len(ctx.graph.nodes),
        "nodes_by_category": dict(sorted(by_category.items())),
        "events": {k: events.get(k, 0) for k in ("added", "removed", "moved", "updated")},
        "changes": changes_summary(ctx),
        "coverage": {
            "observed_m2": round(coverage.observed_area, 1) if coverage else 0.0,
            "fraction": round(coverage.fraction, 3) if coverage else 0.0,
            "unobserved_regions": coverage.unobserved_regions() if coverage else [],
        },
        "traversal": ctx.traverse.summary() if ctx.traverse else {},
        "localized": read_key(LOCALIZED_KEY, "no"),
        "recoveries": ctx.watch.summary() if getattr(ctx, "watch", None) else [],
    }


def write_session_report(ctx, close: bool = True, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write ``sessions/<n>/report.{json,md}`` and the map; ``close`` ends the session in the store,
    with the pass's rows of the change model (:mod:`bomc_bt.change_model`).

    ``extra`` keys are added to the summary (a replayed pass adds ``localized`` and ``replay``).
    """
    if close:  # the history exact at the pass's end before the net changes are read from it
        ctx.store.reconcile(ctx.session, ctx.now())
    seen = ctx.perception.coverage.near if ctx.perception else None  # looked at, not glimpsed
    changes = pass_changes(ctx)[1]  # net: a node added and taken off again in the pass changed nothing
    regions, budget = pass_regions(ctx.store, ctx.robot.live_map(), ctx.config, seen, changes, ctx.session, ctx.now(),
                                   getattr(ctx, "budget", None))
    summary = {**session_summary(ctx), "budget": budget, **(extra or {})}
    if close:  # with what the camera saw: the next passes tell first-seen objects from added ones
        final = coverage_masks(ctx.perception) if ctx.perception else {}
        ctx.store.end_session(ctx.session, ctx.outcome, {**summary, "stamp": ctx.now()}, regions, final)
    out = ctx.site.session_dir(ctx.session)
    write_json(out / "report.json", summary)
    (out / "report.md").write_text(report_markdown(summary))
    removed = [e for e in (ctx.perception.events if ctx.perception else []) if e.kind == "removed"]
    waypoints = ctx.plan.waypoints if ctx.plan else []
    img = render_semantic_map(ctx.robot.live_map(), ctx.graph.nodes.values(), [_Pos(e) for e in removed],
                              waypoints=waypoints, title=f"session {ctx.session}")
    save_png(img, out / "semantic_map.png")
    return summary


class _Pos:
    def __init__(self, event):
        self.position = event.position


def report_markdown(s: dict[str, Any]) -> str:
    t = s["traversal"]
    lines = [
        f"# Session {s['session']}: {s['outcome']}",
        "",
        f"- sim time: {s['sim_time_s']} s, path: {s['path_length_m']} m, frames: {s['frames']}",
        f"- nodes: {s['nodes']} ({', '.join(f'{k} {v}' for k, v in s['nodes_by_category'].items()) or 'none'})",
        f"- raw events (per frame, for debugging): {', '.join(f'{k} {v}' for k, v in s['events'].items())}",
        f"- coverage: {s['coverage']['observed_m2']} m² observed ({s['coverage']['fraction']:.0%} of free space)",
    ]
    if t:
        lines.append(f"- waypoints: {t['waypoints']} (visited {t['visited']}, detoured {t['detoured']}, "
                     f"missed {t['missed']}, not reached {t['pending']}; "
                     f"{t.get('gap_viewpoints', 0)} of them gap viewpoints, "
                     f"{t.get('refresh_stops', 0)} refresh stops, {t.get('last_looks', 0)} last looks)")
        for m in t["missed_waypoints"]:
            lines.append(f"  - missed waypoint {m['index'] + 1} at ({m['x']}, {m['y']})")
    regions = s["coverage"]["unobserved_regions"]
    if regions:
        lines.append("- largest unobserved regions:")
        lines += [f"  - ({r['x']}, {r['y']}): {r['area_m2']} m²" for r in regions[:10]]
    lines += _changes_markdown(s.get("changes"))
    r = s.get("replay")
    if r:
        lines.append(f"- replayed from {r['bag']} ({r['rate']}): frames processed {r['processed']}, "
                     f"dropped {r['dropped']}, skipped {r['skipped']} (of {r['frames_in_bag']} in the bag); "
                     f"not-model cost {r['not_model_ms_per_frame']} ms per frame")
    for r in s.get("recoveries", []):
        lines.append(f"- at {r['stamp']} s: {r['trigger']}; {r['cause']}: {r['detail']}; "
                     f"did: {r['action'] or 'nothing'}{'; ' + r['result'] if r['result'] else ''}")
    lines += _budget_lines(s.get("budget") or {})
    if s.get("reason"):
        lines.append(f"- reason: {s['reason']}")
    return "\n".join(lines) + "\n"


def _changes_markdown(changes: dict[str, Any] | None) -> list[str]:
    """The changes, then apart the first-seen nodes (new to the map where no pass had looked)."""
    if not changes:
        return []
    since = "the empty map" if changes["since_session"] is None else f"session {changes['since_session']}"
    counts = ", ".join(f"{k} {v}" for k, v in changes["counts"].items())
    lines = ["", f"## Changes since {since}: {counts}", ""]
    records = [NetChange.from_json(c) for c in changes["nodes"]]
    lines += [f"- {c.describe()}" for c in records if c.kind in NET_KINDS]
    first = [c for c in records if c.kind == FIRST_SEEN]
    if first:
        lines += ["", f"## First seen: {len(first)} (new to the map where no earlier pass had looked; "
                  "not changes)", ""]
        lines += [f"- {c.describe()}" for c in first]
    withdrawn = [c for c in records if c.kind == RETRACTED]
    if withdrawn:
        lines += ["", f"## Retracted: {len(withdrawn)} (seen in too few frames, or missed moments after a sighting: "
                  "not trusted; dropped, not changes)", ""]
        lines += [f"- {c.describe()}" for c in withdrawn]
    return lines

def _budget_lines(b: dict[str, Any]) -> list[str]:
    """The budget a pass ran with and the regions it did not see, stalest first."""
    lines = []
    if b.get("seconds"):
        kind = "a full pass (the budget covers the last full pass)" if b.get("full_pass") else (
            f"{b['stops']} of {b['stops_total']} stops by {b['strategy']}, planned {b['planned_s']} s, "
            f"{b['expected_changes']} changes expected")
        lines.append(f"- budget: {b['seconds']} s robot time: {kind}")
    skipped = b.get("skipped_regions") or []
    if skipped:
        lines.append(f"- regions not seen: {len(skipped)} of {b['regions']} (stalest first: passes since seen, "
                     "changes expected waiting)")
        lines += [f"  - ({r['x']}, {r['y']}): {r['passes_since_seen']} passes, {r['expected_waiting']}"
                  for r in skipped[:10]]
    return lines
