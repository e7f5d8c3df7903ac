"""Object-level evaluation of a mapped graph against ground truth (the paper's protocol).

A mapped node is a true positive when a ground-truth object of the same category lies
within that category's association distance, each ground-truth object matched at most
once; unmatched nodes are false positives, unmatched ground-truth objects false
negatives (CONTRACTS.md section 4).

"Matched at most once" leaves open *which* pairs to take when objects crowd together; a
greedy pass in node order can pair a node with the GT object another node needed and so
report a worse score that depends on the order nodes were stored in. We therefore take,
per category, a **maximum** one-to-one matching (the largest possible number of TPs) and
among those the one with the smallest total distance (ties broken by node id, then GT
order). It is computed per connected component of the "within distance" graph by the
Hungarian method on a component-sized cost matrix in which non-edges cost more than any
set of real edges, so a matching with more pairs always wins. TP/FP/FN therefore do not
depend on node order at all.

Scores follow the paper's tables: precision = TP / mapped (None without mapped nodes),
recall = TP / GT (None without GT), F1 = 2 TP / (2 TP + FP + FN), None only when there is
neither GT nor a mapped node (the paper prints "-" there and 0.00 for a class with one
false positive and no GT). Only nodes with state "present" are scored.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bomc_bt.graph import PRESENT, Node


@dataclass
class ClassScores:
    gt: int
    mapped: int
    tp: int
    fp: int
    fn: int
    precision: float | None
    recall: float | None
    f1: float | None


@dataclass
class Match:
    """A true positive: node ``node_id`` paired with ground-truth object ``gt_index``."""

    node_id: int
    gt_index: int
    category: str
    distance: float


@dataclass
class EvaluationResult:
    session: int
    classes: dict[str, ClassScores]
    overall: ClassScores
    matches: list[Match] = field(default_factory=list)


def scores(gt: int, mapped: int, tp: int) -> ClassScores:
    """Precision, recall, F1 from counts (None where undefined, see the module docstring)."""
    fp, fn = mapped - tp, gt - tp
    precision = tp / mapped if mapped else None
    recall = tp / gt if gt else None
    f1 = 2 * tp / (2 * tp + fp + fn) if (2 * tp + fp + fn) else None
    return ClassScores(gt, mapped, tp, fp, fn, precision, recall, f1)


def evaluate(
    nodes: Sequence[Node],
    ground_truth: Sequence[tuple[str, np.ndarray]],
    thresholds: Callable[[str], float] | float,
    session: int,
) -> EvaluationResult:
    """Score the present ``nodes`` against ``ground_truth`` [(category, position)] of one session."""
    threshold = thresholds if callable(thresholds) else (lambda _c, d=float(thresholds): d)
    live = sorted((n for n in nodes if n.state == PRESENT), key=lambda n: n.id)
    gt = [(c, np.asarray(p, dtype=float).reshape(3)) for c, p in ground_truth]
    categories = sorted({n.category for n in live} | {c for c, _ in gt})
    classes: dict[str, ClassScores] = {}
    matches: list[Match] = []
    for cat in categories:
        cat_nodes = [n for n in live if n.category == cat]
        cat_gt = [i for i, (c, _) in enumerate(gt) if c == cat]
        pairs = _match(
            np.array([n.position for n in cat_nodes]).reshape(-1, 3),
            np.array([gt[i][1] for i in cat_gt]).reshape(-1, 3),
            float(threshold(cat)),
        )
        for a, b, d in pairs:
            matches.append(Match(cat_nodes[a].id, cat_gt[b], cat, d))
        classes[cat] = scores(len(cat_gt), len(cat_nodes), len(pairs))
    total = scores(sum(s.gt for s in classes.values()), sum(s.mapped for s in classes.values()),
                   sum(s.tp for s in classes.values()))
    return EvaluationResult(session, classes, total, matches)


def _match(nodes: np.ndarray, gt: np.ndarray, radius: float) -> list[tuple[int, int, float]]:
    """Maximum one-to-one matching of node rows to gt rows within ``radius``, minimum total distance."""
    if len(nodes) == 0 or len(gt) == 0:
        return []
    dist = np.sqrt(((nodes[:, None, :] - gt[None, :, :]) ** 2).sum(axis=2))
    return match_pairs(dist, dist <= radius)


def match_pairs(dist: np.ndarray, edges: np.ndarray) -> list[tuple[int, int, float]]:
    """Maximum one-to-one matching of rows to columns over the allowed ``edges`` (n, m), and
    among those the one with the smallest total ``dist``: [(row, col, dist)], sorted.

    The protocol's matching with the gate left to the caller (change evaluation gates a
    move on both of its ends)."""
    pairs: list[tuple[int, int, float]] = []
    for rows, cols in _components(edges):
        sub = dist[np.ix_(rows, cols)]
        ok = edges[np.ix_(rows, cols)]
        big = float(sub[ok].sum()) + 1.0  # any extra real pair beats every distance saving
        cost = np.where(ok, sub, big)
        transposed = len(rows) > len(cols)
        assigned = _hungarian(cost.T if transposed else cost)
        for r, c in enumerate(assigned):
            a, b = (c, r) if transposed else (r, c)
            if ok[a, b]:
                pairs.append((rows[a], cols[b], float(sub[a, b])))
    return sorted(pairs)


def _components(edges: np.ndarray) -> list[tuple[list[int], list[int]]]:
    """Connected components (with at least one edge) of the bipartite graph ``edges`` (n, m)."""
    n, m = edges.shape
    parent = list(range(n + m))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in zip(*np.nonzero(edges), strict=True):
        ra, rb = find(int(a)), find(n + int(b))
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    groups: dict[int, tuple[list[int], list[int]]] = {}
    for a in np.unique(np.nonzero(edges)[0]):
        groups.setdefault(find(int(a)), ([], []))
    for a in range(n):
        if find(a) in groups:
            groups[find(a)][0].append(a)
    for b in range(m):
        if find(n + b) in groups:
            groups[find(n + b)][1].append(b)
    return [groups[k] for k in sorted(groups)]


def _hungarian(cost: np.ndarray) -> list[int]:
    """Minimum-cost assignment of every row to a distinct column (rows <= cols); column per row.

    The shortest-augmenting-path form with potentials, O(n^2 m), inner loop vectorised.
    """
    n, m = cost.shape
    u = np.zeros(n + 1)
    v = np.zeros(m + 1)
    p = np.zeros(m + 1, dtype=np.int64)  # p[j]: row (1-based) assigned to column j, 0 = none
    way = np.zeros(m + 1, dtype=np.int64)
    for i in range(1, n + 1):
        p[0] = i
        j0 = 0
        minv = np.full(m + 1, math.inf)
        used = np.zeros(m + 1, dtype=bool)
        while True:
            used[j0] = True
            i0 = p[j0]
            cur = cost[i0 - 1] - u[i0] - v[1:]
            free = ~used[1:]
            better = free & (cur < minv[1:])
            minv[1:][better] = cur[better]
            way[1:][better] = j0
            cand = np.where(free, minv[1:], math.inf)
            j1 = int(np.argmin(cand)) + 1
            delta = cand[j1 - 1]
            cols = np.nonzero(used)[0]
            u[p[cols]] += delta
            v[cols] -= delta
            minv[1:][free] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = int(way[j0])
            p[j0] = p[j1]
            j0 = j1
    out = [0] * n
    for j in range(1, m + 1):
        if p[j]:
            out[p[j] - 1] = j - 1
    return out


# ---------------------------------------------------------------- output
def _r(x: float | None) -> float | None:
    return None if x is None else round(x, 3)


def _scores_json(s: ClassScores, with_counts: bool = True) -> dict[str, Any]:
    out: dict[str, Any] = {"gt": s.gt, "mapped": s.mapped} if with_counts else {}
    out.update(tp=s.tp, fp=s.fp, fn=s.fn, precision=_r(s.precision), recall=_r(s.recall), f1=_r(s.f1))
    return out


def to_json(result: EvaluationResult) -> dict[str, Any]:
    """CONTRACTS.md section 4 (``overall`` also carries gt and mapped; numbers to 3 decimals)."""
    return {
        "session": result.session,
        "classes": {c: _scores_json(s) for c, s in sorted(result.classes.items())},
        "overall": _scores_json(result.overall),
    }


def _ordered(results: Mapping[int, EvaluationResult] | Sequence[EvaluationResult]) -> list[EvaluationResult]:
    items = list(results.values()) if isinstance(results, Mapping) else list(results)
    return sorted(items, key=lambda r: r.session)


def _all_classes(results: list[EvaluationResult]) -> list[str]:
    return sorted({c for r in results for c in r.classes})


def _empty(cat: str, r: EvaluationResult) -> ClassScores:
    return r.classes.get(cat) or scores(0, 0, 0)


def counts_table_data(results: Mapping[int, EvaluationResult] | Sequence[EvaluationResult]) -> dict[str, Any]:
    """The paper's count table: GT and Map of the first session, then changes relative to it."""
    ordered = _ordered(results)
    if not ordered:
        return {"reference_session": None, "sessions": [], "classes": {}}
    ref = ordered[0]
    classes: dict[str, list[dict[str, Any]]] = {}
    for cat in _all_classes(ordered):
        base = _empty(cat, ref)
        rows: list[dict[str, Any]] = [{"session": ref.session, "gt": base.gt, "map": base.mapped}]
        for r in ordered[1:]:
            s = _empty(cat, r)
            delta = {"delta_gt": s.gt - base.gt, "delta_map": s.mapped - base.mapped}
            rows.append({"session": r.session, **delta})
        classes[cat] = rows
    return {"reference_session": ref.session, "sessions": [r.session for r in ordered], "classes": classes}


