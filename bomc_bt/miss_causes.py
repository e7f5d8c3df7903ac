"""Why an object the map should hold is not in it: recall broken down by cause.

Recall alone says how many objects a pass lost, not what to fix. Each false negative of
the object evaluation is put in the first class that fits, judged from what the graph
holds near the object at the end of the pass (``delta`` is the category's association
distance, the evaluation's matching radius):

``removed``
    A node of its category was removed within ``delta`` of it during the pass, and the
    object is still there: a removal without evidence of absence.
``mislabelled``
    A node of another category, matched to nothing, lies within ``delta``: detected and
    placed, under the wrong label.
``displaced``
    A node of its category, matched to nothing, lies within ``2 delta``: mapped, but too
    far off (projection, a view of one end of the object, localization).
``merged``
    A node of its category lies within ``2 delta`` but is matched to a neighbouring object:
    two objects share one node (association).
``unseen``
    Nothing of its kind near it: never mapped (out of the camera's sight on this pass, or
    missed by the detector in every frame that saw it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from bomc_bt.evaluation import EvaluationResult
from bomc_bt.graph import Node

CAUSES = ("removed", "mislabelled", "displaced", "merged", "unseen")


@dataclass
class Miss:
    """One false negative and its cause."""

    category: str
    position: np.ndarray
    cause: str


def miss_causes(result: EvaluationResult, nodes: Sequence[Node], removed: Sequence[tuple[str, np.ndarray]],
                ground_truth: Sequence[tuple[str, np.ndarray]], threshold: Callable[[str], float]) -> list[Miss]:
    """The cause of every ground-truth object ``result`` did not match.

    ``nodes`` are the present nodes that were scored, ``removed`` the (category, position)
    of nodes the pass removed and did not bring back, ``ground_truth`` the list scored
    against (same order as the evaluation's ``gt_index``).
    """
    matched_gt = {m.gt_index for m in result.matches}
    matched_nodes = {m.node_id for m in result.matches}
    out: list[Miss] = []
    for i, (category, pos) in enumerate(ground_truth):
        if i in matched_gt:
            continue
        p = np.asarray(pos, dtype=float).reshape(3)
        out.append(Miss(category, p, _cause(category, p, nodes, removed, matched_nodes, threshold(category))))
    return out


def _cause(category: str, p: np.ndarray, nodes: Sequence[Node], removed: Sequence[tuple[str, np.ndarray]],
           matched: set[int], delta: float) -> str:
    def near(q, radius: float) -> bool:
        return float(np.hypot(q[0] - p[0], q[1] - p[1])) <= radius

    if any(c == category and near(q, delta) for c, q in removed):
        return "removed"
    if any(n.category != category and n.id not in matched and near(n.position, delta) for n in nodes):
        return "mislabelled"
    same = [n for n in nodes if n.category == category and near(n.position, 2 * delta)]
    if any(n.id not in matched for n in same):
        return "displaced"
    if same:
        return "merged"
    return "unseen"


def cause_counts(misses: Sequence[Miss]) -> dict[str, int]:
    """Misses per cause, every cause listed (0 where none)."""
    return {c: sum(m.cause == c for m in misses) for c in CAUSES}
