"""Shorter tours: iterated local search over a matrix of driving distances.

2-opt and Or-opt from a nearest-neighbour start stop at the first tour no single move
improves. On a coverage tour of a few hundred stops over a building (rooms off corridors,
each entered and left by its door) more search finds shorter tours: 4.4 % off the
2,899 m local optimum of a 93 x 90 m floor's 328 stops (docs/exploration.md 7.18), and at
0.6 m/s every 100 m is three minutes of the robot's time in every pass. So, after them,
:func:`improve_cycle` runs the classic remedy (Johnson & McGeoch's iterated local
search, as in LKH's and Concorde's linkern kicks, in its simplest form):

1. Local search to a local optimum: 2-opt and Or-opt (moving a run of one to three stops,
   either way round), each trying only moves that join a stop to one of its ``neighbours``
   nearest stops, and only around stops whose tour changed ("don't-look bits"). A sweep
   then costs a few operations per changed stop instead of a pass over all pairs.
2. A kick: a double bridge (two adjacent runs of the tour swap places) within a short
   stretch, which no single 2-opt move undoes (Or-opt only when a run is three places or
   fewer: a wasted kick); local search again from there.
3. The kicked tour is kept when it is shorter, else the best one so far is kicked again.

The random stretches come from a fixed seed, so a plan is the same every time it is made
from the same map. Distances are taken symmetric (``(d + d.T) / 2``: driving there and back
is the same way, as :func:`bomc_bt.path_matrix.path_length_matrix` gives them); a stop that
cannot be reached must carry a large finite distance, not inf.

An open path with a fixed first stop (the robot's position) is a cycle through one more
place, the path's free end, that is 0 from the first stop and equally far from all others
(:func:`open_path_matrix`): every tour pays that constant once, so the best cycle is the
best path.
"""

from __future__ import annotations

import random

import numpy as np

_EPS = 1e-9


def open_path_matrix(d: np.ndarray) -> np.ndarray:
    """(n + 1)-square matrix whose best cycle, cut at the extra last place, is the best
    open path over ``d`` from place 0 (its end anywhere)."""
    n = len(d)
    far = 2.0 * float(np.max(d)) + 1.0 if n else 1.0
    out = np.full((n + 1, n + 1), far)
    out[:n, :n] = d
    out[n, 0] = out[0, n] = 0.0
    out[n, n] = 0.0
    return out


def cycle_length(d: np.ndarray, tour: list[int]) -> float:
    return float(sum(d[a, b] for a, b in zip(tour, tour[1:] + tour[:1], strict=True)))


def improve_cycle(d: np.ndarray, tour: list[int], kicks: int, neighbours: int = 10, seed: int = 0) -> list[int]:
    """A cycle no longer than ``tour`` over the places of ``d``, starting at ``tour[0]``.

    Local search, then ``kicks`` double-bridge kicks each followed by local search, keeping
    the best cycle found (see the module's text)."""
    n = len(tour)
    if n < 5:
        return list(tour)
    dm = (np.asarray(d, dtype=float) + np.asarray(d, dtype=float).T) / 2.0
    search = _Search(dm.tolist(), _nearest(dm, tour, neighbours), list(tour))
    search.run(set(tour))
    best, best_len = list(search.tour), cycle_length(dm, search.tour)
    rng = random.Random(seed)
    for _ in range(kicks):
        search.reset(best)
        search.run(search.double_bridge(rng))
        length = cycle_length(dm, search.tour)
        if length < best_len - _EPS:
            best, best_len = list(search.tour), length
    at = best.index(tour[0])
    return best[at:] + best[:at]


def _nearest(dm: np.ndarray, places: list[int], k: int) -> dict[int, list[int]]:
    """Each place's ``k`` nearest other places, nearest first."""
    idx = np.asarray(places)
    sub = dm[np.ix_(idx, idx)].copy()
    np.fill_diagonal(sub, np.inf)
    k = min(k, len(idx) - 1)
    part = np.argpartition(sub, k - 1, axis=1)[:, :k]
    out = {}
    for row, p in enumerate(places):
        cand = part[row][np.argsort(sub[row, part[row]], kind="stable")]
        out[p] = [int(idx[c]) for c in cand]
    return out


