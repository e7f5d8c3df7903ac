"""RGB-D frames from a recorded ROS 1 bag, with camera_info and tf at the image stamps.

``bomc replay`` (:mod:`bomc_bt.replay`) reads a bag with Debian's ``python3-rosbag``; no
roscore is needed. The bag is read twice. :func:`index_bag` reads everything small (tf
into a tf2 buffer, camera_info, ``/amcl_pose``, the images' headers only) and decides
which RGB-D pairs can become frames and why the others cannot (no tf at the stamp, no
camera_info, not localized yet, no ground truth for the simulated detector).
:class:`FrameReader` then streams the images again and decodes only the frames the
replay asks for, in order: a dropped frame costs no decoding. A message that does not
decode is a skipped frame with its reason, never a traceback.

Topic and frame names are the ``ros:`` section's (:class:`~bomc_bt.ros.params.RosParams`),
the ones a live ``bomc monitor --ros`` subscribes to; :func:`recorded_topics` lists what
``rosbag record`` must record for a replay.
"""

from __future__ import annotations

import bisect
import json
import struct
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError, MissionFailed
from bomc_bt.robot import RGBDFrame
from bomc_bt.ros import import_ros
from bomc_bt.ros.convert import decode_depth, decode_rgb, intrinsics, planar_std, transform_matrix
from bomc_bt.ros.ground_truth import info_topic, with_ground_truth
from bomc_bt.ros.params import RosParams

TF_TOPICS = ("/tf", "/tf_static")
_HEADER_STAMP = struct.Struct("<II")  # a serialized Header starts with seq (uint32), then secs, nsecs


def recorded_topics(params: RosParams) -> list[str]:
    """The topics a replay reads: images, camera_info, tf, AMCL's pose, the sim's ground truth."""
    topics = [params.rgb_topic, params.depth_topic, params.camera_info_topic, *TF_TOPICS, params.amcl_pose_topic]
    if params.instances_topic:
        topics += [params.instances_topic, info_topic(params.instances_topic)]
    return topics


@dataclass
class FrameRef:
    """One usable RGB-D pair: its stamp, its parts' keys (topic, stamp in ns), its pose and K."""

    stamp: float
    parts: list[tuple[str, int]]
    T_map_base: Any
    T_base_camera: Any
    K: Any


@dataclass
class BagIndex:
    """What :func:`index_bag` found: the usable frames in stamp order and the skipped ones by reason."""

    path: Path
    frames: list[FrameRef] = field(default_factory=list)
    skipped: Counter = field(default_factory=Counter)  # reason -> frames
    corrupt: Counter = field(default_factory=Counter)  # topic -> messages that do not deserialize
    pairs: int = 0  # RGB-D pairs in the bag

    def problems(self) -> list[str]:
        """One line per reason a frame was skipped, with the count, and per corrupt topic."""
        lines = [f"{self.path}: {n} message(s) on {topic} do not decode (corrupt), left out"
                 for topic, n in sorted(self.corrupt.items())]
        return lines + [f"{self.path}: {n} of {self.pairs} frames skipped: {reason}"
                        for reason, n in sorted(self.skipped.items(), key=lambda kv: (-kv[1], kv[0]))]


def open_bag(path: Path) -> Any:
    """The bag for reading, or a one-line error naming the file."""
    import_ros()
    import rosbag

    if not path.is_file():
        raise BomcError("no such bag file", path)
    try:
        return rosbag.Bag(str(path), "r")
    except (rosbag.ROSBagException, OSError, ValueError, struct.error) as exc:
        raise BomcError(f"not a readable ROS 1 bag ({' '.join(str(exc).split()) or type(exc).__name__})",
                        path) from None


def _header_ns(data: bytes) -> int:
    secs, nsecs = _HEADER_STAMP.unpack_from(data, 4)
    return secs * 1_000_000_000 + nsecs


def _decode(raw: tuple) -> Any:
    """A message from rosbag's raw tuple (datatype, data, md5, position, class)."""
    msg = raw[4]()
    msg.deserialize(raw[1])
    return msg


@dataclass
class _Scan:
    """What the first pass collects before pairing."""

    tf: Any
    infos: list[tuple[int, Any]] = field(default_factory=list)
    amcl: list[tuple[int, bool]] = field(default_factory=list)
    images: dict[str, dict[int, str]] = field(default_factory=lambda: {"rgb": {}, "depth": {}})  # ns -> frame_id
    truth: dict[str, set[int]] = field(default_factory=lambda: {"image": set(), "info": set()})
    corrupt: Counter = field(default_factory=Counter)  # topic -> messages that did not decode


