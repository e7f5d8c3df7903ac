"""``bomc replay``: map from a recorded ROS 1 bag, as a live pass would have at that rate.

Researchers and operators often have a recording rather than a robot. A replay reads the
bag's RGB-D frames with their camera_info and tf (:mod:`bomc_bt.ros.bag`) and runs each
through the very Perceive-Associate step of a live pass
(:class:`bomc_bt.monitoring.Perception`: detector, segmenter, back-projection, the graph
update, one store transaction per frame), into a normal session of the site: under the
site's writer lock, on its current map generation, with the session report.

Frames arrive on the wall clock, at the recorded stamps' spacing or at ``rate`` frames
per second; while one is being processed the others wait, and only the newest is taken
when the pipeline is free (:func:`bomc_bt.anytime.next_frame`), as a live robot drops
frames it cannot keep up with. The wall clock paces arrivals and measures costs, nothing
else: the graph sees the recorded stamps. ``as_fast_as_possible`` processes every frame.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from bomc_bt.anytime import arrival_times, every_frame, next_frame
from bomc_bt.config import Config
from bomc_bt.errors import BomcError
from bomc_bt.grid import OccupancyGrid


class WallClock:
    """Seconds since the replay started, on the monotonic wall clock."""

    def __init__(self) -> None:
        self.start = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self.start

    def sleep_until(self, t: float) -> None:
        delay = t - self.now()
        if delay > 0:
            time.sleep(delay)


class TimedDetector:
    """A detector and segmenter that add the seconds they take to ``seconds`` (the model cost)."""

    def __init__(self, detector: Any, segmenter: Any):
        self.detector, self.segmenter = detector, segmenter
        self.seconds = 0.0

    def detect(self, frame, categories):
        t = time.perf_counter()
        try:
            return self.detector.detect(frame, categories)
        finally:
            self.seconds += time.perf_counter() - t

    def segment(self, frame, detections):
        t = time.perf_counter()
        try:
            return self.segmenter.segment(frame, detections) if self.segmenter is not None else detections
        finally:
            self.seconds += time.perf_counter() - t


@dataclass
class RecordedPass:
    """The recording seen as the robot of the session report: its time, path and map."""

    grid: OccupancyGrid
    stamp: float = 0.0  # s, the stamp of the newest frame processed
    distance_travelled: float = 0.0  # m, along map <- base at the usable frames

    def now(self) -> float:
        return self.stamp

    def live_map(self) -> OccupancyGrid:
        return self.grid

    def cancel_all(self) -> None:
        """Nothing drives during a replay."""


@dataclass
class ReplayResult:
    """How a replay went: counts and costs, the session summary, and the problems found."""

    processed: int = 0
    dropped: int = 0
    skipped: int = 0
    frames_in_bag: int = 0
    wall_s: float = 0.0
    model_s: float = 0.0
    not_model_s: float = 0.0
    problems: list[str] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)

    def replay_record(self, bag: Path, rate: str) -> dict[str, Any]:
        n = max(self.processed, 1)
        total = self.model_s + self.not_model_s
        return {"bag": str(bag), "rate": rate, "frames_in_bag": self.frames_in_bag, "processed": self.processed,
                "dropped": self.dropped, "skipped": self.skipped, "wall_s": round(self.wall_s, 2),
                "model_ms_per_frame": round(1000 * self.model_s / n, 2),
                "not_model_ms_per_frame": round(1000 * self.not_model_s / n, 2),
                "not_model_share": round(self.not_model_s / total, 3) if total > 0 else None}


def rate_label(rate: float | None, as_fast_as_possible: bool) -> str:
    if as_fast_as_possible:
        return "as fast as possible"
    return "recorded rate" if rate is None else f"{rate:g} fps"


def run_replay(bag_path: str | Path, site_dir: str | Path, session: int, config: Config, *,
               rate: float | None = None, as_fast_as_possible: bool = False, seed: int = 0,
               clock: Any = None, problems: TextIO | None = None, detector_wrapper: Any = None) -> ReplayResult:
    """Replay ``bag_path`` into session ``session`` of ``site_dir`` (see the module doc).

    Everything is checked (arguments, config, the bag and its frames, the site) before
    the site is written. ``detector_wrapper(detector, segmenter)`` may replace the
    backend (the throughput benchmark's model budget). Problem lines go to ``problems``.
    """
    from bomc_bt.ros.bag import FrameReader, index_bag, open_bag
    from bomc_bt.ros.missions import RosRobots

    if session < 1:
        raise BomcError("must be 1 or more", None, "--session")
    if rate is not None and (as_fast_as_possible or not 0 < rate <= 1000 or not math.isfinite(rate)):
        raise BomcError("must be a rate in frames per second in (0, 1000], without --as-fast-as-possible",
                        None, "--rate")
    problems = problems or sys.stderr
    bag_path = Path(bag_path)
    robots = RosRobots()
    robots.prepare(config)
    params = robots.params
    categories = robots.categories(config)
    bag = open_bag(bag_path)
    try:
        index = index_bag(bag, bag_path, params)
        result = ReplayResult(frames_in_bag=index.pairs, problems=index.problems())
        for line in result.problems:
            print(f"bomc replay: {line}", file=problems)
        if not index.frames:
            raise BomcError(f"none of its {index.pairs} RGB-D frames can be mapped (the lines above say why)",
                            bag_path)
        _replay_into_site(bag, index, FrameReader(bag, index, params), Path(site_dir), session, config,
                          categories, result, rate=rate, every=as_fast_as_possible, seed=seed,
                          clock=clock or WallClock(), wrapper=detector_wrapper)
    finally:
        bag.close()
    for line in result.problems[len(index.problems()):]:
        print(f"bomc replay: {line}", file=problems)
    return result


def _path_length(index) -> float:
    xy = np.array([ref.T_map_base[:2, 3] for ref in index.frames]).reshape(-1, 2)
    return float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0


def _replay_into_site(bag, index, reader, site_dir: Path, session: int, config: Config, categories: list[str],
                      result: ReplayResult, *, rate, every: bool, seed: int, clock, wrapper) -> None:
    from bomc_bt.first_seen import seen_before_for
    from bomc_bt.generations import lock_for_monitor
    from bomc_bt.grid import load_map
    from bomc_bt.mission import MissionContext
    from bomc_bt.monitoring import Perception
    from bomc_bt.report import write_session_report
    from bomc_bt.run import check_session, make_perception, perception_base_dir
    from bomc_bt.site import Site
    from bomc_bt.store import SiteStore

    detector, segmenter = make_perception(config, seed, perception_base_dir(config))
    if wrapper is not None:
        detector, segmenter = wrapper(detector, segmenter)
    timed = TimedDetector(detector, segmenter)
    lock = lock_for_monitor(site_dir)  # one writer (bomc_bt.site_lock), as a live pass
    store = None
    try:
        site = Site(site_dir)  # after the lock: the current generation, read once
        site.require_build()
        grid = load_map(site.map_yaml)
        store = SiteStore(site.store_path)
        check_session(store, session, False, site.store_path)
        graph = store.load_graph(config.association)
        perception = Perception(timed, timed, categories, config.projection, graph, store, session, grid,
                                occlusion_check=config.association.mode != "paper", near_range=config.budget.view_range,
                                seen_before=seen_before_for(store, session, grid, config.association))
        recorded = RecordedPass(grid, index.frames[0].stamp, _path_length(index))
        ctx = MissionContext(robot=recorded, config=config, site=site, mission="monitor", session=session,
                             seed=seed, store=store, graph=graph, perception=perception)
        store.begin_session(session, {"stamp": recorded.stamp, "seed": seed, "mission": "replay",
                                      "bag": str(index.path)})
        label = rate_label(rate, every)
        try:
            _run_frames(index, reader, perception, timed, recorded, result, rate, every, clock)
            ctx.outcome = "completed"
        except KeyboardInterrupt:
            ctx.outcome, ctx.reason = "interrupted", "stopped by the operator (Ctrl-C)"
            raise
        finally:
            result.problems += [f"{index.path}: {n} frame(s) skipped: {reason}"
                                for reason, n in sorted(reader.corrupt.items())]
            result.summary = write_session_report(
                ctx, extra={"localized": "recorded", "replay": result.replay_record(index.path, label)})
    finally:
        if store is not None:
            store.close()
        lock.release()


def _run_frames(index, reader, perception, timed: TimedDetector, recorded: RecordedPass, result: ReplayResult,
                rate: float | None, every: bool, clock) -> None:
    """The anytime loop: wait for the frame :func:`next_frame` picks, process it, repeat."""
    arrivals = arrival_times([ref.stamp for ref in index.frames], rate)
    choose = every_frame if every else next_frame
    done, started = -1, clock.now()
    corrupt = Counter()
    while (pick := choose(arrivals, done, clock.now() - started)) is not None:
        clock.sleep_until(started + pick.start)
        t0, model0 = time.perf_counter(), timed.seconds
        frame = reader.frame(pick.index)
        if frame is None:
            corrupt["frame"] += 1
        else:
            perception.process(frame)
            recorded.stamp = frame.stamp
            result.processed += 1
            result.model_s += timed.seconds - model0
            result.not_model_s += time.perf_counter() - t0 - (timed.seconds - model0)
        result.dropped += pick.dropped
        done = pick.index
    result.skipped = sum(index.skipped.values()) + corrupt["frame"]
    result.wall_s = clock.now() - started
