"""The simulated open-vocabulary detector and promptable segmenter, in one.

It reads the instance image the simulated camera renders (ground truth per pixel) and
turns it into what a GroundingDINO + SAM pipeline would return, with an honest noise model
(preset ``realistic``) or none at all (preset ``perfect``).

What ``realistic`` models, per frame and per visible instance of a prompted category:

* **Misses** with probability ``miss_base + miss_per_metre * distance + miss_occlusion *
  occluded_fraction`` (clipped to [0, 1]); distance is the instance's mean valid depth and
  the occluded fraction compares its visible pixels with the pixels its box would cover if
  nothing were in front (the camera reports that count, from the box geometry). Objects are
  seen in many frames of a pass, so independent per-frame misses are compensated.
* **Scores** drawn from N(``score_mean`` - ``score_drop`` * miss probability, ``score_std``):
  hard views get lower confidence; detections below ``score_threshold`` are dropped, as the
  paper's confidence threshold does.
* **Confusions**: with ``confusion_rate`` the label is swapped for another prompt category.
* **False positives**: with ``false_positive_rate`` per frame, a box on a random wall or floor
  region labelled with a random prompt; its segment is a blob on that background.
* **Box jitter** (``box_jitter`` of the box size per side) and **mask bleed**: each mask
  grows by ``mask_bleed`` of its area onto the pixels around it (usually background at a
  different depth), which is what the robust centroid has to survive.
* **Dropouts**: no detections at all during the given sim-time intervals (fault injection).

Preset ``hard`` adds failures tied to places and views rather than frames (look-alikes
seen again and again from the same side, doors missed edge-on in narrow corridors, dark
zones): see :mod:`bomc_bt.sim.detector_hard`.

Not modelled: appearance (the RGB image is not looked at), lighting, motion blur,
duplicate boxes for one object, and masks that miss parts of an object.

Only prompted categories are reported: the world may hold objects nobody asked for.
Everything random is drawn from ``default_rng([seed, stamp in ms])``, so a frame's result
depends on the seed and its stamp only, not on how many frames came before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from bomc_bt.errors import BomcError
from bomc_bt.perception.frames import Detection
from bomc_bt.robot import RGBDFrame
from bomc_bt.sim import detector_hard
from bomc_bt.sim.frame import SimFrame
from bomc_bt.sim.params import SimDetectorParams

_REFERENCE_AREA = 640 * 480  # min_pixels is given at this resolution


@dataclass
class _Candidate:
    """A visible instance of a prompted category, with what its miss model needs."""

    instance: int
    category: str
    pixels: int
    distance: float
    occluded: float
    box: tuple[int, int, int, int]  # x0, y0, x1, y1 (exclusive)


class SimDetector:
    """Detector and Segmenter over the simulated camera's instance image."""

    def __init__(self, params: SimDetectorParams | None = None, seed: int = 0):
        self.params = params or SimDetectorParams()
        self.seed = int(seed)
        # Which instance each reported box came from (per stamp), so segment() can return
        # the right object's mask even when boxes overlap; cleared on every detect().
        self._sources: dict[tuple[float, tuple[float, float, float, float], str], int] = {}

    # -- Detector ------------------------------------------------------------------------
    def detect(self, frame: RGBDFrame, categories: list[str]) -> list[Detection]:
        """Boxes (no masks yet) for the prompted categories visible in ``frame``."""
        instances = _instances(frame)
        self._sources = {}
        p = self.params
        prompts = list(dict.fromkeys(str(c) for c in categories))
        if not prompts or any(a <= frame.stamp < b for a, b in p.dropouts):
            return []
        rng = np.random.default_rng([self.seed, _stamp_key(frame.stamp), 0])
        candidates = _candidates(frame, instances, set(prompts), self._min_pixels(instances))
        if p.preset == "perfect":
            return [self._emit(frame, c.instance, c.category, c.box, 1.0) for c in candidates]
        out = []
        hard = p.preset == "hard"
        extra = detector_hard.penalties(frame, candidates, p.hard) if hard else {}
        draws = rng.random((len(candidates), 3))
        scores = rng.standard_normal(len(candidates))
        jitter = rng.standard_normal((len(candidates), 4))
        for c, (u_miss, u_conf, u_pick), z, j in zip(candidates, draws, scores, jitter, strict=True):
            added_miss, score_loss = extra.get(c.instance, (0.0, 0.0))
            miss = min(1.0, p.miss_base + p.miss_per_metre * c.distance + p.miss_occlusion * c.occluded
                       + added_miss)
            score = p.score_mean - p.score_drop * miss - score_loss + p.score_std * z
            if u_miss < miss or score < p.score_threshold:
                continue
            category = c.category
            others = [q for q in prompts if q != category]
            if others and u_conf < p.confusion_rate:
                category = others[int(u_pick * len(others)) % len(others)]
            box = _jitter_box(c.box, j, p.box_jitter, instances.shape)
            out.append(self._emit(frame, c.instance, category, box, min(score, 1.0)))
        fp = self._false_positive(frame, instances, prompts, rng)
        if fp is not None:
            out.append(fp)
        if hard:
            out += self._lookalikes(frame, instances, prompts)
        return out

    def _lookalikes(self, frame: SimFrame, instances: np.ndarray, prompts: list[str]) -> list[Detection]:
        """The ``hard`` preset's look-alikes in view (their own random stream: ``realistic``'s is untouched)."""
        p = self.params
        rng = np.random.default_rng([self.seed, _stamp_key(frame.stamp), 1])
        camera_xy = detector_hard.camera_pose(frame)[:2, 3]
        out = []
        for site, category in detector_hard.lookalike_sites(frame.world_key, camera_xy, p.hard, prompts):
            u_fire, z = rng.random(), rng.standard_normal()
            score = p.score_mean + p.score_std * z
            if u_fire >= p.hard.lookalike_rate or score < p.score_threshold:
                continue
            box = detector_hard.lookalike_box(frame, site, p.hard, self._min_pixels(instances))
            if box is not None:
                out.append(self._emit(frame, 0, category, box, min(score, 1.0)))
        return out

    # -- Segmenter -----------------------------------------------------------------------
    def segment(self, frame: RGBDFrame, detections: list[Detection]) -> list[Detection]:
        """One mask per box: the object the box came from, with bleed in ``realistic``.

        Boxes this detector did not produce (another detector's) get the instance that
        dominates the box, or a background blob when no instance does.
        """
        instances = _instances(frame)
        h, w = instances.shape
        out = []
        for det in detections:
            x0, y0, x1, y1 = _clip_box(det.box, (h, w))
            instance = self._sources.get((frame.stamp, tuple(det.box), det.category))
            if instance is None:
                instance = _dominant(instances[y0:y1, x0:x1])
            mask = np.zeros((h, w), dtype=bool)
            if instance > 0:
                mask[y0:y1, x0:x1] = instances[y0:y1, x0:x1] == instance
            elif x1 > x0 and y1 > y0:
                _blob(mask, (x0, y0, x1, y1))
            if self.params.preset != "perfect" and self.params.mask_bleed > 0.0:
                mask = _bleed(mask, self.params.mask_bleed)
            out.append(det.with_mask(mask))
        return out

    def source(self, frame: RGBDFrame, det: Detection) -> int | None:
        """The instance id a detection this detector made of ``frame`` came from (0: a false
        positive; None: not its own); benchmarks score single views with it."""
        return self._sources.get((frame.stamp, tuple(det.box), det.category))

    # -- helpers -------------------------------------------------------------------------
    def _min_pixels(self, instances: np.ndarray) -> int:
        return max(1, round(self.params.min_pixels * instances.size / _REFERENCE_AREA))

    def _emit(self, frame: RGBDFrame, instance: int, category: str, box, score: float) -> Detection:
        box_f = tuple(float(v) for v in box)
        self._sources[(frame.stamp, box_f, category)] = instance
        return Detection(category, box_f, float(score))

    def _false_positive(self, frame: RGBDFrame, instances: np.ndarray, prompts: list[str],
                        rng: np.random.Generator) -> Detection | None:
        """Maybe one spurious box on a random wall or floor region."""
        p = self.params
        u_fp, u_cat, u_px, u_w, u_h = rng.random(5)
        score = p.score_mean + p.score_std * rng.standard_normal()
        if u_fp >= p.false_positive_rate or score < p.score_threshold:
            return None
        background = np.flatnonzero((instances == 0) & np.isfinite(frame.depth))
        if background.size == 0:
            return None
        h, w = instances.shape
        row, col = divmod(int(background[int(u_px * background.size) % background.size]), w)
        half_w, half_h = (0.03 + 0.07 * u_w) * w, (0.03 + 0.07 * u_h) * h
        box = _clip_box((col - half_w, row - half_h, col + half_w, row + half_h), (h, w))
        category = prompts[int(u_cat * len(prompts)) % len(prompts)]
        return self._emit(frame, 0, category, box, min(score, 1.0))


