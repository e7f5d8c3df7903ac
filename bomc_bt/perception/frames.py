"""What detectors and segmenters exchange, and the protocols they implement.

The paper assumes two interchangeable parts: an open-vocabulary detector that returns a
category and a box per object, and a promptable segmenter that returns the mask inside
each box. Any backend (the simulator's, ONNX GroundingDINO + MobileSAM) meets these.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

import numpy as np

from bomc_bt.robot import RGBDFrame


@dataclass
class Detection:
    """One object found in an image.

    ``box`` is (x0, y0, x1, y1) in pixels of the original image; ``mask`` is a bool
    (H, W) array in the original image size, or None until a segmenter has run.
    """

    category: str
    box: tuple[float, float, float, float]
    score: float
    mask: np.ndarray | None = None

    def with_mask(self, mask: np.ndarray) -> Detection:
        return replace(self, mask=mask)


@runtime_checkable
class Detector(Protocol):
    """Open-vocabulary detector: categories are prompts chosen at deployment time."""

    def detect(self, frame: RGBDFrame, categories: list[str]) -> list[Detection]: ...


@runtime_checkable
class Segmenter(Protocol):
    """Promptable segmenter: one mask per detection box."""

    def segment(self, frame: RGBDFrame, detections: list[Detection]) -> list[Detection]: ...
