"""Two nodes that are the two ends of one object, found when a pass ends.

A 1.6 m table whose middle the chairs around it hide is seen end by end: each end's views
are half a metre long, the gap between them wider than ``footprint_touch``, and no frame
shows both. Each end becomes a node 0.7 m off the table's middle (Environment A size,
seed 337: ten of the 45 tables, all ten phantoms of a pass over a floor where nothing
changed). Neither end is big, so no view of one is taken for the other's hidden end.

What tells two ends of one object from two objects is the size its category shows
elsewhere on the floor: tables 1.6 m long, chairs 0.5 m. Two nodes of one category are
taken for one object when each is clearly a part (its footprint at most ``PART_SHARE`` of
the category's reference length), their joint box is no longer than that length (plus the
noise margin), and no frame of the pass showed both. Two chairs side by side are each a
whole chair, so they stay apart. In a big category (a table, not a chair) only the shorter
of the two must be a part: a table seen over most of its length (1.13 m of 1.6 m) and a
sliver of its far end beyond the chairs (0.3-0.7 m) were left as two tables 1.1 m apart,
one of them a phantom (Environment A size, seed 343, pass 2; with seeds 337 and 341 three
such pairs, each one table).

The reference length (:func:`reference_lengths`) is the longest whole view of the
category this pass (a view no occluder or image border cut off). For a big category (one
whose whole views are longer than delta_c plus the margin) it is also at least the
length that several of its nodes' footprints reach: tables stand among chairs, so a view
of a whole table is rare, and in the first pass over that floor the longest was 1.40 m
(of 1.6 m tables) while 16 of its 55 table nodes had footprints of 1.66-1.86 m. Against
1.40 m no pair of ends was a part (ends are 0.85-0.92 m long: the table's width) and no
joint box short enough; the join fired for 3 pairs and left ten phantoms (against the
footprints: 11 pairs, 3 phantoms in that pass). Small
categories keep the whole views only: a chair's footprint may hold the bleed of a mask
over its neighbour (the tenth longest chair footprint there was 0.97 m, whole views of
chairs 0.67 m), and against 0.97 m two chairs would read as parts of one.

On a small floor a big category's reference is short: five tables, each flanked by
chairs, none seen whole, and the footprints reaching 0.98-1.24 m in the first pass (tables
of 1.2 and 1.6 m; generated 36 x 28 m offices, seeds 4411-4424, where a table split in two
was 11 of the 12 errors left after three passes over a floor where nothing changed). An
end's footprint is then as wide as the table (0.8 m and the mask's bleed) and only half a
table long, so its longest side is no part's. So in a big category a part is measured
along the joint box's long axis (how much of the object's length it holds), and the joint
box may exceed the reference by what an occluder hides (``hidden``: the reference itself
comes from views such occluders cut). Two 1.2 m tables end to end, 2.4 m, stay two.

There the only tables seen whole may be seen end-on, 0.80 m across, no longer than a chair
with its mask's bleed (seed 4411: three tables left split in two, their ends never
joined; the footprints of four of its eight table nodes reached 1.02-1.22 m, the other
four were ends of the split tables). So a category is big also when a whole view is
longer than delta_c and a third of its footprints are longer than delta_c plus the margin.
Both must hold for a chair to count as big: its footprints reach that far where masks bled
over the chair beside, and its whole views stay near delta_c (0.56-0.74 m on the 36 x 28 m
offices measured, where tables' reached 0.57-1.61 m).

Tables 0.6 m wide seen whole only end-on are narrower than delta_c even with the mask's
bleed: on a 36 x 28 m office (seed 7305, pass 2) the longest whole view of a table was
0.66 m while four of its six table footprints reached 1.2-1.9 m, so tables were not big, and
the two ends of a 1.2 m table flanked by chairs (0.7 and 0.3 m of it, 0.16 m apart) stayed
two tables in passes 2 and 3. Footprints longer than delta_c plus the margin do not tell
such tables from chairs: after three passes over six 36 x 28 m offices 0-8 of 12-14 chair
footprints were, their masks bled over the chair beside. How long most footprints are
does: the median chair footprint was 0.73-0.96 m there, the median table's 1.21-1.46 m. So
a category is big, too, when a whole view is no more than the margin short of delta_c and at
least half its footprints (``MOST_SHARE``) are longer than delta_c plus twice the margin
(1.1 m: a chair with its neighbour's bleed stays below it).

Two parts make one object of the category's size in both directions: in a big category the
joint box is also no wider across than three in four of the footprints of its nodes that are
no parts (their shorter sides). Doors are big where one is seen whole (0.9 m, longer than
delta_c) and their masks bleed along the wall to 1.3-2.0 m: on office-s (build seed 2, pass
2) two doors facing each other across the 2.1 m corridor, each a sliver of the pair's
length, were joined into one door in the corridor's middle (the pass's object F1 0.952;
their joint box 2.25 x 1.97 m, the four doors' footprints 0.17-0.63 m across). On an
Environment-A-size floor (seed 9955, pass 1) two 1.2 x 0.6 m tables standing side by side,
one 0.8 m further along, were joined into one (joint box 1.52 x 2.33 m); the ends of tables
joined there were 0.85-0.98 m across, the tables' width with the mask's bleed. Not the
widest footprints: a tenth of that floor's table footprints reached 1.3-1.6 m across, and
against them the side-by-side tables were still joined. Nor the gap between the two (what
hides a table's middle is a chair): ends of 1.6 m tables lay 0.65-0.88 m apart. A pair
wider than that only by one end's bleed still joins: the other end is no wider than the
category and the pair no wider than the wider end (the two lie along one line; tables side by
side and doors across a corridor lie beside each other).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Iterable

import numpy as np

from bomc_bt.graph.footprints import longest_side, shortest_side, union
from bomc_bt.graph.records import Node

# [-] a node whose footprint is at most this share of its category's reference length is a
# part of an object, not an object (a table's end: 0.87 m of 1.6 m)
PART_SHARE = 0.6
# [-] share of a big category's nodes (at least FOOTPRINT_RANK of them) whose footprints
# must reach a length for it to count as the category's size: one or two footprints over
# two objects do not set it
FOOTPRINT_SHARE = 0.1
FOOTPRINT_RANK = 3  # [count] the fewest footprints that set a big category's size
# [-] share of a category's footprints longer than delta_c plus the margin that makes it big
# where no whole view was (a table seen whole only across its width)
BIG_SHARE = 1.0 / 3.0
# [-] share of a category's footprints longer than delta_c plus twice the margin that makes it
# big where its whole views fall short of delta_c by up to the margin (tables 0.6 m wide, seen
# whole only end-on)
MOST_SHARE = 0.5
# [-] quantile of the shorter sides of a big category's whole footprints (those no part) that
# two parts joined must stay within across: masks bleed, and a tenth of the table footprints
# on an Environment-A-size floor were 1.3-1.6 m across (tables 0.6-0.8 m wide)
WIDTH_QUANTILE = 0.75


def reference_lengths(nodes: Iterable[Node], longest_whole: dict[str, float],
                      delta: Callable[[str], float], margin: float) -> dict[str, float]:
    """Per category, the length of its objects that tells a part from a whole: the longest
    whole view, and for a big category at least the length that ``FOOTPRINT_SHARE`` of its
    nodes' footprints reach (the ``FOOTPRINT_RANK``-th longest at least). Big (a table, not
    a chair): a whole view longer than ``delta(category)`` plus ``margin``, or one longer
    than delta_c and ``BIG_SHARE`` of its nodes' footprints longer than delta_c plus ``margin``,
    or one longer than delta_c minus ``margin`` and ``MOST_SHARE`` of the footprints longer
    than delta_c plus twice ``margin``.
    Categories with no whole view have none."""
    lengths: dict[str, list[float]] = {}
    for v in nodes:
        if v.footprint is not None:
            lengths.setdefault(v.category, []).append(longest_side(v.footprint))
    out = dict(longest_whole)
    for category, whole in longest_whole.items():
        sides = lengths.get(category, [])
        reached = footprint_length(sides)
        small = delta(category) + margin
        long_share = float(np.mean(np.asarray(sides) > small)) if sides else 0.0
        most_long = float(np.mean(np.asarray(sides) > small + margin)) if sides else 0.0
        big = whole > small or (whole > delta(category) and long_share >= BIG_SHARE) \
            or (whole > delta(category) - margin and most_long >= MOST_SHARE)
        if reached is not None and big:
            out[category] = max(whole, reached)
    return out


def longer_than_one(a: Node, b: Node, reference: dict[str, float], delta: Callable[[str], float],
                    margin: float, hidden: float) -> bool:
    """Whether ``a`` and ``b`` (one category), folded into one node, would make a footprint
    longer than one object of their category (``reference``: :func:`reference_lengths`, plus
    ``margin``, and in a big category ``hidden`` more, as :func:`part_pairs` allows) and
    longer than either footprint alone. A view whose mask bled from one table over the end of
    its neighbour, set at right angles 0.6 m away, covered both tables' nodes, and the fold
    made them one table 2.7 m long (bookstore map at 0.025 m, generated world seed 8451)."""
    length = reference.get(a.category)
    if length is None or a.footprint is None or b.footprint is None:
        return False
    limit = length + margin + (hidden if length > delta(a.category) + margin else 0.0)
    joint = longest_side(union(a.footprint, b.footprint))
    return joint > max(limit, longest_side(a.footprint), longest_side(b.footprint))


def footprint_length(sides: list[float]) -> float | None:
    """The length (m) that ``FOOTPRINT_SHARE`` of a category's footprints reach, and at
    least the ``FOOTPRINT_RANK``-th longest of ``sides`` (their longest sides); None with
    fewer footprints than that."""
    rank = max(FOOTPRINT_RANK, math.ceil(FOOTPRINT_SHARE * len(sides)))
    return sorted(sides, reverse=True)[rank - 1] if len(sides) >= rank else None


def part_pairs(nodes: Iterable[Node], reference: dict[str, float], margin: float,
               seen_apart: Callable[[int, int], bool], big: Container[str] = (),
               hidden: float = 0.0) -> list[tuple[Node, Node]]:
    """Pairs of nodes that are parts of one object, each node in at most one pair, nearest
    first (ties by ids); ``reference``: :func:`reference_lengths`. In a ``big`` category
    only the shorter of the two must be a part, measured along the joint box's long axis
    (the other may be most of the object), the joint box may be ``hidden`` (m) longer
    than the reference, and in a big category no wider (its shorter side) than three in four
    of the category's footprints that are no parts (:func:`_width`) plus ``margin``."""
    by_category: dict[str, list[Node]] = {}
    for v in nodes:
        whole = reference.get(v.category)
        if v.footprint is not None and whole is not None and (
                v.category in big or longest_side(v.footprint) <= PART_SHARE * whole):
            by_category.setdefault(v.category, []).append(v)
    candidates = []
    for category, parts in by_category.items():
        is_big = category in big
        limit = reference[category] + margin + (hidden if is_big else 0.0)
        part = PART_SHARE * reference[category]
        width = _width([shortest_side(v.footprint) for v in parts if longest_side(v.footprint) > part]) \
            if is_big else None
        for i, a in enumerate(parts):
            for b in parts[i + 1:]:
                joint = union(a.footprint, b.footprint)
                shorter = min(_held(a.footprint, joint), _held(b.footprint, joint)) if is_big \
                    else min(longest_side(a.footprint), longest_side(b.footprint))
                wide = _too_wide(a.footprint, b.footprint, joint, width, margin)
                if shorter <= part and longest_side(joint) <= limit and not wide and not seen_apart(a.id, b.id):
                    gap = float(np.hypot(*(a.position[:2] - b.position[:2])))
                    candidates.append((gap, min(a.id, b.id), max(a.id, b.id), a, b))
    candidates.sort(key=lambda c: c[:3])
    used: set[int] = set()
    pairs = []
    for _, _, _, a, b in candidates:
        if a.id not in used and b.id not in used:
            used |= {a.id, b.id}
            pairs.append((a, b))
    return pairs


