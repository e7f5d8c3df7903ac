"""GroundingDINO through onnxruntime: the open-vocabulary :class:`Detector` of the paper.

Two export signatures are accepted, told apart by the session's input names:

* ``huggingface`` - ``GroundingDinoForObjectDetection`` exported with torch.onnx/optimum:
  pixel_values (1, 3, H, W), input_ids, attention_mask, [token_type_ids, pixel_mask]
  -> logits (1, Q, 256), pred_boxes (1, Q, 4). The model builds the phrase masks itself.
* ``original`` - the IDEA-Research repository's model wrapped for export: img (or image),
  input_ids, attention_mask, position_ids, token_type_ids, text_token_mask (1, L, L)
  -> logits, boxes. Here the host computes the phrase masks (see :mod:`.tokenizer`).

Both emit per-query, per-token scores and normalised (cx, cy, w, h) boxes. How a query
becomes a :class:`Detection`: its class is the prompt category whose tokens score highest
(max, or mean, of the sigmoid over the category's tokens), its score is that value, and it
is kept when score >= max(box_threshold, text_threshold, the category's threshold); then
per-class non-maximum suppression and a cap on the count. The box is in the original image.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.onnx_common import OnnxModel, OnnxPerceptionParams, load_model, match_export, normalise_into
from bomc_bt.perception.tokenizer import PromptTokenizer, TokenizedPrompt, normalise_category
from bomc_bt.robot import RGBDFrame

IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], dtype=np.float32)

# Tried in order; the original signature is more specific, so it goes first.
SIGNATURES: dict[str, tuple[str, ...]] = {
    "original": ("img", "input_ids", "attention_mask", "position_ids", "token_type_ids", "text_token_mask"),
    "original-image": ("image", "input_ids", "attention_mask", "position_ids", "token_type_ids",
                       "text_token_mask"),
    "huggingface": ("pixel_values", "input_ids", "attention_mask"),
}
_OPTIONAL = {"huggingface": ("token_type_ids", "pixel_mask")}
_OUTPUTS = {"huggingface": ("logits", "pred_boxes"), "original": ("logits", "boxes"),
            "original-image": ("logits", "boxes")}


@dataclass
class PreparedInputs:
    """What one detect() call feeds the model, and what decoding needs to undo it."""

    feeds: dict[str, np.ndarray]
    prompt: TokenizedPrompt
    image_hw: tuple[int, int]  # original image (H, W)


def resize_shape(h: int, w: int, min_size: int, max_size: int) -> tuple[int, int]:
    """GroundingDINO's resize: shorter side to ``min_size`` unless the longer would pass ``max_size``."""
    short, long = min(h, w), max(h, w)
    size = float(min_size)
    if long / short * size > max_size:
        size = float(round(max_size * short / long))
    if h <= w:
        return int(size), int(size * w / h)
    return int(size * h / w), int(size)


def preprocess_image(rgb: np.ndarray, out_hw: tuple[int, int]) -> np.ndarray:
    """uint8 RGB (H, W, 3) -> float32 (1, 3, h, w), bilinear resize, ImageNet normalisation."""
    h, w = out_hw
    resized = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_LINEAR)
    x = np.empty((1, 3, h, w), dtype=np.float32)
    normalise_into(x[0], resized, 1.0 / (255.0 * IMAGENET_STD), IMAGENET_MEAN / IMAGENET_STD)
    return x


def sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x, -60.0, 60.0)))