def index_bag(bag: Any, path: Path, params: RosParams) -> BagIndex:
    """First pass: which RGB-D pairs become frames (see the module doc)."""
    import genpy
    import tf2_py

    info = bag.get_type_and_topic_info().topics
    for name, topic in (("ros.rgb_topic", params.rgb_topic), ("ros.depth_topic", params.depth_topic)):
        if topic not in info:
            raise BomcError(f"has no messages on {topic} ({name}); topics: {', '.join(sorted(info)) or 'none'}",
                            path)
    span = max(bag.get_end_time() - bag.get_start_time(), 0.0) + 60.0
    scan = _Scan(tf=tf2_py.BufferCore(genpy.Duration.from_sec(span)))
    for topic, raw, _t in bag.read_messages(topics=recorded_topics(params), raw=True):
        try:
            _collect(scan, params, topic, raw)
        except Exception:  # a message that does not deserialize: counted, never a traceback
            scan.corrupt[topic] += 1
    return _pair(scan, path, params, amcl_recorded=params.amcl_pose_topic in info)


def _collect(scan: _Scan, p: RosParams, topic: str, raw: tuple) -> None:
    if topic in TF_TOPICS:
        from tf2_msgs.msg import TFMessage  # tf2 type-checks its input: the installed class, not the bag's

        tf = TFMessage()
        tf.deserialize(raw[1])
        for t in tf.transforms:
            if topic == "/tf_static":
                scan.tf.set_transform_static(t, "bag")
            else:
                scan.tf.set_transform(t, "bag")
    elif topic == p.camera_info_topic:
        msg = _decode(raw)
        scan.infos.append((msg.header.stamp.to_nsec(), msg))
    elif topic == p.amcl_pose_topic:
        msg = _decode(raw)
        sx, sy, syaw = planar_std(msg.pose.covariance)
        confident = sx <= p.max_xy_std and sy <= p.max_xy_std and syaw <= p.max_yaw_std
        scan.amcl.append((msg.header.stamp.to_nsec(), confident))
    elif topic in (p.rgb_topic, p.depth_topic):
        frame_id = _header_frame_id(raw[1])
        scan.images["rgb" if topic == p.rgb_topic else "depth"][_header_ns(raw[1])] = frame_id
    elif topic == p.instances_topic:
        scan.truth["image"].add(_ns(_header_ns(raw[1]) / 1e9))
    elif topic == info_topic(p.instances_topic):
        stamp = float(json.loads(_decode(raw).data)["stamp"])
        scan.truth["info"].add(_ns(stamp))


def _header_frame_id(data: bytes) -> str:
    (length,) = struct.unpack_from("<I", data, 12)
    return data[16:16 + length].decode("utf-8", "replace")


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e6)) * 1000  # stamps are keyed to the microsecond, as the live channel does


def _newest_at_or_before(items: list[tuple[int, Any]], ns: int) -> Any | None:
    keys = [k for k, _ in items]
    i = bisect.bisect_right(keys, ns) - 1
    return items[i][1] if i >= 0 else None


def _pair(scan: _Scan, path: Path, p: RosParams, amcl_recorded: bool) -> BagIndex:
    """RGB and depth within ``ros.sync_slop``, then tf, camera_info, localization and truth per pair."""
    out = BagIndex(path, corrupt=scan.corrupt)
    scan.infos.sort(key=lambda kv: kv[0])
    scan.amcl.sort(key=lambda kv: kv[0])
    rgb_stamps = sorted(scan.images["rgb"])
    slop = int(p.sync_slop * 1e9)
    for depth_ns, frame_id in sorted(scan.images["depth"].items()):
        out.pairs += 1
        i = bisect.bisect_left(rgb_stamps, depth_ns)
        near = [s for s in rgb_stamps[max(i - 1, 0):i + 1] if abs(s - depth_ns) <= slop]
        if not near:
            out.skipped[f"no colour image on {p.rgb_topic} within {p.sync_slop} s (ros.sync_slop)"] += 1
            continue
        rgb_ns = min(near, key=lambda s: abs(s - depth_ns))
        reason, ref = _frame(scan, p, depth_ns, rgb_ns, frame_id, amcl_recorded)
        if ref is None:
            out.skipped[reason] += 1
        else:
            out.frames.append(ref)
    return out