def _width(sides: list[float]) -> float | None:
    """How wide (m) a category's objects are: the ``WIDTH_QUANTILE`` of the shorter sides
    of its whole footprints; None with fewer than ``FOOTPRINT_RANK`` of them."""
    return float(np.quantile(sides, WIDTH_QUANTILE)) if len(sides) >= FOOTPRINT_RANK else None


def _too_wide(a: np.ndarray, b: np.ndarray, joint: np.ndarray, width: float | None, margin: float) -> bool:
    """Whether two boxes together are wider across (the ``joint`` box's shorter side) than
    one object of the category, ``width`` (None: no limit), plus ``margin``; not when that is
    only one box's bleed: the other is no wider than the object, the wider one no more than a
    margin on each side wider (what a mask bleeds over), and the joint box no wider than the
    wider box (the two lie along one line, as a table's ends do). A table's end whose mask
    bled over the chairs on both sides reached 1.23 m across, its other end 0.93 m, the tables
    0.9 m: its two ends were left two tables (36 x 28 m office, seed 7914, pass 1). Two tables
    side by side, or two doors across a corridor, lie beside each other across it; two doors
    at a corner, one along the joint box and one across it (1.0-1.1 m across, doors 0.3 m), are
    no bleed (the same office with the rule first written without that bound: the two were
    joined in pass 2, and the door along the box was found again, added and joined, pass
    after pass)."""
    if width is None or shortest_side(joint) <= width + margin:
        return False
    axis = 1 if joint[2] - joint[0] >= joint[3] - joint[1] else 0  # across the joint box
    narrow, wide = sorted(float(box[axis + 2] - box[axis]) for box in (a, b))
    return not (narrow <= width + margin and wide <= width + 2.0 * margin and shortest_side(joint) <= wide + margin)


