"""Per-frame latency of the ONNX perception pipeline, stage by stage, at 640 x 480.

    .venv/bin/python benchmarks/bench_onnx_perception.py [--frames 30] [--objects 5]

The models are the signature-compatible TEST models of tests/onnx_models.py (planted
outputs, real input/output shapes: 900 queries x 256 text positions, a 1024 x 1024 encoder
input, SamOnnxModel decoder), NOT the real GroundingDINO / MobileSAM weights: the "model"
rows measure onnxruntime overhead and tensor traffic, not network compute. Everything else
(resizing, normalisation, tokenization, decoding, NMS, mask handling, back-projection,
association) is the production code. Ratios are against the same run's total per frame;
the last table compares the cached encoder with a run-the-encoder-per-box baseline.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import onnx_models as om  # noqa: E402

from bomc_bt.geometry import Pose2D, se3  # noqa: E402
from bomc_bt.graph import AssociationParams, ObjectGraph  # noqa: E402
from bomc_bt.perception.grounding_dino import GroundingDinoDetector  # noqa: E402
from bomc_bt.perception.mobile_sam import MobileSamSegmenter  # noqa: E402
from bomc_bt.perception.onnx_common import OnnxPerceptionParams  # noqa: E402
from bomc_bt.perception.projection import ProjectionParams, detections_to_observations  # noqa: E402
from bomc_bt.robot import RGBDFrame  # noqa: E402

H, W, Q, T = 480, 640, 900, 256
CATEGORIES = ["chair", "table", "door", "trash bin", "person", "tv", "cabinet"]


def scene(n_objects: int, rng: np.random.Generator):
    """A frame with ``n_objects`` boxes at 2-5 m in front of a wall, and planted model outputs."""
    depth = np.full((H, W), 7.0, np.float32)
    rgb = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)
    logits = rng.normal(-6.0, 1.0, (Q, T)).astype(np.float32)
    logits[:, 17:] = -np.inf  # the prompt has 17 tokens
    boxes = rng.uniform(0.3, 0.7, (Q, 4)).astype(np.float32)
    boxes[:, 2:] *= 0.2
    # "[CLS] chair . table . door . trash bin . person . tv . cabinet . [SEP]"
    first_token = [1, 3, 5, 7, 10, 12, 14]
    for i in range(n_objects):
        x0, y0 = 20 + i * (W - 40) // n_objects, 100 + 20 * i
        x1, y1 = x0 + (W - 40) // n_objects - 20, y0 + 200
        depth[y0:y1, x0:x1] = 2.0 + 3.0 * i / max(n_objects - 1, 1)
        logits[i, first_token[i % len(first_token)]] = 4.0
        boxes[i] = [(x0 + x1) / 2 / W, (y0 + y1) / 2 / H, (x1 - x0) / W, (y1 - y0) / H]
    K = np.array([[525.0, 0, W / 2], [0, 525.0, H / 2], [0, 0, 1]])
    R = np.array([[0.0, 0, 1], [-1, 0, 0], [0, -1, 0]])
    frame = RGBDFrame(0.0, rgb, depth, K, Pose2D(1.0, 2.0, 0.3).to_matrix(), se3(R, np.array([0.0, 0, 1.0])))
    return frame, logits, boxes


def timed(fn, *args):
    t = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--objects", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    frame, logits, boxes = scene(args.objects, rng)
    params = OnnxPerceptionParams()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        det = GroundingDinoDetector(om.grounding_dino_hf(d / "g.onnx", logits, boxes),
                                    om.write_tokenizer(d / "tokenizer.json"), params)
        seg = MobileSamSegmenter(om.sam_encoder(d / "e.onnx"), om.sam_box_decoder(d / "m.onnx"), params)
        rows = run(det, seg, frame, args.frames)
        baseline = encoder_per_box(seg, frame, det, args.frames)
    report(rows, baseline, args)


def run(det, seg, frame, n_frames: int) -> dict[str, list[float]]:
    graph = ObjectGraph(AssociationParams())
    proj = ProjectionParams()
    rows: dict[str, list[float]] = {k: [] for k in (
        "det preprocess", "det model", "det postprocess", "sam preprocess", "sam encoder", "sam decoder",
        "sam postprocess", "projection", "association")}
    for i in range(n_frames + 3):  # 3 warm-up frames
        f = RGBDFrame(float(i), frame.rgb.copy(), frame.depth, frame.K, frame.T_map_base, frame.T_base_camera)
        t: dict[str, float] = {}
        prepared, t["det preprocess"] = timed(det.prepare, f.rgb, CATEGORIES)
        (lg, bx), t["det model"] = timed(det.infer, prepared)
        dets, t["det postprocess"] = timed(det.decode, prepared, lg, bx)
        x, t["sam preprocess"] = timed(seg.preprocess, f.rgb)
        emb, t["sam encoder"] = timed(seg.run_encoder, x)
        start = time.perf_counter()
        logits = [seg.decode_box(emb, dd.box, (H, W)) for dd in dets]
        t["sam decoder"] = time.perf_counter() - start
        start = time.perf_counter()
        dets = [dd.with_mask(m > seg.params.mask_threshold) for dd, m in zip(dets, logits, strict=True)]
        t["sam postprocess"] = time.perf_counter() - start
        obs, t["projection"] = timed(detections_to_observations, f, dets, proj)
        _, t["association"] = timed(graph.associate, obs, [], 1, float(i))
        if i >= 3:
            for k, v in t.items():
                rows[k].append(v)
    rows["_detections"] = [float(len(dets))]
    rows["_observations"] = [float(len(obs))]
    return rows


def encoder_per_box(seg, frame, det, n_frames: int) -> tuple[float, float]:
    """Median s per frame of segment() (cached encoder) vs. one encoder run per box."""
    dets = det.detect(frame, CATEGORIES)
    cached, naive = [], []
    for i in range(n_frames):
        f = RGBDFrame(100.0 + i, frame.rgb.copy(), frame.depth, frame.K, frame.T_map_base,
                      frame.T_base_camera)
        _, dt = timed(seg.segment, f, dets)
        cached.append(dt)
        start = time.perf_counter()
        for dd in dets:
            emb = seg.run_encoder(seg.preprocess(f.rgb))
            seg.mask_for_box(emb, dd.box, (H, W))
        naive.append(time.perf_counter() - start)
    return statistics.median(cached), statistics.median(naive)


def report(rows: dict[str, list[float]], baseline: tuple[float, float], args) -> None:
    n_det, n_obs = int(rows.pop("_detections")[0]), int(rows.pop("_observations")[0])
    med = {k: statistics.median(v) for k, v in rows.items()}
    total = sum(med.values())
    print(f"ONNX perception per frame, {W}x{H}, {args.frames} frames, "
          f"{n_det} detections -> {n_obs} observations")
    print("models: signature-compatible TEST models (planted outputs), not the real GroundingDINO/MobileSAM")
    print(f"{'stage':<18}{'median ms':>11}{'p90 ms':>9}{'share':>8}")
    for k, v in rows.items():
        p90 = float(np.percentile(v, 90))
        print(f"{k:<18}{med[k] * 1e3:>11.2f}{p90 * 1e3:>9.2f}{med[k] / total:>8.1%}")
    print(f"{'total':<18}{total * 1e3:>11.2f}{'':>9}{1:>8.0%}")
    groups = {"preprocessing": ("det preprocess", "sam preprocess"),
              "model": ("det model", "sam encoder", "sam decoder"),
              "postprocessing": ("det postprocess", "sam postprocess"),
              "projection": ("projection",), "association": ("association",)}
    print(f"\n{'split':<18}{'median ms':>11}{'share':>8}")
    for name, keys in groups.items():
        s = sum(med[k] for k in keys)
        print(f"{name:<18}{s * 1e3:>11.2f}{s / total:>8.1%}")
    cached, naive = baseline
    print(f"\n{'segmenter':<26}{'median ms':>11}{'ratio':>8}")
    print(f"{'encoder once per frame':<26}{cached * 1e3:>11.2f}{cached / naive:>8.2f}")
    print(f"{'baseline: encoder per box':<26}{naive * 1e3:>11.2f}{1:>8.2f}")


if __name__ == "__main__":
    main()
