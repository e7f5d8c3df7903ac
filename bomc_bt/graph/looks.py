"""How an object looks: its colour, kept per node, and the moves only a colour can find.

Position tells objects of one kind apart only while they stay put. A chair carried to a
room at the other end of the floor is, to a map keyed by position, a chair gone and a
chair new, and pairing every such removal with some addition is a coin toss
(:mod:`bomc_bt.graph.relocations` pairs within ``relocation_radius`` only). What the robot
can still tell is how each looked: a red chair gone from one room and a red chair new in
another, when no other red chair came or went in the pass, are one chair moved.

**The colour** of a view is the median chromaticity (r and g over r + g + b) of the pixels
of its own surface (:func:`bomc_bt.perception.colour.surface_colour`): brightness falls out,
so distance, shading and exposure change it little, and the median ignores what the mask
bled onto. A node keeps the running mean of its views' colours (:func:`blend`), saved with
it (site store schema 5: ``nodes.cr``, ``nodes.cg``). Neutral colours (grey, white, black)
share one chromaticity, so two grey chairs look alike here, as they do to any camera that
cannot tell a grey chair from a white one in shadow.

**Pairing by look** (:func:`look_pairs`) runs when the pass ends, after the pairs by
position, over the removals and additions left: per category, a removal and an addition
whose colours lie within ``colour_tolerance`` of each other and of no other candidate of
the pass on either side, and whose look is rare enough among the kind's objects that the
match is evidence of a move rather than a coincidence (:func:`coincidence`). Two red chairs
gone and one red chair new stay a removal and an addition each: which of the two moved is
a guess. A node without a colour (a camera without a colour image, a node of a store
written before schema 5 not seen since) is never paired by look, and where every object of
a kind looks alike (a world without colours: the simulator draws each category in one
colour) nothing is, so such runs are as they were before colours, but for a kind with no
object on the map other than the pass's removals and additions (one sofa on the floor): its
look is judged by the floor's looks of every kind (:func:`coincidence`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from bomc_bt.graph.records import Node, Observation

VIEWS = 20  # a node's colour is the mean of about its last this many views (older ones fade)


def colour_or_none(colour) -> np.ndarray | None:
    """``colour`` as a float (2,) chromaticity, or None when missing or out of range."""
    if colour is None:
        return None
    c = np.asarray(colour, dtype=float).reshape(2)
    return c if np.isfinite(c).all() and (c >= 0.0).all() and c.sum() <= 1.0 + 1e-9 else None


def blend(v: Node, colour: np.ndarray | None) -> None:
    """Fold one view's ``colour`` into ``v``'s (the first view sets it)."""
    if colour is None:
        return
    if v.colour is None:
        v.colour = np.array(colour, dtype=float)
        return
    weight = 1.0 / min(max(int(v.observations), 1), VIEWS)
    v.colour = v.colour + weight * (np.asarray(colour, dtype=float) - v.colour)


def alike(a: np.ndarray | None, b: np.ndarray | None, tolerance: float) -> bool:
    """Whether two colours are one look (False when either is unknown or ``tolerance`` is 0)."""
    if a is None or b is None or tolerance <= 0.0:
        return False
    return float(np.hypot(*(np.asarray(a) - np.asarray(b)))) <= tolerance


def looks_apart(a: Node | Observation, b: Node | Observation, tolerance: float) -> bool:
    """Whether both colours are known and tell the two apart: a blue chair new 2 m from where a
    red one went is another chair (False with ``tolerance`` 0: colours off)."""
    if tolerance <= 0.0 or a.colour is None or b.colour is None:
        return False
    return not alike(a.colour, b.colour, tolerance)


def look_pairs(removed: Sequence[Node], arrivals: Sequence[Node], tolerance: float,
               population: Sequence[Node] = (), unseen: Sequence[Node] = (),
               reach: float = 0.0, earlier: Sequence[Node] = (),
               first_seen: Sequence[Node] = (), odds: float = 1.5) -> list[tuple[Node, Node]]:
    """(removed, arrival) pairs of one category whose colours match each other and no other
    candidate on either side, where the match is evidence of a move (:func:`coincidence`
    below ``odds``, association.look_odds, and a look not every object of the kind shares;
    ``population``: the map's nodes, to count how common a look is), in the removed
    nodes' id order. A node of the arrival's kind and look within ``reach`` (m) of it that the
    pass never saw (``unseen``: its place hidden all pass) is a candidate too: it may be the
    one that moved there. Traced: a generated 93 x 90 m office, seed 9103, pass 2: a blue
    chair moved 1.25 m along its table, its old place hidden by the chairs beside it and by
    itself, and the arrival was paired with a blue chair taken away 35 m off (a wrong move,
    the removal and the move missed).

    So is a node of that look an earlier pass added after the removed node was last seen
    (``earlier``: the map's nodes older than the pass): an object not seen for passes may have
    gone to that place, not this one. Traced: a generated 36 x 28 m office, seed 9105: a red
    chair carried 19 m before pass 2, its old place not seen in pass 2 and the new one added
    there; its node, removed in pass 3, was paired with a red chair brought in during pass 3.

    So, last, is a node of that look the pass found where no earlier pass had looked
    (``first_seen``: no arrival, :mod:`bomc_bt.first_seen`): the removed object may have gone
    there as well as to the arrival's place, and which one it is is a guess, as with two
    arrivals. Traced: a generated 93 x 90 m office, seed 10231, pass 2: a red and a grey chair
    taken away and a red and a grey chair brought in, 25 and 70 m off, were paired as two
    moves (both wrong; two removals and two additions missed); a red and a grey chair were
    also first seen in that pass, 66 and 42 m from the arrivals."""
    if tolerance <= 0.0:
        return []
    pairs = []
    for v in sorted(removed, key=lambda n: n.id):
        twins = [a for a in arrivals if a.category == v.category and alike(v.colour, a.colour, tolerance)]
        if len(twins) != 1:
            continue
        look = twins[0].colour
        rivals = [w for w in removed if w.category == v.category and alike(w.colour, look, tolerance)]
        hidden_beside = [w for w in unseen if w.category == v.category and alike(w.colour, look, tolerance)
                         and float(np.hypot(*(w.position[:2] - twins[0].position[:2]))) <= reach]
        found_since = [w for w in earlier if w.category == v.category and w.first_session > v.last_session
                       and alike(w.colour, look, tolerance)]
        found_elsewhere = [w for w in first_seen if w.category == v.category and alike(w.colour, look, tolerance)]
        if len(rivals) == 1 and not hidden_beside and not found_since and not found_elsewhere \
                and informative(v, removed, arrivals, population, tolerance) \
                and coincidence(v, removed, arrivals, population, tolerance) < odds:
            pairs.append((v, twins[0]))
    return pairs


def coincidence(v: Node, removed: Sequence[Node], arrivals: Sequence[Node], population: Sequence[Node],
                tolerance: float) -> float:
    """How many of the pass's candidates of ``v``'s kind would share its look by chance: the
    larger side's count times the share of the kind's objects that look like ``v``.

    Why: a removal and an addition that look alike are one object moved, or an object taken
    away while an unrelated one of the same model was brought in. If ``v`` moved, its new
    place is among the additions for sure; if it was taken away, one of the ``n`` additions
    matches its look by chance with odds of about ``n`` times the look's share ``p``. The
    match is evidence of a move while ``n * p`` is below the odds of a move against such a
    coincidence (``association.look_odds``; the likelihood ratio ``1 / (n p)`` above their
    inverse). Where every object of a kind looks alike (a world without
    colours, a floor of one chair model) ``p`` is 1 and a look pairs nothing, so such runs
    keep the pairs by position alone.

    A kind whose only objects are the pass's own candidates (one sofa on the floor, gone
    from its place, and one new elsewhere) shows nothing about how common a look is among
    its objects: counted over them alone, ``p`` is 1 by construction. Then the floor's looks
    of every kind stand in (traced: a generated 36 x 28 m office, seed 7901, pass 2: the
    only sofa carried 17 m was reported taken away and a new one brought in)."""
    n = max(sum(a.category == v.category for a in arrivals), sum(w.category == v.category for w in removed))
    return n * look_share(v, removed, arrivals, population, tolerance)


def look_share(v: Node, removed: Sequence[Node], arrivals: Sequence[Node], population: Sequence[Node],
               tolerance: float) -> float:
    """The share of ``v``'s kind that looks like ``v`` (:func:`coincidence`'s ``p``)."""
    coloured = [n for n in (*population, *removed, *arrivals) if n.colour is not None]
    kind = {n.id: n for n in coloured if n.category == v.category}
    candidates = {n.id for n in (*removed, *arrivals)}
    if all(i == v.id or i in candidates for i in kind):
        kind = {n.id: n for n in coloured}
    return sum(alike(v.colour, n.colour, tolerance) for n in kind.values()) / max(len(kind), 1)


def informative(v: Node, removed: Sequence[Node], arrivals: Sequence[Node], population: Sequence[Node],
                tolerance: float) -> bool:
    """Whether ``v``'s look tells it from some object of its kind (its share below 1): where
    every object of a kind looks alike, a match by look is no evidence at all, whatever the
    odds of a move (``association.look_odds``), and nothing is paired by look."""
    return look_share(v, removed, arrivals, population, tolerance) < 1.0 - 1e-9