def _held(box: np.ndarray, joint: np.ndarray) -> float:
    """How much of ``joint``'s long side ``box`` spans (m): a part's share of the length."""
    axis = 0 if joint[2] - joint[0] >= joint[3] - joint[1] else 1
    return float(box[axis + 2] - box[axis])


def parts_of_gone(gone: Iterable[Node], arrivals: Iterable[Node], margin: float,
                  seen_apart: Callable[[int, int], bool], unlike: Callable[[Node, Node], bool],
                  small: Callable[[str], float]) -> list[tuple[Node, Node]]:
    """Pairs of nodes the pass added that are two parts of one object it removed: a big
    object carried off and seen at its new place in two parts, never both in one frame. The
    object's own footprint from earlier passes tells how big it is where the category's
    views this pass do not (one sofa on the floor, seen whole only as a sliver). ``gone``:
    nodes of earlier passes the pass removed; a pair joins when it is of the gone node's
    category and look (``unlike``: their colours tell them apart), the gone node is big (its
    footprint longer than ``small(category)``), the pair's joint box is no bigger than the gone
    node's footprint in either direction (plus ``margin``) and the shorter of the two is a part
    of that length (``PART_SHARE``). Each node is in at most one pair, nearest pairs first."""
    arrivals = [a for a in arrivals if a.footprint is not None]
    candidates = []
    for v in gone:
        if v.footprint is None or longest_side(v.footprint) <= small(v.category):
            continue
        length, across = longest_side(v.footprint) + margin, shortest_side(v.footprint) + margin
        mine = [a for a in arrivals if a.category == v.category and not unlike(v, a)]
        for i, a in enumerate(mine):
            for b in mine[i + 1:]:
                joint = union(a.footprint, b.footprint)
                shorter = min(_held(a.footprint, joint), _held(b.footprint, joint))
                if (longest_side(joint) <= length and shortest_side(joint) <= across
                        and shorter <= PART_SHARE * longest_side(v.footprint) and not seen_apart(a.id, b.id)):
                    gap = float(np.hypot(*(a.position[:2] - b.position[:2])))
                    candidates.append((gap, v.id, min(a.id, b.id), max(a.id, b.id), a, b))
    candidates.sort(key=lambda c: c[:4])
    used: set[int] = set()
    pairs = []
    for _, v_id, _, _, a, b in candidates:
        if not {v_id, a.id, b.id} & used:
            used |= {v_id, a.id, b.id}
            pairs.append((a, b))
    return pairs