def _instances(frame: RGBDFrame) -> np.ndarray:
    if not isinstance(frame, SimFrame):
        raise BomcError("the simulated detector needs frames from the simulated camera (no instance "
                        "image); use a real detector backend for real cameras", field="perception.backend")
    return frame.instances


def _stamp_key(stamp: float) -> int:
    return int(round(float(stamp) * 1000.0)) % (2**63)


def _candidates(frame: SimFrame, instances: np.ndarray, prompts: set[str],
                min_pixels: int) -> list[_Candidate]:
    """Visible, large-enough instances of prompted categories, in id order."""
    wanted = sorted(i for i, c in frame.instance_categories.items() if c in prompts)
    if not wanted:
        return []
    flat = instances.ravel()
    size = max(int(flat.max(initial=0)), max(wanted)) + 1
    counts = np.bincount(flat, minlength=size)
    depth = frame.depth.ravel()
    valid = np.isfinite(depth) & (flat > 0)  # walls and floor (id 0 and below) are never candidates
    n_depth = np.bincount(flat[valid], minlength=size)
    sum_depth = np.bincount(flat[valid], weights=depth[valid], minlength=size)
    far = float(frame.depth_range[1])
    out = []
    for i in wanted:
        if counts[i] < min_pixels:
            continue
        rows, cols = np.nonzero(instances == i)
        full = frame.instance_unoccluded.get(i, int(counts[i]))
        out.append(_Candidate(
            instance=i, category=frame.instance_categories[i], pixels=int(counts[i]),
            distance=float(sum_depth[i] / n_depth[i]) if n_depth[i] else far,
            occluded=float(np.clip(1.0 - counts[i] / max(full, 1), 0.0, 1.0)),
            box=(int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1),
        ))
    return out


