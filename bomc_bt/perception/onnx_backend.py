"""Building the ONNX perception backend (GroundingDINO detector + MobileSAM segmenter).

The one place that knows both model modules: :mod:`.onnx_common` holds what every
backend shares (sessions, providers, signature checks, the params record) and the model
modules build on it, so the factory that picks and wires them lives above all three and
none of them imports another's caller -- no import cycle.
"""

from __future__ import annotations

from pathlib import Path

from bomc_bt.errors import BomcError
from bomc_bt.perception.frames import Detector, Segmenter
from bomc_bt.perception.grounding_dino import GroundingDinoDetector
from bomc_bt.perception.mobile_sam import MobileSamSegmenter
from bomc_bt.perception.onnx_common import OnnxPerceptionParams


def resolve_path(value: str, base_dir: str | Path, field_name: str) -> Path:
    """A configured model path, relative ones taken from the config file's folder."""
    if not value:
        raise BomcError("missing (path to the model file)", field=field_name)
    p = Path(value).expanduser()
    return p if p.is_absolute() else Path(base_dir) / p


def build_onnx_backend(params: OnnxPerceptionParams, base_dir: str | Path) -> tuple[Detector, Segmenter]:
    """The GroundingDINO detector and MobileSAM segmenter the params name, ready to run.

    Returns ``(Detector, Segmenter)``; model paths relative to ``base_dir`` (the folder of
    the config file that named them).
    """
    detector = GroundingDinoDetector(
        resolve_path(params.detector_model, base_dir, "detector_model"),
        resolve_path(params.tokenizer, base_dir, "tokenizer"),
        params,
    )
    segmenter = MobileSamSegmenter(
        resolve_path(params.segmenter_encoder, base_dir, "segmenter_encoder"),
        resolve_path(params.segmenter_decoder, base_dir, "segmenter_decoder"),
        params,
    )
    return detector, segmenter
