"""The ONNX GroundingDINO and MobileSAM backends, end to end on signature-compatible models.

The models in :mod:`tests.onnx_models` have the real exports' inputs and outputs but emit
planted logits, boxes and masks, so each test knows which category, which pixels and which
mask region must come out of the backend for a non-square, non-800-pixel image.
"""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from bomc_bt.errors import BomcError
from bomc_bt.perception.frames import Detection, Detector, Segmenter
from bomc_bt.perception.grounding_dino import GroundingDinoDetector, resize_shape
from bomc_bt.perception.mobile_sam import MobileSamSegmenter, box_prompt, preprocess_sam
from bomc_bt.perception.onnx_backend import build_onnx_backend
from bomc_bt.perception.onnx_common import OnnxPerceptionParams, resolve_providers
from bomc_bt.perception.tokenizer import PromptTokenizer, phrase_masks
from bomc_bt.robot import RGBDFrame

sys.path.insert(0, str(Path(__file__).parent))
import onnx_models as om  # noqa: E402

H, W = 480, 640
CATS = ["chair", "table", "door"]
# "[CLS] chair . table . door . [SEP]": token positions of each category.
TOKEN = {"chair": 1, "table": 3, "door": 5}
T = 256


def frame(stamp: float = 0.0, h: int = H, w: int = W, rgb: np.ndarray | None = None) -> RGBDFrame:
    rgb = np.full((h, w, 3), 120, np.uint8) if rgb is None else rgb
    K = np.array([[500.0, 0, w / 2], [0, 500.0, h / 2], [0, 0, 1]])
    return RGBDFrame(stamp, rgb, np.full((h, w), 2.0, np.float32), K, np.eye(4), np.eye(4))


def planted(queries: list[tuple[dict[str, float], tuple[float, float, float, float]]], q: int = 8):
    """Logits (q, 256) and normalised cx, cy, w, h boxes: one row per (token logits, pixel box)."""
    logits = np.full((q, T), -8.0, np.float32)
    logits[:, 8:] = -np.inf  # the HF export masks positions past the prompt
    boxes = np.tile(np.array([0.5, 0.5, 0.1, 0.1], np.float32), (q, 1))
    for i, (tokens, (x0, y0, x1, y1)) in enumerate(queries):
        for cat, logit in tokens.items():
            logits[i, TOKEN[cat]] = logit
        boxes[i] = [(x0 + x1) / 2 / W, (y0 + y1) / 2 / H, (x1 - x0) / W, (y1 - y0) / H]
    return logits, boxes


def logit(p: float) -> float:
    return math.log(p / (1 - p))


@pytest.fixture()
def tok(tmp_path: Path) -> Path:
    return om.write_tokenizer(tmp_path / "tokenizer.json")


def hf_detector(tmp_path, tok, queries, params=None, **kw) -> GroundingDinoDetector:
    logits, boxes = planted(queries)
    path = om.grounding_dino_hf(tmp_path / "gdino_hf.onnx", logits, boxes, **kw)
    return GroundingDinoDetector(path, tok, params or OnnxPerceptionParams())


# ---------------------------------------------------------------------------- detector
def test_hf_export_boxes_land_on_original_pixels_and_class_from_token_span(tmp_path, tok):
    det = hf_detector(tmp_path, tok, [({"table": 4.0}, (100.0, 50.0, 300.0, 200.0)),
                                      ({"door": 3.0, "chair": 1.5}, (400.0, 100.0, 520.0, 460.0))])
    assert det.signature == "huggingface"
    assert isinstance(det, Detector)
    out = det.detect(frame(), CATS)
    assert [d.category for d in out] == ["table", "door"]
    np.testing.assert_allclose(out[0].box, (100, 50, 300, 200), atol=1e-3)
    np.testing.assert_allclose(out[1].box, (400, 100, 520, 460), atol=1e-3)
    assert out[0].score == pytest.approx(1 / (1 + math.exp(-4.0)), abs=1e-5)


