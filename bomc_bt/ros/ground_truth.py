"""The simulator-only ground-truth channel of the sim-over-ROS bridge.

The simulated detector reads which object each pixel shows (a
:class:`~bomc_bt.sim.frame.SimFrame`). A real camera has no such thing, so the bridge
serves it on a topic of its own, beside the camera's: an int32 instance image and a JSON
record of the instances' categories and unoccluded pixel counts, both keyed by the
image's stamp. This module holds both ends: :func:`instance_messages` for the bridge and
:class:`GroundTruthChannel` for the executive, which turns a camera frame back into a
SimFrame. Nothing else in the ROS robot knows the channel exists.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from bomc_bt.robot import RGBDFrame
from bomc_bt.sim.frame import SimFrame

SIM_INSTANCES_TOPIC = "/bomc_sim/instances"  # the per-pixel instance image the sim detector reads
KEEP = 30  # stamps of ground truth kept while waiting for their camera frames


def info_topic(topic: str) -> str:
    return topic + "/info"


def instance_messages(frame: SimFrame, image: Callable[[str, bytes, int], Any]) -> tuple[Any, Any, float]:
    """The bridge's side: (instance image, info String, the info's stamp) for ``frame``.

    ``image(encoding, data, step)`` makes an Image message stamped like the camera's.
    """
    from std_msgs.msg import String

    h, w = frame.shape
    info_stamp = _key(frame.stamp)  # the executive keys instance data by this
    data = {
        "stamp": info_stamp,
        "categories": {str(k): v for k, v in frame.instance_categories.items()},
        "unoccluded": {str(k): int(v) for k, v in frame.instance_unoccluded.items()},
    }
    return image("32SC1", frame.instances.astype("<i4").tobytes(), w * 4), String(data=json.dumps(data)), info_stamp


class GroundTruthChannel:
    """The executive's side: keeps the newest instance images and infos by stamp."""

    def __init__(self, rospy: Any, topic: str, subscribe: Callable[..., Any]):
        """``subscribe(topic, type, callback, **kwargs)`` makes a subscriber (a tracked one in lockstep)."""
        from sensor_msgs.msg import Image
        from std_msgs.msg import String

        self.rospy = rospy
        self.topic = topic
        self._lock = threading.Lock()
        self._entries: dict[float, dict[str, Any]] = {}
        self.subs = [
            subscribe(topic, Image, self._on_image, queue_size=5, buff_size=2**24),
            subscribe(info_topic(topic), String, self._on_info, stamp_ns=self._info_stamp_ns, queue_size=5),
        ]

    def _on_image(self, msg: Any) -> None:
        with self._lock:
            self._entries.setdefault(_key(msg.header.stamp.to_sec()), {})["image"] = msg
            self._trim()

    def _on_info(self, msg: Any) -> None:
        data = json.loads(msg.data)
        with self._lock:
            self._entries.setdefault(_key(float(data["stamp"])), {})["info"] = data
            self._trim()

    def _info_stamp_ns(self, msg: Any) -> int:
        return self.rospy.Time.from_sec(float(json.loads(msg.data)["stamp"])).to_nsec()

    def _trim(self) -> None:
        while len(self._entries) > KEEP:
            del self._entries[min(self._entries)]

    def _entry(self, stamp: float) -> dict[str, Any] | None:
        with self._lock:
            entry = self._entries.get(_key(stamp))
        return entry if entry is not None and _whole(entry) else None

    def ready(self, stamp: float) -> bool:
        """Both the instance image and its info of the camera image at ``stamp`` are here."""
        return self._entry(stamp) is not None

    def lost(self, stamp: float) -> bool:
        """The ground truth of a newer image is whole but not that of ``stamp``.

        Each topic arrives in order, so the message of ``stamp`` will never come: a publisher
        or subscriber queue overran on a loaded machine. Its camera frame is skipped rather
        than waited for (``ros.frame_timeout``) and the mission failed for one lost message.
        """
        key = _key(stamp)
        with self._lock:
            newer = [entry for k, entry in self._entries.items() if k > key]
        return self._entry(stamp) is None and any(_whole(e) for e in newer)

    def missing(self, stamp: float) -> str:
        """Why the mission stops for the ground truth of ``stamp``: what did come, for the
        one who reads the error (a topic never connected, or one far behind the camera's)."""
        with self._lock:
            entry = self._entries.get(_key(stamp), {})
            whole = [k for k, e in self._entries.items() if _whole(e)]
        newest = f"the newest whole one is of {max(whole):.2f} s" if whole else "none has come whole"
        parts = "; its info came" if "info" in entry else ("; its image came" if "image" in entry else "")
        return f"no instance image on {self.topic} for the image at {stamp:.2f} s ({newest}{parts})"

    def attach(self, frame: RGBDFrame) -> SimFrame:
        """``frame`` with its ground truth (once :meth:`ready` says it is here)."""
        entry = self._entry(frame.stamp)
        if entry is None:
            raise KeyError(f"no ground truth for the frame at {frame.stamp:.2f} s")
        return with_ground_truth(frame, entry["image"], entry["info"])


def _key(stamp: float) -> float:
    """The entry key of a stamp (s): both topics' stamps, rounded alike."""
    return round(stamp, 6)


def _whole(entry: dict[str, Any]) -> bool:
    """Both the instance image and its info record have come."""
    return "image" in entry and "info" in entry


def with_ground_truth(frame: RGBDFrame, image: Any, info: dict[str, Any]) -> SimFrame:
    """``frame`` with the instance image message and the info record of its stamp
    (what the channel received, or what a recorded bag holds: :mod:`bomc_bt.ros.bag`)."""
    instances = np.frombuffer(image.data, dtype="<i4").reshape(image.height, image.width).astype(np.int32)
    return SimFrame.of(
        frame,
        instances,
        {int(k): str(v) for k, v in info["categories"].items()},
        {int(k): int(v) for k, v in info.get("unoccluded", {}).items()},
    )
