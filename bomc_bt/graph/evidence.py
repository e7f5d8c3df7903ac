"""The evidence of absence robust association weighs before it removes a node.

Per node, in this process only (a new pass starts from the prior): how many frames that
expected the node saw it, how much miss weight piled up before the current run of misses,
and the weight of that run; per viewing side, carried over passes, the same counts
(:mod:`bomc_bt.graph.view_sides`); with ``association.miss_spacing``, the nodes an earlier
pass ended awaiting a second look (:attr:`MissEvidence.looked_before`), also carried. A miss
weighs 1 when the frame had a clear, near view of the node and less farther away (see
:func:`bomc_bt.perception.expected.miss_weights`); a detection ends the run and adds it to
the node's record of misses. Robust association (:func:`misses_needed`) compares the run
with what the node's own detection rate makes convincing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from bomc_bt.graph.view_sides import SideRates


@dataclass
class DetectionRecord:
    seen: float = 0.0  # expected frames that detected the node (at most one per interval)
    missed: float = 0.0  # miss weight before the current run of misses
    run: float = 0.0  # miss weight of the current run
    last_seen: float = -math.inf  # robot time of the last counted detection
    run_from: tuple[float, float] | None = None  # robot (x, y) at the current run's first miss
    run_spread: float = 0.0  # m: farthest robot place of the run from run_from (inf: no places given)


class MissEvidence:
    """Detection records of the graph's nodes."""

    def __init__(self, sides: SideRates | None = None) -> None:
        self._records: dict[int, DetectionRecord] = {}
        self.sides = sides  # per viewing side, carried over passes (None: one rate per node)
        # Nodes an earlier pass ended awaiting a second look (a run of misses that would remove
        # them, all from one place, no detection since): that pass's misses were one look, so a
        # run from one place in this pass is the second, at another time. Without it a chair
        # taken from beside a table and a wall, its place seen only from one stop each pass,
        # stayed on the map for ten passes, 13 clear misses a pass (36 x 28 m office, seed 10101).
        self.looked_before: set[int] = set()

    def seen(self, node_id: int, stamp: float, interval: float, side: int | None = None) -> None:
        """An expected frame (from ``side``, when known) detected the node: count it (once per
        ``interval``), end the run."""
        r = self._records.setdefault(node_id, DetectionRecord())
        self._end_run(node_id, r, refuted=True)
        if stamp - r.last_seen >= interval:
            r.seen += 1.0
            r.last_seen = stamp
            if self.sides is not None and side is not None:
                self.sides.seen(node_id, side)

    def missed(self, node_id: int, weight: float, place: Sequence[float] | None = None,
               side: int | None = None) -> float:
        """A counted miss of ``weight``, seen with the robot at ``place`` (x, y; from ``side``,
        when known); returns the run's weight."""
        if self.sides is not None and side is not None:
            self.sides.missed(node_id, side, weight)
        r = self._records.setdefault(node_id, DetectionRecord())
        if place is None:
            r.run_spread = math.inf
        elif r.run == 0.0 or r.run_from is None:
            r.run_from = (float(place[0]), float(place[1]))
        else:
            r.run_spread = max(r.run_spread, math.hypot(place[0] - r.run_from[0], place[1] - r.run_from[1]))
        r.run += weight
        return r.run

    def spread(self, node_id: int) -> float:
        """How far apart (m) the robot's places in the node's current run of misses lie, from
        its first: one place is one look, however many frames it took (inf: places unknown)."""
        r = self._records.get(node_id)
        return 0.0 if r is None else r.run_spread

    def apart(self, node_id: int, spacing: float) -> bool:
        """Whether the node's current run of misses counts as looks from ``spacing`` (m) apart:
        its places lie that far apart, or an earlier pass ended with a look of its own at the
        node that no detection has answered since (:attr:`looked_before`)."""
        return self.spread(node_id) >= spacing or node_id in self.looked_before

    def looks_json(self, awaiting: Iterable[int]) -> dict:
        """The second looks' state a pass saves (JSON-able): the nodes it began with an earlier
        pass's look at (:attr:`looked_before`, still standing) and those ``awaiting`` one now;
        the next pass begins with both (:func:`bomc_bt.pass_resume.earlier_looks`)."""
        return {"before": sorted(self.looked_before), "awaiting": sorted(awaiting)}

    def run_place(self, node_id: int) -> tuple[float, float] | None:
        """Where the robot stood (x, y) at the first miss of the node's current run (None: no run)."""
        r = self._records.get(node_id)
        return None if r is None or r.run == 0.0 else r.run_from

    def run(self, node_id: int) -> float:
        r = self._records.get(node_id)
        return 0.0 if r is None else r.run

    def forget(self, node_id: int, refuted: bool = False) -> None:
        """The node's run is over: a detection ``refuted`` it, or the node left the graph."""
        r = self._records.get(node_id)
        if r is not None:
            self._end_run(node_id, r, refuted)

    def _end_run(self, node_id: int, r: DetectionRecord, refuted: bool) -> None:
        if self.sides is not None:
            self.sides.end_run(node_id, refuted)
        self.looked_before.discard(node_id)  # seen (the misses were a detector's) or gone
        r.missed += r.run
        r.run = 0.0
        r.run_from, r.run_spread = None, 0.0

    def detection_rate(self, node_id: int, prior: float, weight: float) -> float:
        """How often the frames that expected the node saw it before its current run, with
        ``weight`` frames' worth of ``prior``: the rate a present object would show."""
        r = self._records.get(node_id, DetectionRecord())
        return (r.seen + prior * weight) / (r.seen + r.missed + weight)

    def sides_prove_absence(self, node_id: int) -> bool:
        """Whether the node's current run is evidence of absence whatever came just before it: its
        viewing sides unknown (``association.miss_sides`` 0, no robot place: no view to blame), or
        sides that saw the node and never missed it while present (:meth:`SideRates.run_clear`)."""
        return self.sides is None or not self.sides.run_sides(node_id) or self.sides.run_clear(node_id)

    def run_rate(self, node_id: int, prior: float, weight: float) -> float:
        """The rate the node's current run is judged by: :meth:`detection_rate`, or the lowest
        rate of the sides the run was seen from when that is lower."""
        rate = self.detection_rate(node_id, prior, weight)
        if self.sides is None:
            return rate
        return min(rate, self.sides.rate(node_id, self.sides.run_sides(node_id), prior, weight))


def misses_needed(rate: float, prior: float, confirm_misses: int, max_misses: int) -> int:
    """Consecutive counted misses that remove a node detected in a share ``rate`` of the
    frames that expected it: ``confirm_misses`` for one detected as often as ``prior`` says,
    more for one those frames often missed (a door leaf seen through its doorway, an object
    at the edge of the camera's reach). A present object detected in a share p of the
    frames is missed k times in a row with probability (1 - p)^k; k is chosen so that this
    chance is no larger than at the prior rate with ``confirm_misses`` (at most ``max_misses``)."""
    if rate >= prior:
        return confirm_misses
    if rate <= 0.0:
        return max_misses
    need = math.ceil(confirm_misses * math.log(1.0 - prior) / math.log(1.0 - rate) - 1e-9)
    return int(min(max(confirm_misses, need), max_misses))
