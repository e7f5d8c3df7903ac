"""Where a site's objects change: a rate per map region, learned from the site's passes.

A pass with a budget (:mod:`bomc_bt.budget_plan`) should look first where changes are
waiting. Changes come at different rates in different places (a meeting room's chairs
move every day, a corridor's doors never), and a change waits until a pass looks: so the
changes waiting in a region are its rate times the passes since it was last seen.

Regions are squares of ``budget.region_size`` on the map (a room-sized tile: rooms and
corridor stretches both fall into a few). After every pass :func:`region_rows` records
per region how much of its floor the camera looked at (saw within ``budget.view_range``:
the coverage's ``near`` part; a room glimpsed from the corridor through its door is not
looked at, and a change there cannot be confirmed) and how many changes the pass found
there: its net changes (:func:`bomc_bt.net_changes.net_changes`: ``added``, ``removed``,
``moved``, a move at both ends), not its raw events, for a node added and taken off again
in one pass, or taken off and found again where it stood (a door seen from both sides, a
miss count run out behind a chair), changed nothing, and counted as change such noise
makes a corridor look like a meeting room to the budgeted planner; a change counts
only in a region seen by an earlier pass (the first look adds everything, which is the
map being built, not change). :class:`ChangeModel` reads those rows back: each region's
rate is the Poisson estimate ``(changes + prior_rate * prior_weight) / (exposure +
prior_weight)``. Only looks at ``budget.seen_share`` of a region or more count, and each
adds as exposure the passes since the last such look times the share it looked at (a
look at half a room is expected to find half its changes): a glimpse that could not have
found a change must not teach the model that none happen there, else a hot room that
budgeted passes only glimpse cools in the model and drops out of their tours. A region
with no history has the uniform prior rate and history moves it from there.
The rows live in the site store's ``region_passes`` table (schema version 4).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.algorithm_params import BudgetParams
from bomc_bt.grid import OccupancyGrid
from bomc_bt.net_changes import NET_KINDS, NetChange


@dataclass(frozen=True)
class RegionGrid:
    """The square regions of one map: ``n`` map cells a side, counted from the map origin."""

    grid: OccupancyGrid
    size: float  # [m] the configured side (the key rows are stored under)

    @property
    def n(self) -> int:
        return max(1, int(round(self.size / self.grid.resolution)))

    @property
    def shape(self) -> tuple[int, int]:
        h, w = self.grid.data.shape
        return -(-h // self.n), -(-w // self.n)

    def per_region(self, mask: np.ndarray) -> np.ndarray:
        """(I, J) count of the true cells of a map-sized ``mask`` in each region."""
        h, w = mask.shape
        i, j = self.shape
        padded = np.zeros((i * self.n, j * self.n), dtype=np.int64)
        padded[:h, :w] = mask
        return padded.reshape(i, self.n, j, self.n).sum(axis=(1, 3))

    def floor(self) -> np.ndarray:
        """(I, J) free cells per region; a region without floor is no region."""
        return self.per_region(self.grid.free_mask())

    def index(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Region (i, j) of map-frame points and whether each lies on the map."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        rows, cols = self.grid.world_to_cell(xy[:, 0], xy[:, 1])
        h, w = self.grid.data.shape
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        return rows // self.n, cols // self.n, inside

    def centre(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """(K, 2) map-frame centres of regions."""
        mid = (self.n - 1) / 2
        x, y = self.grid.cell_to_world(np.asarray(i) * self.n + mid, np.asarray(j) * self.n + mid)
        return np.stack([np.asarray(x, float), np.asarray(y, float)], axis=-1).reshape(-1, 2)


class ChangeModel:
    """Per region: passes seen, changes found, rate, last pass seen; built from stored rows."""

    def __init__(self, regions: RegionGrid, params: BudgetParams, rows: Iterable[tuple] = ()):
        self.regions, self.params = regions, params
        shape = regions.shape
        self.floor = regions.floor()
        self.changes = np.zeros(shape, dtype=float)
        self.exposure = np.zeros(shape, dtype=float)  # passes between the looks that counted
        self.last_seen = np.zeros(shape, dtype=np.int64)  # session; 0: never seen
        self.seen_passes = np.zeros(shape, dtype=np.int64)
        for session, size, i, j, seen, changes, _stamp in sorted(rows):
            if abs(size - regions.size) > 1e-9 or not (0 <= i < shape[0] and 0 <= j < shape[1]):
                continue  # another region size, or another map's region: not this model's
            if seen < params.seen_share:
                continue
            if self.last_seen[i, j]:  # a look finds the share ``seen`` of the changes since the last
                self.exposure[i, j] += (session - self.last_seen[i, j]) * min(1.0, seen)
                self.changes[i, j] += changes
            self.last_seen[i, j] = session
            self.seen_passes[i, j] += 1

    @property
    def rate(self) -> np.ndarray:
        """(I, J) changes per pass: the uniform prior, moved by the history."""
        p = self.params
        return (self.changes + p.prior_rate * p.prior_weight) / (self.exposure + p.prior_weight)

    def passes_since(self, session: int) -> np.ndarray:
        """(I, J) passes since each region was last seen, as of the start of ``session``."""
        return np.maximum(session - self.last_seen, 0)

    def waiting(self, session: int) -> np.ndarray:
        """(I, J) expected changes waiting at the start of ``session`` (0 where there is no floor)."""
        since = np.minimum(self.passes_since(session), self.params.max_wait)
        return np.where(self.floor > 0, self.rate * since, 0.0)

    def to_json(self, session: int) -> dict:
        """The model as the viewer and the report show it: one entry per region with floor."""
        ii, jj = np.nonzero(self.floor > 0)
        centres = self.regions.centre(ii, jj)
        rate, since, waiting = self.rate, self.passes_since(session), self.waiting(session)
        half = self.regions.n * self.regions.grid.resolution / 2
        return {"session": session, "size_m": round(2 * half, 3), "regions": [
            {"i": int(i), "j": int(j), "x": round(float(c[0]), 2), "y": round(float(c[1]), 2),
             "rate": round(float(rate[i, j]), 3), "seen_passes": int(self.seen_passes[i, j]),
             "last_seen": int(self.last_seen[i, j]) or None, "passes_since": int(since[i, j]),
             "waiting": round(float(waiting[i, j]), 3)} for i, j, c in zip(ii, jj, centres, strict=True)]}


def region_rows(regions: RegionGrid, seen: np.ndarray, changes: Iterable[NetChange], session: int,
                stamp: float | None, model: ChangeModel, objects: np.ndarray | None = None,
                object_reach: float = 0.5) -> list[tuple]:
    """The rows one pass adds: per region with floor, the share of it looked at and the changes found.

    ``seen`` is the map-sized mask of the floor the pass looked at, ``changes`` its net
    changes, and ``model`` the history before it (a change counts only where an earlier
    pass looked). ``objects`` ((K, 2) map-frame places of the objects the map had when the
    pass began) make the share of a region with objects the share of its objects looked
    at (within ``object_reach`` m): changes happen at objects (a chair moved, a bin taken
    away), so a look at a room's empty half could not have found them.
    """
    share = look_share(regions, seen, objects, object_reach)
    floor = regions.floor()
    points = []
    for c in changes:  # a node first seen (no earlier pass had looked there) is no change
        if c.kind in NET_KINDS:
            points += [np.asarray(p, float)[:2] for p in (c.old, c.new) if p is not None]
    found = np.zeros(floor.shape, dtype=np.int64)
    if points:
        i, j, inside = regions.index(np.array(points))
        ok = inside & (i < floor.shape[0]) & (j < floor.shape[1])
        np.add.at(found, (i[ok], j[ok]), 1)
    found = np.where(model.last_seen > 0, found, 0)  # the first look builds the map: no change
    ii, jj = np.nonzero(floor > 0)
    return [(session, regions.size, int(i), int(j), round(float(share[i, j]), 4), int(found[i, j]),
             None if stamp is None else float(stamp)) for i, j in zip(ii, jj, strict=True)]


def look_share(regions: RegionGrid, seen: np.ndarray, objects: np.ndarray | None = None,
               object_reach: float = 0.5) -> np.ndarray:
    """(I, J) share of each region a pass looked at: of its objects where it has any
    (an object counts when ``seen`` reaches within ``object_reach`` m of it), else of its floor."""
    floor = regions.floor()
    seen = seen.astype(bool)
    share = np.where(floor > 0, regions.per_region(seen & regions.grid.free_mask()) / np.maximum(floor, 1), 0.0)
    if objects is None or not len(objects):
        return share
    k = max(1, int(round(object_reach / regions.grid.resolution)))
    reach = cv2.dilate(seen.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1)))
    i, j, inside = regions.index(np.asarray(objects, float)[:, :2])
    rows, cols = regions.grid.world_to_cell(np.asarray(objects, float)[:, 0], np.asarray(objects, float)[:, 1])
    ok = inside & (i < share.shape[0]) & (j < share.shape[1])
    looked = np.zeros(share.shape)
    count = np.zeros(share.shape)
    np.add.at(count, (i[ok], j[ok]), 1.0)
    np.add.at(looked, (i[ok], j[ok]), reach[rows[ok], cols[ok]].astype(float))
    return np.where((count > 0) & (floor > 0), looked / np.maximum(count, 1.0), share)


def skipped_regions(model: ChangeModel, rows: list[tuple], session: int) -> list[dict]:
    """Regions this pass did not see (``rows``: its own rows), with how stale each now is:
    passes since last seen and the changes expected to be waiting there, most first."""
    seen = {(i, j) for _s, _z, i, j, share, _c, _t in rows if share >= model.params.seen_share}
    after = model.passes_since(session + 1)
    waiting = model.rate * np.minimum(after, model.params.max_wait)
    out = []
    for _s, _z, i, j, _share, _c, _t in rows:
        if (i, j) in seen:
            continue
        c = model.regions.centre(np.array([i]), np.array([j]))[0]
        out.append({"x": round(float(c[0]), 2), "y": round(float(c[1]), 2),
                    "last_seen": int(model.last_seen[i, j]) or None, "passes_since_seen": int(after[i, j]),
                    "expected_waiting": round(float(waiting[i, j]), 3)})
    return sorted(out, key=lambda r: (-r["expected_waiting"], r["x"], r["y"]))