class _Search:
    """A cycle as an array and each place's position in it, with the moves that change it."""

    def __init__(self, d: list[list[float]], near: dict[int, list[int]], tour: list[int]):
        self.d, self.near = d, near
        self.reset(tour)

    def reset(self, tour: list[int]) -> None:
        self.tour = list(tour)
        self.n = len(tour)
        self.pos = {p: i for i, p in enumerate(self.tour)}

    def succ(self, p: int) -> int:
        return self.tour[(self.pos[p] + 1) % self.n]

    def pred(self, p: int) -> int:
        return self.tour[(self.pos[p] - 1) % self.n]

    def run(self, active: set[int]) -> None:
        """Local search until no move around an active place improves the cycle."""
        queue = list(active)
        queued = set(queue)
        while queue:
            a = queue.pop()
            queued.discard(a)
            touched = self._two_opt(a) or self._or_opt(a)
            for p in touched or ():
                if p not in queued:
                    queued.add(p)
                    queue.append(p)
            if touched:
                queued.add(a)
                queue.append(a)

    def _two_opt(self, a: int) -> list[int] | None:
        d = self.d
        for forward in (True, False):
            b = self.succ(a) if forward else self.pred(a)
            dab = d[a][b]
            for c in self.near[a]:
                g1 = dab - d[a][c]
                if g1 <= _EPS:
                    break
                e = self.succ(c) if forward else self.pred(c)
                if c == b or e == a:
                    continue
                if g1 + d[c][e] - d[b][e] > _EPS:
                    # forward: a b ... c e -> a c ... b e; backward: e c ... b a -> e b ... c a
                    if forward:
                        self._reverse(b, c)
                    else:
                        self._reverse(c, b)
                    return [a, b, c, e]
        return None

    def _or_opt(self, a: int) -> list[int] | None:
        """Move the run of 1-3 places starting at ``a`` (forward) next to a neighbour."""
        d = self.d
        for size in (1, 2, 3):
            if size > self.n - 3:
                break
            i = self.pos[a]
            seg = [self.tour[(i + k) % self.n] for k in range(size)]
            p, q = self.pred(seg[0]), self.succ(seg[-1])
            s0, s1 = seg[0], seg[-1]
            saved = d[p][s0] + d[s1][q] - d[p][q]
            if saved <= _EPS:
                continue
            best = None
            inside = set(seg)
            for end in (s0, s1):
                for c in self.near[end]:
                    if c in inside:
                        continue
                    for e in (self.succ(c), self.pred(c)):
                        if e in inside:
                            continue
                        # insert between c and e; the end touching c is chosen
                        base = d[c][e]
                        keep = d[c][s0] + d[s1][e] - base  # c s0 .. s1 e
                        flip = d[c][s1] + d[s0][e] - base  # c s1 .. s0 e
                        cost = min(keep, flip)
                        if saved - cost > _EPS and (best is None or cost < best[0]):
                            best = (cost, c, e, keep <= flip)
            if best is not None:
                _, c, e, keep = best
                self._move(seg, c, e, keep)
                return [p, q, c, e, s0, s1]
        return None

    def _reverse(self, x: int, y: int) -> None:
        """Reverse the stretch from ``x`` forward to ``y`` (or, being the same cycle, the rest)."""
        i, j = self.pos[x], self.pos[y]
        length = (j - i) % self.n + 1
        if 2 * length > self.n:
            i, j = (j + 1) % self.n, (i - 1) % self.n
            length = self.n - length
        t, pos = self.tour, self.pos
        for _ in range(length // 2):
            t[i], t[j] = t[j], t[i]
            pos[t[i]], pos[t[j]] = i, j
            i, j = (i + 1) % self.n, (j - 1) % self.n

    def _move(self, seg: list[int], c: int, e: int, keep: bool) -> None:
        """Take ``seg`` out and put it between the neighbours ``c`` and ``e``."""
        inside = set(seg)
        rest = [p for p in self.tour if p not in inside]
        at_c = rest.index(c)
        after = rest[(at_c + 1) % len(rest)] == e
        run = seg if keep else seg[::-1]  # reads c, run, e
        # e after c: c, run, e; e before c: e, the run reversed, c
        self.reset(rest[:at_c + 1] + run + rest[at_c + 1:] if after else rest[:at_c] + run[::-1] + rest[at_c:])

    def double_bridge(self, rng: random.Random, stretch: int = 30) -> set[int]:
        """Swap two adjacent runs of the cycle within a stretch of at most ``stretch`` places
        (A B C D -> A C B D); returns the places whose neighbours changed."""
        n = self.n
        span = min(stretch, n - 1)
        start = rng.randrange(n)
        cuts = sorted(rng.sample(range(1, span + 1), 3))
        t = self.tour[start:] + self.tour[:start]
        i, j, k = cuts
        new = t[:i] + t[j:k] + t[i:j] + t[k:]
        self.reset(new)
        ends = {t[i - 1], t[i], t[j - 1], t[j], t[k - 1], t[k % n]}
        return ends