def nms_per_class(boxes: np.ndarray, scores: np.ndarray, classes: np.ndarray, iou: float) -> np.ndarray:
    """Indices kept by greedy non-maximum suppression within each class, best score first."""
    order = np.argsort(-scores, kind="stable")
    x0, y0, x1, y1 = boxes.T
    area = np.maximum(x1 - x0, 0) * np.maximum(y1 - y0, 0)
    suppressed = np.zeros(len(scores), dtype=bool)
    keep: list[int] = []
    for i in order:
        if suppressed[i]:
            continue
        keep.append(int(i))
        ix = np.maximum(0, np.minimum(x1[i], x1) - np.maximum(x0[i], x0))
        iy = np.maximum(0, np.minimum(y1[i], y1) - np.maximum(y0[i], y0))
        inter = ix * iy
        overlap = inter / np.maximum(area[i] + area - inter, 1e-12)
        suppressed |= (overlap > iou) & (classes == classes[i])
    return np.asarray(keep, dtype=np.int64)


class GroundingDinoDetector:
    """Open-vocabulary detection with a user-supplied GroundingDINO ONNX export."""

    def __init__(self, model_path: str | Path, tokenizer_path: str | Path, params: OnnxPerceptionParams):
        self.params = params
        self.model: OnnxModel = load_model(model_path, params.providers, "detector_model")
        self.signature = match_export(self.model, SIGNATURES, _OUTPUTS, "GroundingDINO")
        known = set(SIGNATURES[self.signature]) | set(_OPTIONAL.get(self.signature, ()))
        extra = sorted(set(self.model.inputs) - known)
        if extra:
            raise BomcError(f"GroundingDINO export has inputs this backend cannot fill: {', '.join(extra)}",
                            self.model.path)
        self.tokenizer = PromptTokenizer(tokenizer_path)
        self._image_name = SIGNATURES[self.signature][0]
        spec = self.model.inputs[self._image_name]
        h, w = spec.static_dim(2), spec.static_dim(3)
        self.static_hw = (h, w) if h and w else None
        self.text_length = self.model.inputs["input_ids"].static_dim(1)
        self._thresholds = {normalise_category(k): v for k, v in params.category_thresholds.items()}
        self._prompts: dict[tuple[str, ...], TokenizedPrompt] = {}

    # -- the Detector protocol ------------------------------------------------------------
    def detect(self, frame: RGBDFrame, categories: list[str]) -> list[Detection]:
        """Detections of ``categories`` (or the configured prompts) in the frame's RGB image."""
        cats = list(categories) or list(self.params.prompts)
        if frame.rgb is None or not cats:
            return []
        prepared = self.prepare(frame.rgb, cats)
        logits, boxes = self.infer(prepared)
        return self.decode(prepared, logits, boxes)

    # -- the three stages (public so the benchmark can time them) -------------------------
    def prepare(self, rgb: np.ndarray, categories: list[str]) -> PreparedInputs:
        """Resize + normalise the image and tokenize the prompt (cached per category list)."""
        h, w = int(rgb.shape[0]), int(rgb.shape[1])
        out_hw = self.static_hw or resize_shape(h, w, self.params.min_size, self.params.max_size)
        prompt = self.prompt(categories)
        feeds = {self._image_name: preprocess_image(rgb, out_hw),
                 "input_ids": prompt.input_ids, "attention_mask": prompt.attention_mask}
        inputs = self.model.inputs
        if "token_type_ids" in inputs:
            feeds["token_type_ids"] = prompt.token_type_ids
        if "pixel_mask" in inputs:
            feeds["pixel_mask"] = np.ones((1, *out_hw), dtype=np.int64)
        if "position_ids" in inputs:
            feeds["position_ids"] = prompt.position_ids
        if "text_token_mask" in inputs:
            feeds["text_token_mask"] = prompt.text_mask
        return PreparedInputs(feeds, prompt, (h, w))

    def prompt(self, categories: list[str]) -> TokenizedPrompt:
        key = tuple(categories)
        if key not in self._prompts:
            self._prompts[key] = self.tokenizer.encode(list(categories), self.text_length)
        return self._prompts[key]

    def infer(self, prepared: PreparedInputs) -> tuple[np.ndarray, np.ndarray]:
        """Run the model: per-query token scores (Q, T) and boxes (Q, 4)."""
        logits_name, boxes_name = _OUTPUTS[self.signature]
        out = self.model.run(prepared.feeds, [logits_name, boxes_name])
        logits, boxes = out[logits_name], out[boxes_name]
        if logits.ndim != 3 or boxes.ndim != 3 or boxes.shape[-1] != 4 or logits.shape[1] != boxes.shape[1]:
            shapes = f"{logits_name}{logits.shape}, {boxes_name}{boxes.shape}"
            raise BomcError(f"unexpected output shapes {shapes} (expected (1, Q, T) and (1, Q, 4))",
                            self.model.path)
        return logits[0], boxes[0]

    def decode(self, prepared: PreparedInputs, logits: np.ndarray, boxes: np.ndarray) -> list[Detection]:
        """Token scores -> category and score per query; thresholds, boxes in pixels, NMS."""
        prompt = prepared.prompt
        n = int(prompt.attention_mask.sum())
        if logits.shape[1] < n:
            raise BomcError(f"the prompt has {n} tokens but the model scores only {logits.shape[1]}; "
                            "use fewer or shorter categories", self.model.path)
        probs = self._probabilities(logits[:, : prompt.length])
        cls, score = self.category_scores(probs, prompt.category_tokens)
        floor = max(self.params.box_threshold, self.params.text_threshold)
        thr = np.array([max(floor, self._threshold(c)) for c in prompt.categories])
        xyxy = self.to_pixels(boxes, prepared.image_hw)
        valid = (xyxy[:, 2] > xyxy[:, 0]) & (xyxy[:, 3] > xyxy[:, 1])
        idx = np.flatnonzero((score >= thr[cls]) & valid)
        if idx.size == 0:
            return []
        kept = idx[nms_per_class(xyxy[idx], score[idx], cls[idx], self.params.nms_iou)]
        kept = kept[np.argsort(-score[kept], kind="stable")][: self.params.max_detections]
        return [Detection(prompt.categories[cls[i]], tuple(float(v) for v in xyxy[i]), float(score[i]))
                for i in kept]

    def category_scores(self, probs: np.ndarray, tokens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per query: the best category (index) and its score over that category's tokens."""
        if self.params.span_score == "mean":
            counts = np.maximum(tokens.sum(axis=1), 1)
            per_cat = (probs @ tokens.T.astype(probs.dtype)) / counts
            per_cat[:, tokens.sum(axis=1) == 0] = 0.0
        else:
            per_cat = np.where(tokens[None], probs[:, None, :], 0.0).max(axis=2)
        cls = per_cat.argmax(axis=1)
        return cls, per_cat[np.arange(len(cls)), cls]

    @staticmethod
    def to_pixels(boxes: np.ndarray, image_hw: tuple[int, int]) -> np.ndarray:
        """Normalised (cx, cy, w, h) -> (x0, y0, x1, y1) pixels of the original image, clipped.

        The model normalises by the size of the image it saw; that image is the original
        resized (keeping aspect, or stretched to a static export size), so scaling by the
        original size undoes both.
        """
        h, w = image_hw
        cx, cy, bw, bh = boxes.astype(np.float64).T
        xyxy = np.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2], axis=1) * [w, h, w, h]
        return np.clip(xyxy, 0.0, [w, h, w, h])

    def _probabilities(self, logits: np.ndarray) -> np.ndarray:
        mode = self.params.detector_scores
        if mode == "auto":
            finite = logits[np.isfinite(logits)]
            mode = "probabilities" if finite.size and finite.min() >= 0 and finite.max() <= 1 else "logits"
        if mode == "probabilities":
            return np.nan_to_num(logits.astype(np.float32), nan=0.0, posinf=1.0, neginf=0.0)
        return sigmoid(logits.astype(np.float32))

    def _threshold(self, category: str) -> float:
        return self._thresholds.get(normalise_category(category), self.params.default_category_threshold)
