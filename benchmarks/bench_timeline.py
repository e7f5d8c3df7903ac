"""What recording a pass's timeline costs (issue 19, item 3: under 5 % of the pass's wall time).

Builds the world once, then runs monitor session 1 on fresh copies of the built site,
alternately with the timeline recorded (``mission.timeline: true``, the default) and
without (``mission.timeline: false``), ``--repeats`` times each, and prints the wall time
and CPU time (this process's) of each mode and their ratios. On a shared machine the wall
times of two runs differ by more than the recorder costs (CPU time less so), so a last
pass, without the built-in recorder, runs the same
:class:`~bomc_bt.timeline.TimelineRecorder` as an extra tick hook and times the hook
itself: its own share of the pass is the number to compare with 5 %.

Usage: ``python benchmarks/bench_timeline.py [--world ../shared/worlds/office-s.yaml]
[--repeats 3] [--seed 0]`` (prints a table).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bomc_bt import run  # noqa: E402
from bomc_bt.timeline import TimelineRecorder, TimelineWriter, read_timeline, timeline_path  # noqa: E402


class TimedRecorder(TimelineRecorder):
    """The recorder, timing its own ticks (perf_counter around each call)."""

    spent = 0.0

    def __call__(self, runner) -> None:
        start = time.perf_counter()
        super().__call__(runner)
        TimedRecorder.spent += time.perf_counter() - start


def one_pass(world: Path, built: Path, work: Path, name: str, seed: int, record: bool,
             hooks: list = ()) -> tuple[float, float, Path]:
    site = work / name
    shutil.copytree(built, site)
    config = run.build_config()
    config.mission.timeline = record
    start, cpu = time.perf_counter(), time.process_time()
    run.run_monitor(world, site, 1, seed=seed, config=config, context_hooks=list(hooks))
    return time.perf_counter() - start, time.process_time() - cpu, site


def timed_hook(ctx) -> TimedRecorder:
    """The recorder as an extra hook, writing beside the pass's own file."""
    path = timeline_path(ctx.site.session_dir(ctx.session)).with_name("timeline-timed.jsonl")
    return TimedRecorder(ctx, TimelineWriter(path, ctx.config.mission.timeline_flush_period),
                         ctx.config.mission.timeline_pose_period)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", type=Path, default=REPO.parent / "shared" / "worlds" / "office-s.yaml")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bomc-bench-timeline-") as folder:
        work = Path(folder)
        built = work / "built"
        run.run_build(args.world, built, seed=args.seed)
        walls: dict[bool, list[float]] = {True: [], False: []}
        cpus: dict[bool, list[float]] = {True: [], False: []}
        size = records = 0
        for i in range(args.repeats):
            for record in ((True, False) if i % 2 == 0 else (False, True)):
                wall, cpu, site = one_pass(args.world, built, work, f"run-{i}-{int(record)}", args.seed, record)
                walls[record].append(wall)
                cpus[record].append(cpu)
                if record:
                    path = timeline_path(site / "sessions" / "1")
                    size, timeline = path.stat().st_size, read_timeline(path, 1)
                    records = len(timeline.status) + len(timeline.poses) + len(timeline.frames) + len(timeline.events)
                    end = timeline.end
        TimedRecorder.spent = 0.0
        hooked_wall, _, _ = one_pass(args.world, built, work, "timed", args.seed, False, [timed_hook])
    on, off = statistics.median(walls[True]), statistics.median(walls[False])
    print(f"world {args.world.name}, seed {args.seed}, {args.repeats} passes per mode, {end:.0f} s robot time each")
    print(f"timeline: {size / 1024:.0f} KiB, {records} records\n")
    print("| mode | passes | median wall s | min wall s | max wall s | median CPU s | min CPU s |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for record, label in ((False, "timeline off"), (True, "timeline on")):
        w, c = walls[record], cpus[record]
        print(f"| {label} | {len(w)} | {statistics.median(w):.2f} | {min(w):.2f} | {max(w):.2f} | "
              f"{statistics.median(c):.2f} | {min(c):.2f} |")
    cpu_on, cpu_off = statistics.median(cpus[True]), statistics.median(cpus[False])
    print(f"\nratio on / off, median wall: {on / off:.3f} ({100 * (on / off - 1):+.1f} %), "
          f"median CPU: {cpu_on / cpu_off:.3f} ({100 * (cpu_on / cpu_off - 1):+.1f} %), "
          f"min CPU: {min(cpus[True]) / min(cpus[False]):.3f}")
    print(f"recorder's own time in a pass: {TimedRecorder.spent:.3f} s = "
          f"{100 * TimedRecorder.spent / off:.2f} % of the median wall time of a pass without it ({off:.2f} s), "
          f"{100 * TimedRecorder.spent / cpu_off:.2f} % of its CPU time ({cpu_off:.2f} s)  (limit 5 %; "
          f"that timed pass took {hooked_wall:.2f} s)")


if __name__ == "__main__":
    main()
