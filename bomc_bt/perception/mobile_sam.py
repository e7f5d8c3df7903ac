"""MobileSAM / SAM through onnxruntime: the promptable :class:`Segmenter` of the paper.

SAM splits into a heavy image encoder (run once per frame: its 1 x 256 x 64 x 64 embedding
is cached by frame) and a light prompt decoder (``SamOnnxModel`` from segment-anything's
or MobileSAM's ``scripts/export_onnx_model.py``) run once per detection box. A box is fed
as two points labelled 2 (top-left) and 3 (bottom-right) in the coordinates of the image
resized so its longest side is 1024; the decoder upsamples its mask logits to
``orig_im_size`` and logits > 0 are the object. Encoder exports come in two forms, told
apart by the input's rank: (1, 3, 1024, 1024) normalised and padded by us, or samexporter's
``--use-preprocess`` (H, W, 3) raw RGB that normalises and pads inside the graph.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.perception.frames import Detection
from bomc_bt.perception.onnx_common import OnnxModel, OnnxPerceptionParams, load_model, match_export, normalise_into
from bomc_bt.robot import RGBDFrame

SAM_PIXEL_MEAN = np.array([123.675, 116.28, 103.53], dtype=np.float32)
SAM_PIXEL_STD = np.array([58.395, 57.12, 57.375], dtype=np.float32)
SAM_IMAGE_SIZE = 1024

DECODER_SIGNATURE = {
    "SamOnnxModel": ("image_embeddings", "point_coords", "point_labels", "mask_input", "has_mask_input",
                     "orig_im_size"),
}
DECODER_OUTPUTS = {"SamOnnxModel": ("masks", "iou_predictions")}  # what decode_box reads
BOX_LABELS = np.array([[2.0, 3.0]], dtype=np.float32)  # SAM's labels for box corners


def resize_longest(h: int, w: int, size: int = SAM_IMAGE_SIZE) -> tuple[int, int]:
    """SAM's ResizeLongestSide target (h, w): longest side to ``size``, rounded."""
    scale = size / max(h, w)
    return int(h * scale + 0.5), int(w * scale + 0.5)


def preprocess_sam(rgb: np.ndarray, size: int = SAM_IMAGE_SIZE) -> np.ndarray:
    """uint8 RGB (H, W, 3) -> float32 (1, 3, size, size): resized, normalised, padded bottom-right."""
    new_h, new_w = resize_longest(rgb.shape[0], rgb.shape[1], size)
    resized = cv2.resize(rgb, (new_w, new_h), interpolation=cv2.INTER_LINEAR)
    x = np.zeros((1, 3, size, size), dtype=np.float32)
    normalise_into(x[0], resized, 1.0 / SAM_PIXEL_STD, SAM_PIXEL_MEAN / SAM_PIXEL_STD)
    return x


def box_prompt(box: tuple[float, float, float, float], image_hw: tuple[int, int],
               size: int = SAM_IMAGE_SIZE) -> np.ndarray:
    """A pixel box of the original image as SAM's two corner points (1, 2, 2) in resized coords."""
    h, w = image_hw
    new_h, new_w = resize_longest(h, w, size)
    scale = np.array([new_w / w, new_h / h], dtype=np.float64)
    corners = np.asarray(box, dtype=np.float64).reshape(2, 2) * scale
    return corners[None].astype(np.float32)


def upscale_low_res(logits: np.ndarray, image_hw: tuple[int, int], size: int = SAM_IMAGE_SIZE) -> np.ndarray:
    """Mask logits over the padded square (e.g. 256 x 256) -> logits at the original size.

    SAM's own postprocessing: up to the padded input, crop the part the image fills, then
    resize to the original. Needed when a decoder returns masks smaller than orig_im_size.
    """
    h, w = image_hw
    new_h, new_w = resize_longest(h, w, size)
    padded = cv2.resize(logits.astype(np.float32), (size, size), interpolation=cv2.INTER_LINEAR)
    return cv2.resize(padded[:new_h, :new_w], (w, h), interpolation=cv2.INTER_LINEAR)


