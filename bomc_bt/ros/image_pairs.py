"""RGB and depth images paired by stamp, and an account of the camera images that never became frames.

The robot's camera publishes an RGB and a depth image per frame on two topics; a frame is
the newest pair whose stamps are within ``sync_slop``. A pair newer than the one being taken
passes the older ones over (a camera faster than the tree's ticks), and a frame whose
simulator ground truth was lost is dropped: both are counted by why in
:attr:`ImagePairs.passed_over`, the latest with their stamps in :attr:`ImagePairs.last_passed_over`,
so a pass that saw fewer frames than the camera published can say which and why (in lockstep
with the sim bridge no image should ever be passed over; the ROS tests read the counts).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

from bomc_bt.errors import MissionFailed

KEEP = 30  # images kept per topic while waiting for their partner (a frame rate's worth of seconds)
LAST = 20  # passed-over images kept with their stamps (the counts cover all of them)


@dataclass
class PassedOver:
    """A camera image that never became a frame: its stamp (s) and why."""

    stamp: float
    why: str  # "newer pair" (an older image skipped for a newer pair) or "ground truth lost"


@dataclass
class ImagePairs:
    """The newest RGB/depth pair not yet returned as a frame (callers hold the robot's lock)."""

    sync_slop: float  # [s] an RGB and a depth image this close in stamp are a pair
    rgb: deque = field(default_factory=lambda: deque(maxlen=KEEP))
    depth: deque = field(default_factory=lambda: deque(maxlen=KEEP))
    last_stamp: float = -math.inf  # the stamp of the last pair taken
    seen_at: dict[str, float] = field(default_factory=dict)  # "rgb" / "depth" -> when the first came
    passed_over: Counter = field(default_factory=Counter)  # why -> how many images
    last_passed_over: deque = field(default_factory=lambda: deque(maxlen=LAST))  # the latest, as PassedOver

    def add(self, kind: str, msg: Any, now: float) -> None:
        """An image of ``kind`` ("rgb" or "depth") received at ROS time ``now``."""
        (self.rgb if kind == "rgb" else self.depth).append(msg)
        self.seen_at.setdefault(kind, now)

    def newest(self, now: float) -> dict[str, Any] | None:
        """The newest pair newer than the last one taken, or None; it is taken (not returned again)."""
        for depth in reversed(self.depth):
            ds = image_stamp(depth)
            if ds <= self.last_stamp:
                break
            best = min(self.rgb, key=lambda m: abs(image_stamp(m) - ds), default=None)
            if best is not None and abs(image_stamp(best) - ds) <= self.sync_slop:
                skipped = sorted({image_stamp(m) for m in self.depth if self.last_stamp < image_stamp(m) < ds})
                for stamp in skipped:
                    self.drop(stamp, "newer pair")
                self.last_stamp = ds
                return {"stamp": ds, "rgb": best, "depth": depth, "received": now}
        return None

    def drop(self, stamp: float, why: str) -> None:
        """An image that will not become a frame (a pair taken by :meth:`newest`, or one it passed over)."""
        self.passed_over[why] += 1
        self.last_passed_over.append(PassedOver(stamp, why))

    def check_unpaired(self, now: float, timeout: float, rgb_topic: str, depth_topic: str) -> None:
        """Images on one topic but never a partner on the other within ``timeout`` s: a misnamed topic."""
        seen = self.seen_at
        for kind, other, topic in (("rgb", "depth", depth_topic), ("depth", "rgb", rgb_topic)):
            if kind in seen and other not in seen and now - seen[kind] > timeout:
                raise MissionFailed(
                    f"{kind} images arrive but none on {topic} within {timeout:.0f} s (ros.{other}_topic)"
                )


def image_stamp(msg: Any) -> float:
    """An image's header stamp (s), rounded like the ground truth's keys."""
    return round(msg.header.stamp.to_sec(), 6)
