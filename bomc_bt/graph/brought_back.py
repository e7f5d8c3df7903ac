"""Objects brought back: a new node where an earlier pass saw one of its kind and look go.

Objects that are taken away come back. A chair lent to another floor is returned to its
desk, a bin taken for emptying is put back in its corner. When it comes back to the very
place where an earlier pass saw it gone (removed on evidence of absence, and not seen
since), a node of its category new in this pass stands there, and the simplest story is
that object returning: an addition, which is what it is.

Why the pass end has to know: a removal of this pass and an addition that look alike are
paired as one object moved when no other candidate of the pass shares their look
(:func:`~bomc_bt.graph.looks.look_pairs`). A return breaks that in two ways. Beside a true
move of the same model, the returned object is a second candidate, so the true move stays a
removal plus an addition (36 x 28 m office, seed 7503, pass 11: chair-9 carried 17.6 m while
chair-1, of the same navy model, came back to its old place). Beside a removal of the same
model, the returned object is the removal's only look-alike, so a chair taken away and
another brought back become one invented move (the ideal reporter on seed 202, session 5:
grey chair-12 taken away while grey chair-9 came back to its old place 14 m off). Taking
the returns out of the arrivals before any pairing tells both right.

``radius`` ([m], ``association.return_radius``) is how near the old place the new node
must stand: the error of two estimates of one object's centre, well under the spacing of
chairs at a table (0.6-0.8 m; at 1 m a chair moved to the next seat of a table where one
of its model had gone was taken for a return). Where both colours are known they must be
one look (:func:`~bomc_bt.graph.looks.looks_apart`); where either is unknown, or colours
are off, the place alone decides. Measured with the ideal reporter
(``benchmarks/bench_change_ceiling.py --looks``) on ten 36 x 28 m offices of 12 sessions,
mean change F1 0.872 -> 0.895 (5 higher, none lower); on ten 93 x 90 m floors of 3
sessions (fewer earlier removals to come back) 0.748 -> 0.747 (one lower: a bin back at
its place left a removal and a new bin of one model as the pass's only look-alikes, and
they were paired). By position alone the pairs are the same either way.

What this costs: an object carried far in an earlier pass whose move that pass did not
pair (its old node removed, a new node where it went) and later carried back to its old
place is reported as that new node removed and the old one back, not as one move back.
The generators move an object to a place drawn anew (only objects taken away are
brought back to their old places), so the measurements above do not show it.

During the pass the same story decides which new node an older node's confirmed absence
folds in (:func:`stands_where_gone`): a look-alike new where an earlier pass saw one of its
kind go is that object back, no other's new place. Traced on a 36 x 28 m office (seed 9105,
pass 11): navy chair-11 carried 1.6 m while navy chair-5 came back to its place 1.4 m the
other side; chair-11's node folded in the nearer new node, chair-5's, as its move, and
chair-11 at its new place was reported added (change F1 0.250, the ideal reporter 1.000).

The pass end marks each return with an ``updated`` event whose ``detail`` is
``{"back_of": <id of the node seen go>}`` (:data:`BACK_OF`), and the change report says so
(:func:`back_of`; "added chair #N at (x, y), back where #M went").
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from bomc_bt.graph.looks import looks_apart
from bomc_bt.graph.records import Event, Node, Observation

BACK_OF = "back_of"  # the key in an ``updated`` event's detail: the id of the node this one is back of


def brought_back(arrivals: Sequence[Node], gone: Sequence[Node], radius: float, tolerance: float
                 ) -> list[tuple[Node, Node]]:
    """(arrival, gone node) for each of the ``arrivals`` standing within ``radius`` (planar,
    m) of a ``gone`` node of its category whose look does not tell them apart (``tolerance``:
    the colour tolerance, 0 colours off), the nearest such; none when ``radius`` is 0."""
    back = []
    for a in arrivals:
        near = _gone_near(a, gone, radius, tolerance)
        if near:
            back.append((a, min(near, key=lambda t: t[:2])[2]))
    return back


def stands_where_gone(at: Node | Observation, gone: Sequence[Node], radius: float, tolerance: float) -> bool:
    """Whether ``at`` (a node or a view) stands where :func:`brought_back` would take it for
    one of the ``gone`` brought back."""
    return bool(_gone_near(at, gone, radius, tolerance))


def _gone_near(at: Node | Observation, gone: Sequence[Node], radius: float, tolerance: float
               ) -> list[tuple[float, int, Node]]:
    """(planar distance, id, node) of each ``gone`` node of ``at``'s category within ``radius``
    whose look does not tell them apart (none when ``radius`` is 0)."""
    if radius <= 0.0:
        return []
    near = []
    for g in gone:
        if g.category == at.category:
            d = float(np.hypot(*(at.position[:2] - g.position[:2])))
            if d <= radius and not looks_apart(at, g, tolerance):
                near.append((d, g.id, g))
    return near


def back_of(events: Iterable[Event]) -> dict[int, int]:
    """Per node, the id of the node it was found to be back of (the last mark among ``events``)."""
    return {int(e.node_id): int(e.detail[BACK_OF]) for e in events
            if e.kind == "updated" and (e.detail or {}).get(BACK_OF) is not None}