class MobileSamSegmenter:
    """Masks for detection boxes with user-supplied MobileSAM (or SAM) ONNX exports."""

    def __init__(self, encoder_path: str | Path, decoder_path: str | Path, params: OnnxPerceptionParams):
        self.params = params
        self.encoder: OnnxModel = load_model(encoder_path, params.providers, "segmenter_encoder")
        self.decoder: OnnxModel = load_model(decoder_path, params.providers, "segmenter_decoder")
        self._encoder_input, self.encoder_mode = self._encoder_signature()
        spec = self.encoder.inputs[self._encoder_input]
        self.image_size = (spec.static_dim(2) if self.encoder_mode == "chw" else None) or SAM_IMAGE_SIZE
        match_export(self.decoder, DECODER_SIGNATURE, DECODER_OUTPUTS, "SAM decoder")
        mask_spec = self.decoder.inputs["mask_input"]
        self._mask_hw = (mask_spec.static_dim(2) or 256, mask_spec.static_dim(3) or 256)
        self.encoder_runs = 0
        self.decoder_runs = 0
        self._cached_rgb: np.ndarray | None = None
        self._cached_stamp: float | None = None
        self._cached_embedding: np.ndarray | None = None

    def segment(self, frame: RGBDFrame, detections: list[Detection]) -> list[Detection]:
        """Each detection with its mask (bool, original image size); the encoder runs once per frame."""
        if frame.rgb is None or not detections:
            return list(detections)
        embedding = self.encode(frame)
        hw = (int(frame.rgb.shape[0]), int(frame.rgb.shape[1]))
        return [d.with_mask(self.mask_for_box(embedding, d.box, hw)) for d in detections]

    def encode(self, frame: RGBDFrame) -> np.ndarray:
        """The frame's image embedding, computed once and reused for every box of that frame."""
        if self._cached_rgb is frame.rgb and self._cached_stamp == frame.stamp:
            return self._cached_embedding
        embedding = self.run_encoder(self.preprocess(frame.rgb))
        self._cached_rgb, self._cached_stamp, self._cached_embedding = frame.rgb, frame.stamp, embedding
        return embedding

    def preprocess(self, rgb: np.ndarray) -> np.ndarray:
        if self.encoder_mode == "hwc":
            new_h, new_w = resize_longest(rgb.shape[0], rgb.shape[1], self.image_size)
            return cv2.resize(rgb, (new_w, new_h), interpolation=cv2.INTER_LINEAR).astype(np.float32)
        return preprocess_sam(rgb, self.image_size)

    def run_encoder(self, x: np.ndarray) -> np.ndarray:
        self.encoder_runs += 1
        out = self.encoder.run({self._encoder_input: x})
        embedding = next(iter(out.values()))
        if embedding.ndim != 4:
            raise BomcError(f"encoder output has shape {embedding.shape}; expected (1, 256, 64, 64)",
                            self.encoder.path)
        return embedding

    def mask_for_box(self, embedding: np.ndarray, box: tuple[float, float, float, float],
                     image_hw: tuple[int, int]) -> np.ndarray:
        """The decoder's best mask (highest predicted IoU) for one box, bool at the original size."""
        logits = self.decode_box(embedding, box, image_hw)
        return logits > self.params.mask_threshold

    def decode_box(self, embedding: np.ndarray, box: tuple[float, float, float, float],
                   image_hw: tuple[int, int]) -> np.ndarray:
        """Mask logits (H, W) for one box."""
        feeds = {
            "image_embeddings": embedding,
            "point_coords": box_prompt(box, image_hw, self.image_size),
            "point_labels": BOX_LABELS,
            "mask_input": np.zeros((1, 1, *self._mask_hw), dtype=np.float32),
            "has_mask_input": np.zeros(1, dtype=np.float32),
            "orig_im_size": np.asarray(image_hw, dtype=np.float32),
        }
        self.decoder_runs += 1
        out = self.decoder.run(feeds, ["masks", "iou_predictions"])
        masks, iou = out["masks"], out["iou_predictions"]
        if masks.ndim != 4 or masks.shape[1] < 1:
            raise BomcError(f"decoder masks have shape {masks.shape}; expected (1, N, H, W)",
                            self.decoder.path)
        best = int(np.argmax(np.asarray(iou).reshape(-1)[: masks.shape[1]])) if np.size(iou) else 0
        logits = masks[0, best]
        if logits.shape != tuple(image_hw):
            logits = upscale_low_res(logits, image_hw, self.image_size)
        return logits

    def _encoder_signature(self) -> tuple[str, str]:
        inputs = list(self.encoder.inputs.values())
        if len(inputs) == 1 and len(inputs[0].shape) in (3, 4):
            return inputs[0].name, ("chw" if len(inputs[0].shape) == 4 else "hwc")
        found = ", ".join(f"{i.name}{list(i.shape)}" for i in inputs) or "none"
        raise BomcError(f"SAM image encoder inputs ({found}) match no known signature (expected one float "
                        "image input: (1, 3, 1024, 1024) normalised, or (H, W, 3) RGB with preprocessing "
                        "inside)", self.encoder.path)