def counts_table(results: Mapping[int, EvaluationResult] | Sequence[EvaluationResult]) -> str:
    """Markdown rendering of :func:`counts_table_data`."""
    data = counts_table_data(results)
    sessions = data["sessions"]
    if not sessions:
        return "(no sessions)\n"
    head = ["Class", f"S{sessions[0]} GT", f"S{sessions[0]} Map"]
    for s in sessions[1:]:
        head += [f"S{s} ΔGT", f"S{s} ΔMap"]
    lines = [_row(head), _row(["---"] * len(head))]
    for cat, rows in data["classes"].items():
        cells = [cat, str(rows[0]["gt"]), str(rows[0]["map"])]
        for row in rows[1:]:
            cells += [_signed(row["delta_gt"]), _signed(row["delta_map"])]
        lines.append(_row(cells))
    return "\n".join(lines) + "\n"


def scores_table_data(results: Mapping[int, EvaluationResult] | Sequence[EvaluationResult]) -> dict[str, Any]:
    """TP / FP / FN / F1 per class per session (and overall), JSON-able."""
    ordered = _ordered(results)
    classes = {
        cat: [{"session": r.session, **_scores_json(_empty(cat, r))} for r in ordered]
        for cat in _all_classes(ordered)
    }
    overall = [{"session": r.session, **_scores_json(r.overall)} for r in ordered]
    return {"sessions": [r.session for r in ordered], "classes": classes, "overall": overall}


def scores_table(results: Mapping[int, EvaluationResult] | Sequence[EvaluationResult]) -> str:
    """Markdown rendering of :func:`scores_table_data` (F1 to 2 decimals, "-" where undefined)."""
    data = scores_table_data(results)
    if not data["sessions"]:
        return "(no sessions)\n"
    head = ["Class"]
    for s in data["sessions"]:
        head += [f"S{s} TP", f"S{s} FP", f"S{s} FN", f"S{s} F1"]
    lines = [_row(head), _row(["---"] * len(head))]
    for name, rows in [*data["classes"].items(), ("overall", data["overall"])]:
        cells = [name]
        for row in rows:
            f1 = "-" if row["f1"] is None else f"{row['f1']:.2f}"
            cells += [str(row["tp"]), str(row["fp"]), str(row["fn"]), f1]
        lines.append(_row(cells))
    return "\n".join(lines) + "\n"


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _signed(x: int) -> str:
    return f"+{x}" if x > 0 else str(x)
