"""Detection rates per viewing side: where a node is missed from, remembered over passes.

A detector's misses are tied to views, not only to frames: a door leaf on a corridor's side
wall, seen from along the corridor, is a sliver the detector misses whenever the robot
drives there, and a chair behind a table leg is hidden from one side only. Robust
association removes a node on a run of misses that would be unlikely for a present object
(:func:`~bomc_bt.graph.evidence.misses_needed`), judged by the node's detection rate in the
frames of this pass. A door well seen face-on has a high rate, and three misses in a row
from along its corridor removed it (issue 17, ``hard`` preset, 36 x 28 m office, seed 9781:
17 of 20 phantoms over 12 passes were doors removed so and found again a pass or two later,
the same five doors again and again).

So each node keeps, per *side* (``association.miss_sides`` equal sectors of bearing from the
node to where the robot stood), how many of the frames that expected it from there saw it
and how much miss weight they counted in runs a later detection refuted: the misses of a
present object. A run of misses is judged by the lowest rate of the sides it was seen from,
or the pass's own rate when that is lower (:meth:`SideRates.rate`). A run that removes the
node teaches nothing (the object was gone); one a detection ends does. What a pass learnt is
carried into the next one, its counts weighed by ``association.side_memory`` (saved with the
resume point, :mod:`bomc_bt.pass_resume`): the robot drives the same corridors every pass,
and where a view missed a present door before, a miss from there is weak evidence again.

A side seen from seldom or never borrows the node's rate over all its sides (the prior
where it has none): a door the detector misses from every side it was seen from is no
easier to remove from a new one. A door 1.5 m in front of the robot, missed three frames in
a row from a side no pass had seen it from before, was removed so, its rate from the side
beside it 1.7 detections against 9.4 misses (the same office, pass 7). A node the map first
holds has no sides yet, so the first views of a duplicate or a false detection remove it as
before. The price: a look-alike detected from the side it is mistaken from and missed from
the others, the misses ended by its next detection, learns that it is often missed, and
stays longer -- the evidence says no more.

A node removed on a run of misses and found again at its place in a later pass (brought
back, :mod:`bomc_bt.graph.brought_back`) was most often never gone: the views that removed
it missed it. The node found there takes the removed node's counts, and that run counts as
refuted misses on its sides (:meth:`SideRates.bring_back`; the counts and runs of nodes gone
on evidence are carried with the rest while they may come back, until faded to ``FADED``). Without it each
return started afresh and the same views removed it again: on a generated 36 x 28 m office
under the ``hard`` preset (seed 9941, 12 passes) a door was removed in passes 1, 2 and 4
and found again in passes 2, 3 and 5, another removed in passes 7 and 11 and found in 10.
A chair truly taken away and brought back to its place pays for it: the views that saw it
go count as misses of a present chair, so its next removal from there needs a longer run
(at most ``max_misses``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from bomc_bt.json_text import JSONMemo, keyed

Counts = tuple[float, ...]  # per node: seen per side, then missed per side (replaced, never changed in place)
FADED = 0.01  # frames' worth: counts faded below this over the passes are dropped (a node gone for many passes)
CLEAR = 0.05  # frames' worth of refuted misses below which a side never missed a present node (one faded 5 passes)


def side_of(node_xy: Sequence[float], place: Sequence[float], sides: int) -> int:
    """The sector (0 .. ``sides`` - 1) of the bearing from the node to the robot's ``place``."""
    bearing = math.atan2(float(place[1]) - float(node_xy[1]), float(place[0]) - float(node_xy[0]))
    return int(math.floor((bearing + math.pi) / (2.0 * math.pi) * sides)) % sides


