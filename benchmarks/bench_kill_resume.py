"""Issue 18's acceptance test: ``kill -9`` at random moments of a re-build and of a monitor pass.

* Re-build: a built site (generation 1) is re-built with another seed, and the ``bomc
  build`` process is killed at a random moment. The site's map, trajectory and build
  record (top level and current generation) must be the old generation's or the new
  one's, byte for byte, never a mix.
* Pass: session 2 (which has a change during the pass) is run by ``bomc monitor`` and
  killed at a random moment, then resumed with ``--resume``; the resumed pass must end with
  the uninterrupted pass's object F1, and the map and trajectory must be untouched.

Usage: ``python benchmarks/bench_kill_resume.py [--kills 10] [--size 30x20] [--seed 18]``
(prints two tables and the totals).
"""

from __future__ import annotations

import argparse
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bomc_bt import run  # noqa: E402
from bomc_bt.evaluate_site import evaluate_session  # noqa: E402
from bomc_bt.officegen import OfficeParams, generate_office  # noqa: E402
from bomc_bt.resume_rows import load_resume_point  # noqa: E402
from bomc_bt.site import Site, current_generation  # noqa: E402
from bomc_bt.store import SiteStore  # noqa: E402
from bomc_bt.world import load_world  # noqa: E402

BUILD_FILES = ("map.yaml", "map.pgm", "trajectory.csv", "build.json")


def bomc(*args: str) -> list[str]:
    return [sys.executable, "-m", "bomc_bt.cli", *args]


def build_files(folder: Path) -> dict[str, bytes | None]:
    return {n: (folder / n).read_bytes() if (folder / n).exists() else None for n in BUILD_FILES}


