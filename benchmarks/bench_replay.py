"""Throughput of ``bomc replay``: a recorded office-s pass replayed at 5, 10, 21 and 30 fps.

    .venv/bin/python benchmarks/bench_replay.py [--work DIR] [--rates 5 10 21 30] [--frames N]

The paper's throughput test (issue 21): one recording replayed at fixed frame rates on
the wall clock; frames that arrive while one is processed are dropped (newest wins), so
a slow pipeline maps from fewer frames. Steps:

1. office-s (``../shared/worlds/office-s.yaml``, found through tests/shared_data.py) is
   built in the simulator, and its session-1 pass is run through ROS
   (``bomc sim-ros`` + ``bomc monitor --ros``) while ``rosbag record`` records it (a real
   roscore on a free loopback port). ``--work DIR`` keeps the build and the bag for reruns.
2. The bag is replayed into a fresh copy of the build at each rate with two back ends:

   - ``onnx 45 ms``: the ONNX GroundingDINO + MobileSAM pipeline of ``perception.backend:
     onnx`` on the signature-compatible TEST models of tests/onnx_models.py (planted
     outputs, real input/output shapes), run on every processed frame with the models'
     inference (detector, SAM encoder, SAM decoder calls) padded to 45 ms per frame, a
     GroundingDINO + MobileSAM budget on a fixed GPU. The test models see nothing, so the
     detections the graph gets are the simulator's detector's for the same frame; the
     pipeline's pre- and postprocessing are the production code and count as not-model.
   - ``sim``: the simulator's detector alone (its time counts as the model).

Columns: nodes mapped, true positives and F1 against the world (CONTRACTS 4), frames
processed / dropped, model and not-model ms per processed frame (not-model: bag decoding,
ONNX pre/postprocessing, back-projection, association, the store's transaction) and the
not-model share. Timings are wall time on this machine, whatever else runs on it.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import onnx_models as om  # noqa: E402
from ros_recording import record_pass, roscore  # noqa: E402
from shared_data import require_shared, shared_path  # noqa: E402

from bomc_bt.evaluate_site import evaluate_session  # noqa: E402
from bomc_bt.perception.grounding_dino import GroundingDinoDetector  # noqa: E402
from bomc_bt.perception.mobile_sam import MobileSamSegmenter  # noqa: E402
from bomc_bt.perception.onnx_common import OnnxPerceptionParams  # noqa: E402
from bomc_bt.replay import run_replay  # noqa: E402
from bomc_bt.ros.bag import recorded_topics  # noqa: E402
from bomc_bt.ros.missions import ros_params  # noqa: E402
from bomc_bt.run import build_config, run_build  # noqa: E402
from bomc_bt.sim.factory import world_categories  # noqa: E402
from bomc_bt.world import load_world  # noqa: E402

BUDGET = 0.045  # s of model inference per frame: GroundingDINO + MobileSAM on a fixed GPU
BUILD_FILES = ("map.yaml", "map.pgm", "trajectory.csv", "build.json")


class _Timed:
    """Mixin: the seconds spent in the model calls named ``MODEL_CALLS`` add up in ``clock[0]``."""

    MODEL_CALLS: tuple[str, ...] = ()

    def timed_model(self, clock: list[float]) -> None:
        for name in self.MODEL_CALLS:
            inner = getattr(self, name)

            def call(*args, _inner=inner, **kwargs):
                t = time.perf_counter()
                try:
                    return _inner(*args, **kwargs)
                finally:
                    clock[0] += time.perf_counter() - t

            setattr(self, name, call)


class Dino(_Timed, GroundingDinoDetector):
    MODEL_CALLS = ("infer",)


class Sam(_Timed, MobileSamSegmenter):
    MODEL_CALLS = ("run_encoder", "decode_box")


class BudgetedOnnx:
    """Detector + segmenter: the ONNX pipeline's cost with its inference padded to the budget,
    the simulator's detections (the test models' outputs are planted)."""

    def __init__(self, sim, dino: Dino, sam: Sam, budget: float):
        self.sim, self.dino, self.sam, self.budget = sim, dino, sam, budget
        self.frame_model = [0.0]
        self.model_s = 0.0  # the padded inference time, summed over processed frames
        dino.timed_model(self.frame_model)
        sam.timed_model(self.frame_model)

    def detect(self, frame, categories):
        self.frame_model[0] = 0.0
        self.sam.segment(frame, self.dino.detect(frame, categories))
        pad = self.budget - self.frame_model[0]
        if pad > 0:
            time.sleep(pad)
        self.model_s += max(self.budget, self.frame_model[0])
        return self.sim.detect(frame, categories)

    def segment(self, frame, detections):
        return self.sim.segment(frame, detections)


def onnx_models(folder: Path, categories: list[str]) -> tuple[Dino, Sam]:
    """The test models, planting three confident boxes per frame so SAM decodes three masks."""
    rng = np.random.default_rng(0)
    q, t = 900, 256
    logits = np.full((q, t), -8.0, np.float32)
    boxes = rng.uniform(0.3, 0.7, (q, 4)).astype(np.float32)
    boxes[:, 2:] *= 0.2
    for i in range(3):
        logits[i, 1] = 4.0  # the first token of the first category
        boxes[i] = [0.2 + 0.3 * i, 0.5, 0.15, 0.3]
    params = OnnxPerceptionParams()
    dino = Dino(om.grounding_dino_hf(folder / "g.onnx", logits, boxes), om.write_tokenizer(folder / "tok.json"),
                params)
    sam = Sam(om.sam_encoder(folder / "e.onnx"), om.sam_box_decoder(folder / "m.onnx"), params)
    return dino, sam


def record(work: Path, world: Path, config_path: Path) -> Path:
    """office-s built and its session-1 pass recorded through ROS (kept in ``work``)."""
    bag, built = work / "office-s-pass.bag", work / "built"
    if bag.exists() and (built / "map.yaml").exists():
        return bag
    shutil.rmtree(built, ignore_errors=True)
    t = time.monotonic()
    run_build(world, built)
    live = work / "live"
    shutil.rmtree(live, ignore_errors=True)
    _copy_build(built, live)
    config = build_config([str(config_path)])
    with roscore(work) as env:
        proc = record_pass(env, world, live, 1, bag, config_path, recorded_topics(ros_params(config)),
                           timeout=3600)
    if proc.returncode != 0:
        raise SystemExit(f"the recorded pass failed: {proc.stderr[-2000:]}")
    print(f"recorded {bag} ({bag.stat().st_size / 1e6:.0f} MB) in {time.monotonic() - t:.0f} s; live pass: "
          f"{proc.stdout.strip()}", flush=True)
    return bag


def _copy_build(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True)
    for name in BUILD_FILES:
        shutil.copy(src / name, dst / name)
    return dst


def replay_row(name: str, rate: float, bag: Path, work: Path, world: Path, config_path: Path, models) -> dict:
    config = build_config([str(config_path)])
    site = work / f"replay-{name.split()[0]}-{rate:g}"
    shutil.rmtree(site, ignore_errors=True)
    _copy_build(work / "built", site)
    budgeted: list[BudgetedOnnx] = []

    def wrap(detector, segmenter):
        budgeted.append(BudgetedOnnx(detector, *models, BUDGET))
        return budgeted[0], budgeted[0]

    result = run_replay(bag, site, 1, config, rate=rate, detector_wrapper=wrap if models else None)
    score = evaluate_session(world, site, 1, config).overall
    total = result.model_s + result.not_model_s
    model = budgeted[0].model_s if budgeted else result.model_s
    n = max(result.processed, 1)
    return {"backend": name, "fps": rate, "nodes": score.mapped, "tp": score.tp, "f1": score.f1,
            "processed": result.processed, "dropped": result.dropped, "skipped": result.skipped,
            "model_ms": 1000 * model / n, "not_model_ms": 1000 * (total - model) / n,
            "not_model_share": (total - model) / total if total else 0.0, "wall_s": result.wall_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", help="folder for the build, the bag and the replays (kept; default: a temp dir)")
    ap.add_argument("--rates", type=float, nargs="+", default=[5.0, 10.0, 21.0, 30.0])
    ap.add_argument("--backends", nargs="+", default=["onnx", "sim"], choices=["onnx", "sim"])
    ap.add_argument("--json", help="also write the rows to this file")
    args = ap.parse_args()
    world = Path(shared_path("worlds/office-s.yaml"))
    if not world.exists():
        require_shared(world)
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="bench-replay-"))
    work.mkdir(parents=True, exist_ok=True)
    config_path = work / "replay.yaml"
    config_path.write_text(json.dumps({"perception": {"categories": world_categories(load_world(world))},
                                       "ros": {"frame_timeout": 5.0, "clock_timeout": 10.0}}))
    bag = record(work, world, config_path)
    categories = build_config([str(config_path)]).perception.categories
    rows = []
    with tempfile.TemporaryDirectory() as models_dir:
        for backend in args.backends:
            models = onnx_models(Path(models_dir), categories) if backend == "onnx" else None
            name = f"onnx {BUDGET * 1000:.0f} ms" if backend == "onnx" else "sim"
            for rate in args.rates:
                rows.append(replay_row(name, rate, bag, work, world, config_path, models))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    print_table(rows)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


def print_table(rows: list[dict]) -> None:
    print(f"office-s session 1, replayed from a ROS bag on the wall clock; onnx: model inference padded to "
          f"{BUDGET * 1000:.0f} ms per frame (test models; detections from the simulator's detector)")
    head = ("backend", "fps", "nodes", "TP", "F1", "processed", "dropped", "model ms", "not-model ms", "share")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        f1 = "n/a" if r["f1"] is None else f"{r['f1']:.3f}"
        print(f"| {r['backend']} | {r['fps']:g} | {r['nodes']} | {r['tp']} | {f1} | {r['processed']} | "
              f"{r['dropped']} | {r['model_ms']:.1f} | {r['not_model_ms']:.1f} | {r['not_model_share']:.0%} |")


if __name__ == "__main__":
    main()