def test_dynamic_input_is_resized_shorter_side_800_keeping_aspect(tmp_path, tok):
    det = hf_detector(tmp_path, tok, [])
    feeds = det.prepare(frame().rgb, CATS).feeds
    assert feeds["pixel_values"].shape == (1, 3, 800, 1066)
    assert feeds["pixel_mask"].shape == (1, 800, 1066) and feeds["pixel_mask"].all()
    assert resize_shape(1000, 3000, 800, 1333) == (444, 1332)  # longer side capped (as HF rounds)
    assert resize_shape(640, 480, 800, 1333) == (1066, 800)  # portrait
    # ImageNet normalisation of a uniform grey image, channel by channel.
    expected = (120 / 255 - np.array([0.485, 0.456, 0.406])) / np.array([0.229, 0.224, 0.225])
    np.testing.assert_allclose(feeds["pixel_values"][0, :, 400, 500], expected, atol=1e-5)


def test_static_export_size_is_fed_exactly_and_boxes_still_map_to_original(tmp_path, tok):
    det = hf_detector(tmp_path, tok, [({"chair": 5.0}, (10.0, 20.0, 110.0, 220.0))], static_hw=(800, 800))
    assert det.static_hw == (800, 800)
    out = det.detect(frame(), CATS)  # onnxruntime rejects any other shape
    assert [d.category for d in out] == ["chair"]
    np.testing.assert_allclose(out[0].box, (10, 20, 110, 220), atol=1e-3)


def test_thresholds_box_text_and_per_category(tmp_path, tok):
    queries = [({"table": logit(0.80)}, (10.0, 10.0, 60.0, 60.0)),
               ({"door": logit(0.70)}, (100.0, 10.0, 160.0, 60.0)),
               ({"chair": logit(0.50)}, (200.0, 10.0, 260.0, 60.0))]
    default = hf_detector(tmp_path, tok, queries).detect(frame(), CATS)
    assert [d.category for d in default] == ["table"]  # paper: keep >= 0.75
    params = OnnxPerceptionParams(category_thresholds={"Door": 0.6}, default_category_threshold=0.75)
    assert [d.category for d in hf_detector(tmp_path, tok, queries, params).detect(frame(), CATS)] == \
        ["table", "door"]
    low = OnnxPerceptionParams(default_category_threshold=0.0, box_threshold=0.6, text_threshold=0.25)
    assert [d.category for d in hf_detector(tmp_path, tok, queries, low).detect(frame(), CATS)] == \
        ["table", "door"]  # the box threshold still drops the 0.5 chair
    text = OnnxPerceptionParams(default_category_threshold=0.0, box_threshold=0.0, text_threshold=0.75)
    assert [d.category for d in hf_detector(tmp_path, tok, queries, text).detect(frame(), CATS)] == ["table"]


def test_per_class_nms_keeps_overlapping_boxes_of_other_classes(tmp_path, tok):
    queries = [({"chair": 4.0}, (100.0, 100.0, 200.0, 200.0)),
               ({"chair": 3.0}, (105.0, 102.0, 205.0, 198.0)),  # duplicate, lower score
               ({"table": 3.5}, (104.0, 101.0, 204.0, 201.0)),  # same place, other class
               ({"chair": 3.8}, (400.0, 300.0, 480.0, 400.0))]
    out = hf_detector(tmp_path, tok, queries).detect(frame(), CATS)
    kept = sorted((d.category, round(d.box[0])) for d in out)
    assert kept == [("chair", 100), ("chair", 400), ("table", 104)]
    capped = hf_detector(tmp_path, tok, queries, OnnxPerceptionParams(max_detections=2)).detect(frame(), CATS)
    assert [d.score for d in capped] == sorted((d.score for d in out), reverse=True)[:2]


def test_multi_token_category_mean_versus_max(tmp_path, tok):
    cats = ["trash bin", "chair"]  # "[CLS] trash bin . chair . [SEP]": tokens 1-2 and 4
    logits = np.full((2, T), -8.0, np.float32)
    logits[0, 1], logits[0, 2] = logit(0.95), logit(0.65)  # mean 0.80, max 0.95
    boxes = np.array([[0.5, 0.5, 0.2, 0.2]] * 2, np.float32)
    path = om.grounding_dino_hf(tmp_path / "m.onnx", logits, boxes)
    by_max = GroundingDinoDetector(path, tok, OnnxPerceptionParams()).detect(frame(), cats)
    by_mean = GroundingDinoDetector(path, tok, OnnxPerceptionParams(span_score="mean")).detect(frame(), cats)
    assert by_max[0].category == by_mean[0].category == "trash bin"
    assert by_max[0].score == pytest.approx(0.95, abs=1e-4)
    assert by_mean[0].score == pytest.approx(0.80, abs=1e-4)