def kill_after(command: list[str], delay: float) -> int:
    """Run ``command``, SIGKILL it after ``delay`` s; its return code (-9 when killed)."""
    proc = subprocess.Popen(command, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        proc.wait(timeout=delay)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    return proc.returncode


def kill_at_robot_time(command: list[str], site: Path, session: int, target: float) -> int:
    """Run ``command`` and SIGKILL it as soon as its pass has committed robot time ``target``
    (a random moment of the pass in robot time, whatever the machine's speed)."""
    proc = subprocess.Popen(command, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while proc.poll() is None:
        if (site / "site.db").exists() and (committed_time(site, session) or 0.0) >= target:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.005)
    return proc.wait()


def timed(command: list[str]) -> float:
    start = time.monotonic()
    subprocess.run(command, cwd=REPO, check=False, capture_output=True)
    return time.monotonic() - start


def rebuild_kills(world: Path, built: Path, root: Path, kills: int, rng: random.Random) -> list[dict]:
    old = build_files(built)
    reference = shutil.copytree(built, root / "rebuild-ref")
    args = ("build", "--world", str(world), "--quiet", "--seed", "1")
    duration = timed(bomc(*args, "--site", str(reference)))
    new = build_files(reference)
    assert new != old and current_generation(reference) == 2
    rows = []
    for k in range(kills):
        site = shutil.copytree(built, root / f"rebuild-{k}")
        at = rng.uniform(0.05, 1.05) * duration  # past the end too: a kill during the switch
        code = kill_after(bomc(*args, "--site", str(site)), at)
        top, current = build_files(site), build_files(Site(site).data)
        state = "old" if top == old and current == old else "new" if top == new and current == new else "MIXED"
        rows.append({"kill_s": at, "killed": code == -9, "state": state, "generation": current_generation(site)})
    return rows


def graph(site: Path, session: int) -> list[tuple]:
    with SiteStore(site, readonly=True) as store:
        return [(n.id, n.category, tuple(n.position.round(6))) for n in store.graph_after(session)]


def committed_time(site: Path, session: int) -> float | None:
    with SiteStore(site, readonly=True) as store:
        point = load_resume_point(store, session)
    robot = (point or {}).get("robot") or {}
    return None if "steps" not in robot else robot["steps"] * 0.1


def pass_kills(world: Path, monitored: Path, root: Path, kills: int, rng: random.Random) -> tuple[dict, list[dict]]:
    config = run.build_config()
    reference = shutil.copytree(monitored, root / "pass-ref")
    args = ("monitor", "--world", str(world), "--session", "2", "--seed", "2", "--quiet")
    duration = timed(bomc(*args, "--site", str(reference)))
    with SiteStore(reference, readonly=True) as store:
        robot_time = store.sessions()[-1].ended_stamp
    ref = {"f1": evaluate_session(world, reference, 2, config).overall.f1, "graph": graph(reference, 2),
           "wall_s": duration, "robot_s": robot_time}
    before = build_files(monitored)
    rows = []
    for k in range(kills):
        site = shutil.copytree(monitored, root / f"pass-{k}")
        at = rng.uniform(0.02, 0.98) * robot_time
        code = kill_at_robot_time(bomc(*args, "--site", str(site)), site, 2, at)
        committed = committed_time(site, 2)
        resumed = subprocess.run(bomc(*args, "--site", str(site), "--resume"), cwd=REPO, capture_output=True,
                                 text=True)
        f1 = evaluate_session(world, site, 2, config).overall.f1
        rows.append({"kill_s": at, "killed": code == -9, "robot_s": committed, "resume_rc": resumed.returncode,
                     "f1": f1, "same_f1": f1 == ref["f1"], "same_graph": graph(site, 2) == ref["graph"],
                     "map_intact": build_files(site) == before})
    return ref, rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kills", type=int, default=10)
    p.add_argument("--size", default="30x20")
    p.add_argument("--seed", type=int, default=18, help="seed of the random kill moments")
    args = p.parse_args()
    width, height = (float(v) for v in args.size.split("x"))
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory(prefix="bench-kill-") as tmp:
        root = Path(tmp)
        world = root / "office.yaml"
        generate_office(OfficeParams(width=width, height=height, seed=4, sessions=2), world)
        change = load_world(world).during_changes(2)
        built = root / "built"
        run.run_build(world, built, seed=0)
        rebuilds = rebuild_kills(world, built, root, args.kills, rng)
        monitored = shutil.copytree(built, root / "monitored")
        run.run_monitor(world, monitored, 1, seed=1)
        ref, passes = pass_kills(world, monitored, root, args.kills, rng)
    print(f"office {args.size} m, session 2 changes during the pass at {[d.at for d in change]} s robot time\n")
    print("re-build killed at      | killed | site after the kill | current generation")
    for r in rebuilds:
        print(f"{r['kill_s']:8.2f} s wall        | {str(r['killed']):6} | {r['state']:19} | {r['generation']}")
    print(f"\nuninterrupted pass: F1 {ref['f1']:.3f}, {ref['robot_s']:.1f} s robot time, {ref['wall_s']:.1f} s wall\n")
    print("pass killed at   | killed | robot time committed | resume rc | F1    | same F1 | same graph | map intact")
    for r in passes:
        committed = "-" if r["robot_s"] is None else f"{r['robot_s']:.1f} s"
        print(f"{r['kill_s']:6.1f} s robot | {str(r['killed']):6} | {committed:20} | {r['resume_rc']:9} | "
              f"{r['f1']:.3f} | {str(r['same_f1']):7} | {str(r['same_graph']):10} | {r['map_intact']}")
    whole = sum(r["state"] != "MIXED" for r in rebuilds)
    same = sum(r["same_f1"] and r["resume_rc"] == 0 for r in passes)
    print(f"\nre-build: old or new, never mixed, in {whole}/{len(rebuilds)} "
          f"({sum(r['state'] == 'old' for r in rebuilds)} old, {sum(r['state'] == 'new' for r in rebuilds)} new)")
    print(f"pass: resume gives the uninterrupted F1 in {same}/{len(passes)}; the same final graph in "
          f"{sum(r['same_graph'] for r in passes)}/{len(passes)}; map and trajectory intact in "
          f"{sum(r['map_intact'] for r in passes)}/{len(passes)}")
    return 0 if whole == len(rebuilds) and same == len(passes) else 1


if __name__ == "__main__":
    sys.exit(main())
