"""Loading user-supplied ONNX models: sessions, execution providers, signature checks.

Model weights are never bundled: users export GroundingDINO and MobileSAM themselves
(docs/perception-onnx.md). Exports differ in input names, dtypes and static sizes, so
every backend goes through here to turn a bad file or an unexpected export into one
:class:`BomcError` that names the file and lists what was expected, and to feed each
input in the dtype the session declares (bool vs int64 masks differ between exports).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from bomc_bt.errors import BomcError

CPU_PROVIDER = "CPUExecutionProvider"

# ONNX tensor type strings (as onnxruntime reports them) -> numpy dtypes we can feed.
_ONNX_DTYPES: dict[str, type] = {
    "tensor(float)": np.float32,
    "tensor(float16)": np.float16,
    "tensor(double)": np.float64,
    "tensor(int64)": np.int64,
    "tensor(int32)": np.int32,
    "tensor(bool)": np.bool_,
    "tensor(uint8)": np.uint8,
}


@dataclass
class OnnxPerceptionParams:
    """The ``perception.onnx`` config block: model files, prompts, thresholds, providers.

    Paths may be relative: :func:`bomc_bt.perception.onnx_backend.build_onnx_backend` resolves
    them against the folder of the config file that named them. Defaults follow the GroundingDINO README (box 0.35,
    text 0.25) and the paper (detections kept at confidence >= 0.75).
    """

    detector_model: str = ""  # GroundingDINO .onnx (Hugging Face or original signature)
    tokenizer: str = ""  # tokenizer.json of the model's text encoder, or a BERT vocab.txt
    segmenter_encoder: str = ""  # MobileSAM / SAM image encoder .onnx
    segmenter_decoder: str = ""  # SamOnnxModel prompt decoder .onnx
    prompts: list[str] = field(default_factory=list)  # categories when the caller names none
    box_threshold: float = 0.35
    text_threshold: float = 0.25
    category_thresholds: dict[str, float] = field(default_factory=dict)
    default_category_threshold: float = 0.75
    span_score: Literal["max", "mean"] = "max"  # how a category's token scores combine
    detector_scores: Literal["auto", "logits", "probabilities"] = "auto"  # sigmoid inside the export?
    nms_iou: float = 0.5
    max_detections: int = 50
    min_size: int = 800  # shorter image side fed to a dynamic-size detector
    max_size: int = 1333  # cap on the longer side
    mask_threshold: float = 0.0  # SAM mask logits above this are the object
    providers: list[str] = field(default_factory=lambda: [CPU_PROVIDER])

    def __post_init__(self) -> None:
        for name in ("box_threshold", "text_threshold", "default_category_threshold"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1]")
        for cat, value in self.category_thresholds.items():
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"category_thresholds.{cat} must be in [0, 1]")
        if not 0.0 < self.nms_iou <= 1.0:
            raise ValueError("nms_iou must be in (0, 1]")
        if self.max_detections < 1:
            raise ValueError("max_detections must be >= 1")
        if not 0 < self.min_size <= self.max_size:
            raise ValueError("min_size and max_size must satisfy 0 < min_size <= max_size")


@dataclass(frozen=True)
class TensorSpec:
    """One model input or output: name, numpy dtype, shape (None or str = dynamic)."""

    name: str
    dtype: type
    shape: tuple[int | str | None, ...]

    def static_dim(self, axis: int) -> int | None:
        """The size of ``axis`` if the export fixed it, else None."""
        if axis >= len(self.shape) or axis < -len(self.shape):
            return None
        d = self.shape[axis]
        return d if isinstance(d, int) and d > 0 else None


class OnnxModel:
    """An onnxruntime session plus its declared inputs and outputs."""

    def __init__(self, session, path: Path):
        self.session = session
        self.path = path
        self.inputs = {i.name: _spec(i) for i in session.get_inputs()}
        self.outputs = {o.name: _spec(o) for o in session.get_outputs()}

    @property
    def providers(self) -> list[str]:
        return list(self.session.get_providers())

    def run(self, feeds: dict[str, np.ndarray], outputs: list[str] | None = None) -> dict[str, np.ndarray]:
        """Run with every feed cast to the dtype the export declares; returns name -> array."""
        cast = {n: np.ascontiguousarray(a, dtype=self.inputs[n].dtype) for n, a in feeds.items()}
        names = outputs or list(self.outputs)
        try:
            values = self.session.run(names, cast)
        except Exception as exc:  # onnxruntime raises its own exception types per failure
            shapes = ", ".join(f"{n}{tuple(a.shape)}" for n, a in cast.items())
            raise BomcError(f"model failed to run on inputs {shapes}: {exc}", self.path) from None
        return dict(zip(names, values, strict=True))


def resolve_providers(requested: list[str] | tuple[str, ...], field: str = "providers") -> list[str]:
    """The requested execution providers that this onnxruntime build has, CPU always last.

    A name onnxruntime does not know at all is a typo -> BomcError. A known provider that
    this machine lacks (CUDA without a GPU build) is dropped with a warning, so the same
    config runs on a laptop and on the robot.
    """
    import onnxruntime as ort

    known = set(ort.get_all_providers())
    available = set(ort.get_available_providers())
    chosen: list[str] = []
    for name in requested:
        if name not in known:
            raise BomcError(f"unknown execution provider {name!r} (known: {', '.join(sorted(known))})",
                            field=field)
        if name not in available:
            warnings.warn(f"ONNX execution provider {name} is not available here; falling back to "
                          f"{CPU_PROVIDER}", RuntimeWarning, stacklevel=2)
            continue
        if name not in chosen:
            chosen.append(name)
    if CPU_PROVIDER not in chosen:
        chosen.append(CPU_PROVIDER)
    return chosen


def load_model(path: str | Path, providers: list[str] | tuple[str, ...], field: str) -> OnnxModel:
    """Open an ONNX file as a session; a missing, unreadable or corrupt file -> BomcError."""
    p = Path(path)
    if not p.is_file():
        raise BomcError(f"ONNX model file not found ({field})", p)
    try:
        with p.open("rb") as fh:
            fh.read(1)
    except OSError as exc:
        raise BomcError(f"cannot read ONNX model ({field}): {exc.strerror or exc}", p) from None
    import onnxruntime as ort

    chosen = resolve_providers(providers)
    options = ort.SessionOptions()
    options.log_severity_level = 3  # onnxruntime's own warnings are noise for users
    try:
        session = ort.InferenceSession(str(p), sess_options=options, providers=chosen)
    except Exception as exc:  # InvalidProtobuf, Fail, NotImplemented...: all "not a usable model"
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise BomcError(f"not a loadable ONNX model ({field}): {first}", p) from None
    return OnnxModel(session, p)


def match_signature(model: OnnxModel, signatures: dict[str, tuple[str, ...]], what: str) -> str:
    """Which known signature the model's input names contain; else BomcError listing them all.

    Signatures are tried in order and must be distinguishable by their names alone.
    """
    names = set(model.inputs)
    for key, required in signatures.items():
        if set(required) <= names:
            return key
    expected = "; ".join(f"{key}: {', '.join(req)}" for key, req in signatures.items())
    raise BomcError(
        f"inputs ({', '.join(sorted(names)) or 'none'}) match no known {what} signature "
        f"(expected one of - {expected})",
        model.path,
    )


def match_export(model: OnnxModel, signatures: dict[str, tuple[str, ...]],
                 outputs: dict[str, tuple[str, ...]], what: str) -> str:
    """The model's signature (see :func:`match_signature`), checked to have the outputs it needs.

    ``outputs`` names, per signature, the outputs the backend reads; every backend asks
    both questions of each model it opens, so a bad export fails on one line here.
    """
    key = match_signature(model, signatures, what)
    require_outputs(model, outputs[key], what)
    return key


def require_outputs(model: OnnxModel, names: tuple[str, ...], what: str) -> None:
    """Check the outputs a backend reads exist, naming the file when they do not."""
    missing = [n for n in names if n not in model.outputs]
    if missing:
        raise BomcError(
            f"{what} outputs ({', '.join(model.outputs) or 'none'}) lack {', '.join(missing)} "
            f"(expected {', '.join(names)})",
            model.path,
        )


def normalise_into(out: np.ndarray, rgb: np.ndarray, scale: np.ndarray, offset: np.ndarray) -> None:
    """out[c, :h, :w] = rgb[..., c] * scale[c] - offset[c], one contiguous plane at a time.

    Per-plane in-place arithmetic is ~4x faster than broadcasting over an (H, W, 3) array
    and transposing, and this runs on every frame at ~1 Mpixel.
    """
    h, w = rgb.shape[:2]
    for c, plane in enumerate(cv2.split(rgb)):
        view = out[c, :h, :w]
        view[...] = plane
        view *= scale[c]
        view -= offset[c]


def _spec(arg) -> TensorSpec:
    dtype = _ONNX_DTYPES.get(arg.type, np.float32)
    shape = tuple(d if isinstance(d, int) else None for d in (arg.shape or ()))
    return TensorSpec(arg.name, dtype, shape)