def test_original_export_gets_phrase_masks_as_bool_and_probabilities_are_detected(tmp_path, tok):
    logits, boxes = planted([({"door": 4.0}, (320.0, 40.0, 600.0, 470.0))])
    probs = 1 / (1 + np.exp(-np.nan_to_num(logits, neginf=-60)))  # an export with sigmoid inside
    path = om.grounding_dino_original(tmp_path / "orig.onnx", probs, boxes)
    det = GroundingDinoDetector(path, tok, OnnxPerceptionParams())
    assert det.signature == "original"
    feeds = det.prepare(frame().rgb, CATS).feeds
    assert feeds["text_token_mask"].shape == (1, 8, 8)
    out = det.detect(frame(), CATS)
    assert [d.category for d in out] == ["door"]
    np.testing.assert_allclose(out[0].box, (320, 40, 600, 470), atol=1e-3)
    assert out[0].score == pytest.approx(probs[0, TOKEN["door"]], abs=1e-5)


def test_original_export_with_static_text_length_is_padded(tmp_path, tok):
    logits, boxes = planted([({"chair": 4.0}, (0.0, 0.0, 50.0, 50.0))])
    path = om.grounding_dino_original(tmp_path / "o.onnx", logits, boxes, image_name="image", text_len=16)
    det = GroundingDinoDetector(path, tok, OnnxPerceptionParams())
    feeds = det.prepare(frame().rgb, CATS).feeds
    assert feeds["input_ids"].shape == (1, 16) and feeds["attention_mask"][0].tolist() == [1] * 8 + [0] * 8
    assert [d.category for d in det.detect(frame(), CATS)] == ["chair"]


def test_phrase_masks_match_the_original_repository():
    # [CLS] chair . trash bin . [SEP] with separators CLS=2, SEP=3, "."=5
    ids = np.array([2, 7, 5, 10, 11, 5, 3])
    mask, pos = phrase_masks(ids, [2, 3, 5])
    expected = np.zeros((7, 7), bool)
    expected[0, 0] = expected[6, 6] = True
    expected[1:3, 1:3] = True
    expected[3:6, 3:6] = True
    np.testing.assert_array_equal(mask, expected)
    assert pos.tolist() == [0, 0, 1, 0, 1, 2, 0]


def test_vocab_txt_and_tokenizer_json_agree(tmp_path, tok):
    vocab = om.write_vocab(tmp_path / "vocab.txt")
    a = PromptTokenizer(tok).encode(["Chair", "trash  bin"])
    b = PromptTokenizer(vocab).encode(["Chair", "trash  bin"])
    assert a.caption == "chair . trash bin ."
    np.testing.assert_array_equal(a.input_ids, b.input_ids)
    np.testing.assert_array_equal(a.category_tokens, b.category_tokens)
    assert a.category_tokens.astype(int).tolist() == [[0, 1, 0, 0, 0, 0, 0], [0, 0, 0, 1, 1, 0, 0]]


def test_bad_files_and_signatures_give_bomc_errors(tmp_path, tok):
    params = OnnxPerceptionParams()
    with pytest.raises(BomcError, match="not found"):
        GroundingDinoDetector(tmp_path / "missing.onnx", tok, params)
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model at all")
    with pytest.raises(BomcError, match=r"junk\.onnx.*not a loadable ONNX model"):
        GroundingDinoDetector(junk, tok, params)
    encoder = om.sam_encoder(tmp_path / "enc.onnx")
    with pytest.raises(BomcError) as err:
        GroundingDinoDetector(encoder, tok, params)
    msg = str(err.value)
    assert str(encoder) in msg and "pixel_values" in msg and "text_token_mask" in msg
    with pytest.raises(BomcError, match="SAM decoder"):
        MobileSamSegmenter(encoder, encoder, params)
    hf = om.grounding_dino_hf(tmp_path / "hf.onnx", *planted([]))
    with pytest.raises(BomcError, match="image encoder"):
        MobileSamSegmenter(hf, om.sam_box_decoder(tmp_path / "dec.onnx"), params)
    with pytest.raises(BomcError, match="tokenizer"):
        GroundingDinoDetector(hf, tmp_path / "nope.json", params)
    with pytest.raises(BomcError, match="contains '.'"):
        GroundingDinoDetector(hf, tok, params).detect(frame(), ["chair.leg"])
    with pytest.raises(BomcError, match="unknown execution provider"):
        resolve_providers(["CUDAExecutionProvidr"])