class SideRates:
    """Per node and side: detections, and miss weight refuted by a later detection."""

    def __init__(self, sides: int, memory: float) -> None:
        self.sides = sides
        self.memory = memory
        self.counts: dict[int, Counts] = {}
        self._runs: dict[int, dict[int, float]] = {}  # the current run's miss weight per side
        self.removals: dict[int, dict[int, float]] = {}  # per removed node: the run that removed it, per side

    def seen(self, node_id: int, side: int) -> None:
        """An expected frame from ``side`` detected the node (counted once per interval)."""
        self._add(node_id, side, 1.0, 0)

    def missed(self, node_id: int, side: int, weight: float) -> None:
        """A counted miss of ``weight`` from ``side``, part of the node's current run."""
        run = self._runs.setdefault(node_id, {})
        run[side] = run.get(side, 0.0) + weight

    def end_run(self, node_id: int, refuted: bool) -> None:
        """The run is over: a detection ``refuted`` it (its misses were a present object's,
        counted to their sides) or the node left the graph (they were not)."""
        run = self._runs.pop(node_id, None)
        if refuted and run:
            for side, weight in run.items():
                self._add(node_id, side, weight, self.sides)
        elif run:
            self.removals[node_id] = run

    def bring_back(self, node_id: int, gone_id: int) -> None:
        """Node ``node_id`` is the object ``gone_id`` stood for, back at its place: it takes that
        node's counts, and the run of misses that removed it counts as refuted on its sides (the
        object was there; those views missed it)."""
        counts = np.zeros(2 * self.sides)
        for i in (node_id, gone_id):
            if len(c := self.counts.get(i, ())) == 2 * self.sides:
                counts += np.asarray(c)
        for side, weight in self.removals.pop(gone_id, {}).items():
            counts[self.sides + side] += weight
        self.counts[node_id] = tuple(round(float(x), 6) for x in counts)
        self.counts.pop(gone_id, None)

    def forget(self, node_id: int) -> None:
        """The node's object moved: its sides start afresh."""
        self.counts.pop(node_id, None)
        self._runs.pop(node_id, None)

    def run_sides(self, node_id: int) -> list[int]:
        return sorted(self._runs.get(node_id, ()))

    def run_clear(self, node_id: int) -> bool:
        """Whether the sides the current run of misses was seen from had detected the node (a
        frame's worth or more, earlier passes' weighed by ``memory``) and had not missed it while
        it stood there (less than ``CLEAR`` of refuted miss weight): misses from such sides are
        evidence of absence even moments after a sighting; from others they may be the view's."""
        counts, run = self.counts.get(node_id), self._runs.get(node_id, {})
        if counts is None or not run:
            return False
        seen = sum(counts[side] for side in run)
        return seen >= 1.0 and sum(counts[self.sides + side] for side in run) < CLEAR

    def rate(self, node_id: int, sides: Sequence[int], prior: float, weight: float) -> float:
        """The lowest detection rate among ``sides``: each side's counts with ``weight`` frames'
        worth of the node's rate over all sides, itself with ``weight`` frames' worth of ``prior``."""
        counts = self.counts.get(node_id)
        if counts is None or not sides:
            return prior
        c = np.asarray(counts).reshape(2, self.sides)
        pooled = (c[0].sum() + prior * weight) / (c.sum() + weight)
        seen, missed = c[0, list(sides)], c[1, list(sides)]
        return float(np.min((seen + pooled * weight) / (seen + missed + weight)))

    def _add(self, node_id: int, side: int, value: float, offset: int) -> None:
        counts = list(self.counts.get(node_id) or (0.0,) * (2 * self.sides))
        counts[offset + side] += value
        self.counts[node_id] = tuple(counts)

    def carry(self, state: dict | None, keep: set[int]) -> None:
        """Start a pass with what an earlier pass saved (:meth:`to_json`) of the nodes in ``keep``
        (those on the map, and those gone that may come back), weighed by ``memory``."""
        if self.memory <= 0.0:
            return
        for node_id, c in carried_counts(state, self.sides).items():
            if node_id in keep and len(c) == 2 * self.sides and self.memory * sum(c) >= FADED:
                self.counts[node_id] = tuple(round(self.memory * float(x), 6) for x in c)
        for node_id, run in _runs_of(state, "removals", self.sides).items():
            if node_id in keep and self.memory * sum(run.values()) >= FADED:
                self.removals[node_id] = {side: round(self.memory * w, 6) for side, w in run.items()}

    def to_json(self, memo: JSONMemo | None = None) -> dict:
        """JSON-able state (``memo``: the counts as text, each node's encoded again only when it changed)."""
        return {"sides": self.sides, "counts": keyed(memo, "side_counts", self.counts.items(), list),
                "runs": _runs_json(self._runs), "removals": _runs_json(self.removals)}

    def restore(self, state: dict) -> None:
        """Put back what :meth:`to_json` saved in this pass (a resumed pass), if its sides are these."""
        if int(state.get("sides", -1)) != self.sides:
            return
        self.counts = {int(i): tuple(float(x) for x in c) for i, c in state.get("counts", {}).items()}
        self._runs = _runs_of(state, "runs", self.sides)
        self.removals = _runs_of(state, "removals", self.sides)


def carried_counts(state: dict | None, sides: int) -> dict[int, Counts]:
    """The per-node counts a pass's saved :meth:`SideRates.to_json` holds (none when its sides differ)."""
    if not isinstance(state, dict) or int(state.get("sides", -1)) != sides:
        return {}
    return {int(i): tuple(float(x) for x in c) for i, c in state.get("counts", {}).items()}


def _runs_json(runs: dict[int, dict[int, float]]) -> dict:
    return {str(i): {str(s): w for s, w in run.items()} for i, run in runs.items()}


def _runs_of(state: dict | None, key: str, sides: int) -> dict[int, dict[int, float]]:
    """Runs of misses per node and side saved under ``key`` (none when the sides differ)."""
    if not isinstance(state, dict) or int(state.get("sides", -1)) != sides:
        return {}
    return {int(i): {int(s): float(w) for s, w in run.items()} for i, run in (state.get(key) or {}).items()}
