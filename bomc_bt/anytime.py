"""Which frames an anytime pipeline processes when frames come faster than it can keep up.

A live robot's Perceive-Associate takes the newest frame each time it is free; frames
that arrived while it was busy are never seen (the camera driver keeps only the newest).
Replaying a recording at a given rate must drop the same way, or a throughput test
measures nothing: :func:`next_frame` is that rule as a pure function of arrival times
and the time the pipeline is free, and :func:`schedule` runs it over known processing
times (what the tests and the benchmark reason with). The replay loop
(:mod:`bomc_bt.replay`) calls :func:`next_frame` with the wall clock's time.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Pick:
    """The frame to process next: ``index``, from ``start`` (s), after dropping ``dropped`` frames."""

    index: int
    start: float
    dropped: int


def next_frame(arrivals: Sequence[float], done: int, free_at: float) -> Pick | None:
    """The newest frame arrived by ``free_at`` after frame ``done`` (-1: none yet), or the
    next one to arrive if none has; None when every frame was handled.

    ``arrivals`` are non-decreasing times (s). Frames between ``done`` and the pick arrived
    while the pipeline was busy and are dropped (newest wins).
    """
    first = done + 1
    if first >= len(arrivals):
        return None
    newest = bisect.bisect_right(arrivals, free_at) - 1
    if newest >= first:
        return Pick(newest, free_at, newest - first)
    return Pick(first, float(arrivals[first]), 0)


def every_frame(arrivals: Sequence[float], done: int, free_at: float) -> Pick | None:
    """As fast as possible: each frame in order, none dropped, no waiting."""
    first = done + 1
    return Pick(first, free_at, 0) if first < len(arrivals) else None


@dataclass
class Schedule:
    """What :func:`schedule` decided: the processed frames in order, with their start times."""

    processed: list[int] = field(default_factory=list)
    starts: list[float] = field(default_factory=list)
    dropped: int = 0


def schedule(arrivals: Sequence[float], costs: Sequence[float]) -> Schedule:
    """Run :func:`next_frame` with frame ``i`` taking ``costs[i]`` seconds to process."""
    if len(costs) != len(arrivals):
        raise ValueError("one processing time per frame")
    out = Schedule()
    done, free_at = -1, float("-inf")
    while (pick := next_frame(arrivals, done, free_at)) is not None:
        out.processed.append(pick.index)
        out.starts.append(pick.start)
        out.dropped += pick.dropped
        done, free_at = pick.index, pick.start + float(costs[pick.index])
    return out


def arrival_times(stamps: Sequence[float], rate: float | None) -> list[float]:
    """When each frame arrives (s from the first): at the recorded stamps' spacing, or
    evenly at ``rate`` frames per second."""
    if not stamps:
        return []
    if rate is None:
        return [float(s) - float(stamps[0]) for s in stamps]
    if not rate > 0:
        raise ValueError("rate must be > 0")
    return [i / rate for i in range(len(stamps))]