def test_unavailable_provider_falls_back_to_cpu_with_a_warning():
    import onnxruntime as ort

    missing = [p for p in ort.get_all_providers() if p not in ort.get_available_providers()]
    if not missing:
        pytest.skip("every execution provider onnxruntime knows is available here")
    with pytest.warns(RuntimeWarning, match="falling back"):
        assert resolve_providers([missing[0], "CPUExecutionProvider"]) == ["CPUExecutionProvider"]


# ---------------------------------------------------------------------------- segmenter
def test_box_mask_at_original_size_and_encoder_runs_once_per_frame(tmp_path):
    seg = MobileSamSegmenter(om.sam_encoder(tmp_path / "e.onnx"), om.sam_box_decoder(tmp_path / "d.onnx"),
                             OnnxPerceptionParams())
    assert isinstance(seg, Segmenter)
    boxes = [(100.0, 50.0, 300.0, 200.0), (350.0, 220.0, 630.0, 470.0), (0.0, 0.0, 40.0, 479.0)]
    f = frame()
    out = seg.segment(f, [Detection("chair", b, 0.9) for b in boxes])
    assert seg.encoder_runs == 1 and seg.decoder_runs == 3
    for d, (x0, y0, x1, y1) in zip(out, boxes, strict=True):
        assert d.mask.shape == (H, W) and d.mask.dtype == bool
        ys, xs = np.nonzero(d.mask)
        expected = (int(x0), math.ceil(x1) - 1, int(y0), math.ceil(y1) - 1)
        assert (xs.min(), xs.max(), ys.min(), ys.max()) == expected
    seg.segment(f, out[:1])
    assert seg.encoder_runs == 1  # same frame: cached embedding
    seg.segment(frame(stamp=0.1), out[:1])
    assert seg.encoder_runs == 2


def test_low_res_masks_are_upscaled_like_sam_and_best_iou_wins(tmp_path):
    low = np.full((3, 256, 256), -5.0, np.float32)
    low[0, 0:40, 0:40] = 5.0
    low[1, 64:128, 32:96] = 5.0  # the best one: 1024-space rows 256-512, cols 128-384
    low[2, 100:200, 100:200] = 5.0
    seg = MobileSamSegmenter(om.sam_encoder(tmp_path / "e.onnx"),
                             om.sam_lowres_decoder(tmp_path / "d.onnx", low, np.array([0.2, 0.9, 0.5])),
                             OnnxPerceptionParams())
    mask = seg.segment(frame(), [Detection("door", (0.0, 0.0, 10.0, 10.0), 0.9)])[0].mask
    assert mask.shape == (H, W)
    ys, xs = np.nonzero(mask)  # 640 px -> 1024: scale 1.6, so /1.6
    assert abs(ys.min() - 160) <= 1 and abs(ys.max() - 319) <= 1
    assert abs(xs.min() - 80) <= 1 and abs(xs.max() - 239) <= 1


def test_sam_preprocessing_and_box_prompt():
    rgb = np.zeros((H, W, 3), np.uint8)
    rgb[:, :, 0] = 255
    x = preprocess_sam(rgb)
    assert x.shape == (1, 3, 1024, 1024)
    assert x[0, 0, 100, 100] == pytest.approx((255 - 123.675) / 58.395, abs=1e-4)
    assert x[0, 1, 100, 100] == pytest.approx(-116.28 / 57.12, abs=1e-4)
    assert not x[:, :, 768:, :].any()  # 480 * 1.6 = 768 rows of image, then zero padding
    np.testing.assert_allclose(box_prompt((100, 50, 300, 200), (H, W)), [[[160, 80], [480, 320]]])


def test_hwc_encoder_export_gets_resized_raw_rgb(tmp_path):
    seg = MobileSamSegmenter(om.sam_encoder_hwc(tmp_path / "e.onnx"), om.sam_box_decoder(tmp_path / "d.onnx"),
                             OnnxPerceptionParams())
    assert seg.encoder_mode == "hwc"
    assert seg.preprocess(frame().rgb).shape == (768, 1024, 3)
    out = seg.segment(frame(), [Detection("tv", (10.0, 10.0, 20.0, 20.0), 0.9)])
    assert out[0].mask.sum() == 100