def _frame(scan: _Scan, p: RosParams, depth_ns: int, rgb_ns: int, frame_id: str,
           amcl_recorded: bool) -> tuple[str, FrameRef | None]:
    """The pair at ``depth_ns`` as a frame, or why it cannot be one."""
    import genpy

    info = _newest_at_or_before(scan.infos, depth_ns + int(p.sync_slop * 1e9))
    if info is None:
        return f"no camera_info on {p.camera_info_topic} at or before the image (ros.camera_info_topic)", None
    try:
        K = intrinsics(info)
    except MissionFailed as exc:
        return str(exc), None
    if amcl_recorded and not _newest_at_or_before(scan.amcl, depth_ns):
        return f"not localized: no confident {p.amcl_pose_topic} at or before the image (ros.max_xy_std)", None
    camera = p.camera_frame or frame_id or info.header.frame_id
    when = genpy.Time(depth_ns // 1_000_000_000, depth_ns % 1_000_000_000)
    T_map_base = _lookup(scan.tf, p.map_frame, p.base_frame, when)
    if T_map_base is None:
        return f"no tf {p.map_frame} <- {p.base_frame} at the image stamp (ros.map_frame / ros.base_frame)", None
    T_base_camera = _lookup(scan.tf, p.base_frame, camera, when)
    if T_base_camera is None:
        return f"no tf {p.base_frame} <- {camera} at the image stamp (ros.camera_frame)", None
    parts = [(p.depth_topic, depth_ns), (p.rgb_topic, rgb_ns)]
    if p.instances_topic:
        key = _ns(depth_ns / 1e9)
        if key not in scan.truth["image"] or key not in scan.truth["info"]:
            return (f"no instance image on {p.instances_topic} (the simulated detector's ground truth; "
                    "a real recording needs perception.backend: onnx)"), None
        parts += [(p.instances_topic, key), (info_topic(p.instances_topic), key)]
    return "", FrameRef(depth_ns / 1e9, parts, T_map_base, T_base_camera, K)


def _lookup(buffer: Any, target: str, source: str, when: Any) -> Any | None:
    try:
        return transform_matrix(buffer.lookup_transform_core(target, source, when).transform)
    except Exception:  # tf2's LookupException, ConnectivityException, ExtrapolationException
        return None


class FrameReader:
    """Second pass: decodes the frames the replay asks for, in increasing index order."""

    def __init__(self, bag: Any, index: BagIndex, params: RosParams):
        self.index = index
        self.params = params
        self.owner = {key: i for i, ref in enumerate(index.frames) for key in ref.parts}
        topics = sorted({topic for topic, _ in self.owner})
        self._messages = bag.read_messages(topics=topics, raw=True)
        self._parts: dict[tuple[str, int], tuple] = {}
        self.corrupt: Counter = Counter()  # reason -> frames asked for that did not decode

    def frame(self, i: int) -> RGBDFrame | None:
        """Frame ``i`` (asked for in increasing order), or None if one of its messages is corrupt."""
        ref = self.index.frames[i]
        for key in list(self._parts):
            if self.owner[key] < i:
                del self._parts[key]
        while not all(key in self._parts for key in ref.parts):
            try:
                topic, raw, _t = next(self._messages)
            except StopIteration:
                self.corrupt["a message vanished between the two reads of the bag"] += 1
                return None
            key = self._key(topic, raw)
            if key is not None and self.owner.get(key, -1) >= i:
                self._parts[key] = raw
        try:
            return self._build(ref)
        except Exception as exc:  # deserialisation or a truncated image: counted, never a traceback
            reason = str(exc) if isinstance(exc, MissionFailed) else f"{type(exc).__name__} while decoding"
            self.corrupt[f"corrupt message: {' '.join(reason.split())}"] += 1
            return None

    def _key(self, topic: str, raw: tuple) -> tuple[str, int] | None:
        try:
            truth = self.params.instances_topic
            if truth and topic == info_topic(truth):
                return topic, _ns(float(json.loads(_decode(raw).data)["stamp"]))
            if truth and topic == truth:
                return topic, _ns(_header_ns(raw[1]) / 1e9)
            return topic, _header_ns(raw[1])
        except Exception:
            return None

    def _build(self, ref: FrameRef) -> RGBDFrame:
        p = self.params
        depth = _decode(self._parts[(p.depth_topic, ref.parts[0][1])])
        rgb = _decode(self._parts[(p.rgb_topic, ref.parts[1][1])])
        frame = RGBDFrame(stamp=round(ref.stamp, 6), rgb=decode_rgb(rgb), depth=decode_depth(depth), K=ref.K,
                          T_map_base=ref.T_map_base, T_base_camera=ref.T_base_camera,
                          depth_range=(p.depth_min, p.depth_max))
        if not p.instances_topic:
            return frame
        image = _decode(self._parts[ref.parts[2]])
        info = json.loads(_decode(self._parts[ref.parts[3]]).data)
        return with_ground_truth(frame, image, info)
