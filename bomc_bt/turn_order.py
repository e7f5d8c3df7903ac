"""The order a stop's headings are turned through, so the robot turns as little as it can.

A coverage stop faces one to ``max_headings`` headings, and the robot turns on the spot
for every one of them: from the direction it arrived in, through the headings, to the
direction of the leg that leaves the stop (a differential-drive robot turns to face its
path before it drives). On an Environment-A-size pass that turning is about a sixth of
the robot's time. Which headings a stop faces is the coverage plan's decision; this
module only orders them, given where the robot comes from and where it goes next.

The arrival and departure directions are those of the legs the robot drives (paths on
the grid), not the straight line between stops: in a building the leg into a room
often arrives from the side.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np

from bomc_bt.geometry import wrap_angle

# [m] how far back along a leg its end direction is measured: one cell of a grid path
# zig-zags; the robot's pure pursuit looks about this far ahead
END_SPAN = 0.75
# above this many headings the order is greedy (the permutations grow as n!)
_EXACT_UP_TO = 6


def turn_cost(headings: Sequence[float], arrive: float, depart: float | None) -> float:
    """Radians turned: from ``arrive`` through ``headings`` in order, then to ``depart``."""
    total, at = 0.0, arrive
    for h in headings:
        total += abs(wrap_angle(h - at))
        at = h
    return total + (abs(wrap_angle(depart - at)) if depart is not None else 0.0)


def turn_order(headings: Sequence[float], arrive: float, depart: float | None = None) -> list[float]:
    """``headings`` in the order that turns least from ``arrive``, through all of them, to
    ``depart`` (None: nothing after the last). Exact for up to six headings, greedy above."""
    hs = list(headings)
    if len(hs) <= 1:
        return hs
    if len(hs) <= _EXACT_UP_TO:
        return list(min(itertools.permutations(hs), key=lambda order: turn_cost(order, arrive, depart)))
    out, at = [], arrive
    while hs:
        nxt = min(hs, key=lambda h: abs(wrap_angle(h - at)))
        hs.remove(nxt)
        out.append(nxt)
        at = nxt
    return out


def end_direction(path: np.ndarray, at_start: bool, span: float = END_SPAN) -> float | None:
    """Direction (rad) of a path's first (``at_start``) or last ``span`` metres; None for a
    path shorter than a millimetre."""
    pts = np.asarray(path, dtype=float).reshape(-1, 2)
    if at_start:
        pts = pts[::-1]
    end = pts[-1]
    far = np.hypot(pts[:, 0] - end[0], pts[:, 1] - end[1])
    back = np.nonzero(far >= span)[0]
    ref = pts[back[-1]] if len(back) else pts[0]
    d = end - ref
    if math.hypot(d[0], d[1]) < 1e-3:
        return None
    angle = math.atan2(d[1], d[0])
    return wrap_angle(angle + math.pi) if at_start else angle