def _jitter_box(box, noise: np.ndarray, sigma: float, shape: tuple[int, int]) -> tuple[float, ...]:
    x0, y0, x1, y1 = (float(v) for v in box)
    bw, bh = x1 - x0, y1 - y0
    jittered = (x0 + noise[0] * sigma * bw, y0 + noise[1] * sigma * bh,
                x1 + noise[2] * sigma * bw, y1 + noise[3] * sigma * bh)
    h, w = shape
    x0, y0 = min(max(jittered[0], 0.0), w - 1.0), min(max(jittered[1], 0.0), h - 1.0)
    x1, y1 = min(max(jittered[2], x0 + 1.0), float(w)), min(max(jittered[3], y0 + 1.0), float(h))
    return x0, y0, x1, y1


def _clip_box(box, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """Integer pixel bounds (x0, y0, x1 exclusive, y1 exclusive) inside the image."""
    h, w = shape
    x0, y0 = max(int(math.floor(box[0])), 0), max(int(math.floor(box[1])), 0)
    x1, y1 = min(int(math.ceil(box[2])), w), min(int(math.ceil(box[3])), h)
    return x0, y0, max(x1, x0), max(y1, y0)


def _dominant(crop: np.ndarray) -> int:
    """The instance covering most of a box (at least a fifth of it), else 0."""
    if crop.size == 0:
        return 0
    counts = np.bincount(crop.ravel())
    counts[0] = 0
    best = int(counts.argmax())
    return best if counts[best] * 5 >= crop.size else 0


def _blob(mask: np.ndarray, box: tuple[int, int, int, int]) -> None:
    """An elliptical segment filling a box: what a segmenter returns for a spurious box."""
    x0, y0, x1, y1 = box
    crop = np.zeros((y1 - y0, x1 - x0), dtype=np.uint8)
    centre = ((x1 - x0 - 1) // 2, (y1 - y0 - 1) // 2)
    axes = (max((x1 - x0) // 2, 1), max((y1 - y0) // 2, 1))
    cv2.ellipse(crop, centre, axes, 0.0, 0.0, 360.0, 1, -1)
    mask[y0:y1, x0:x1] |= crop.astype(bool)


def _bleed(mask: np.ndarray, fraction: float) -> np.ndarray:
    """Grow ``mask`` by ``fraction`` of its area onto the nearest pixels around it."""
    area = int(np.count_nonzero(mask))
    k = int(round(fraction * area))
    if area == 0 or k == 0:
        return mask
    rows, cols = np.nonzero(mask)
    h, w = mask.shape
    reach = int(math.ceil(math.sqrt(area) * fraction)) + 3
    r0, r1 = max(int(rows.min()) - reach, 0), min(int(rows.max()) + reach + 1, h)
    c0, c1 = max(int(cols.min()) - reach, 0), min(int(cols.max()) + reach + 1, w)
    crop = mask[r0:r1, c0:c1]
    dist = cv2.distanceTransform((~crop).astype(np.uint8), cv2.DIST_L2, 3)
    outside = np.flatnonzero(~crop)
    if outside.size == 0:
        return mask
    k = min(k, outside.size)
    nearest = outside[np.argpartition(dist.ravel()[outside], k - 1)[:k]]
    grown_crop = crop.copy().ravel()  # a contiguous copy: the crop itself is a strided view
    grown_crop[nearest] = True
    grown = mask.copy()
    grown[r0:r1, c0:c1] = grown_crop.reshape(crop.shape)
    return grown