# ---------------------------------------------------------------------------- factory
def test_build_onnx_backend_resolves_relative_paths(tmp_path, tok):
    models = tmp_path / "models"
    models.mkdir()
    om.grounding_dino_hf(models / "gdino.onnx", *planted([({"door": 4.0}, (200.0, 100.0, 300.0, 400.0))]))
    om.sam_encoder(models / "enc.onnx")
    om.sam_box_decoder(models / "dec.onnx")
    params = OnnxPerceptionParams(detector_model="models/gdino.onnx", tokenizer=str(tok),
                                  segmenter_encoder="models/enc.onnx", segmenter_decoder="models/dec.onnx",
                                  prompts=CATS)
    detector, segmenter = build_onnx_backend(params, tmp_path)
    f = frame()
    out = segmenter.segment(f, detector.detect(f, []))  # no categories given: the prompts
    assert [d.category for d in out] == ["door"] and out[0].mask.sum() == 100 * 300
    with pytest.raises(BomcError, match="segmenter_decoder: missing"):
        build_onnx_backend(OnnxPerceptionParams(detector_model="models/gdino.onnx", tokenizer=str(tok),
                                                segmenter_encoder="models/enc.onnx"), tmp_path)


def test_params_from_yaml_mapping_reject_bad_values():
    from bomc_bt.params import from_mapping

    p = from_mapping(OnnxPerceptionParams, {"box_threshold": 0.3, "category_thresholds": {"chair": 0.8}},
                     "cfg.yaml", "perception.onnx")
    assert p.category_thresholds == {"chair": 0.8} and p.providers == ["CPUExecutionProvider"]
    with pytest.raises(BomcError, match="cfg.yaml.*box_threshold must be in"):
        from_mapping(OnnxPerceptionParams, {"box_threshold": 1.5}, "cfg.yaml", "perception.onnx")
    with pytest.raises(BomcError, match="span_score"):
        from_mapping(OnnxPerceptionParams, {"span_score": "median"}, "cfg.yaml", "perception.onnx")


# ---------------------------------------------------------------------------- end to end
def test_planted_detection_becomes_a_graph_node_at_the_expected_map_position(tmp_path, tok):
    from bomc_bt.geometry import Pose2D, se3
    from bomc_bt.graph import AssociationParams, ObjectGraph
    from bomc_bt.perception import projection

    # A box 1 m wide at 3 m in front of a camera 0.5 m up on a robot at (2, 1) facing +y.
    depth = np.full((H, W), 6.0, np.float32)  # wall behind
    x0, y0, x1, y1 = 240, 160, 400, 320
    depth[y0:y1, x0:x1] = 3.0
    K = np.array([[500.0, 0, W / 2], [0, 500.0, H / 2], [0, 0, 1]])
    R_base_cam = np.array([[0.0, 0, 1], [-1, 0, 0], [0, -1, 0]])  # optical z forward = base x
    f = RGBDFrame(0.0, np.full((H, W, 3), 90, np.uint8), depth, K,
                  Pose2D(2.0, 1.0, math.pi / 2).to_matrix(), se3(R_base_cam, np.array([0.0, 0.0, 0.5])))
    queries = [({"table": 4.0}, (float(x0), float(y0), float(x1), float(y1)))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        detector = hf_detector(tmp_path, tok, queries)
        segmenter = MobileSamSegmenter(om.sam_encoder(tmp_path / "e.onnx"),
                                       om.sam_box_decoder(tmp_path / "d.onnx"), OnnxPerceptionParams())
    dets = segmenter.segment(f, detector.detect(f, CATS))
    obs = projection.detections_to_observations(f, dets, projection.ProjectionParams())
    assert [o.category for o in obs] == ["table"]
    # Pixel centre (320, 240) at 3 m is straight ahead: base x 3 m -> map (2, 4), z 0.5 m.
    np.testing.assert_allclose(obs[0].position, [2.0, 4.0, 0.5], atol=0.05)
    graph = ObjectGraph(AssociationParams(confirm_detections=1))  # one frame: no second sighting
    graph.associate(obs, expected=[], session=1, stamp=0.0)
    nodes = list(graph.nodes.values())
    assert len(nodes) == 1 and nodes[0].category == "table"
    np.testing.assert_allclose(nodes[0].position, [2.0, 4.0, 0.5], atol=0.05)
