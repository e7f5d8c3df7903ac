"""``bomc replay``: anytime frame dropping, problem bags, and a real recording replayed (issue 21).

The drop rule is checked as the pure function it is; bags with missing tf, missing
camera_info and a corrupt image are written here with ``rosbag``'s Python API (no
roscore); the last test records a simulated pass on a real roscore (`bomc sim-ros` +
`rosbag record`) and replays it into the live pass's graph.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from ros_recording import record_pass, roscore

from bomc_bt.anytime import arrival_times, next_frame, schedule
from bomc_bt.cli import main as bomc
from bomc_bt.errors import BomcError
from bomc_bt.evaluate_site import evaluate_session
from bomc_bt.run import build_config, run_build
from bomc_bt.sim.factory import world_categories
from bomc_bt.world import load_world

try:
    from bomc_bt.ros import import_ros

    import_ros()
    import rosbag  # noqa: F401

    ROS_MISSING = "" if shutil.which("roscore") and shutil.which("rosbag") else "roscore / rosbag not on PATH"
except (BomcError, ImportError) as exc:
    ROS_MISSING = str(exc)
needs_ros = pytest.mark.skipif(bool(ROS_MISSING), reason=f"ROS 1 unavailable: {ROS_MISSING}")


# -- the drop rule -------------------------------------------------------------------------------
def test_a_pipeline_faster_than_the_camera_processes_every_frame_when_it_arrives():
    arrivals = arrival_times([10.0 + 0.5 * i for i in range(8)], None)
    assert arrivals == [0.5 * i for i in range(8)]
    s = schedule(arrivals, [0.1] * 8)
    assert s.processed == list(range(8)) and s.dropped == 0 and s.starts == arrivals  # waits for each


def test_a_slow_pipeline_takes_the_newest_frame_and_drops_the_ones_it_missed():
    arrivals = arrival_times(list(range(11)), 10.0)  # 10 fps: 0.0, 0.1, ... 1.0 s
    s = schedule(arrivals, [0.25] * 11)
    # free at 0.25 -> frames 1, 2 arrived: 2 wins; at 0.5 -> 5; at 0.75 -> 7; at 1.0 -> 10
    assert s.processed == [0, 2, 5, 7, 10]
    assert s.dropped == 6 and len(s.processed) + s.dropped == 11
    assert s.starts == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])


def test_every_pick_is_the_newest_arrival_and_nothing_is_counted_twice():
    rng = np.random.default_rng(3)
    arrivals = np.cumsum(rng.exponential(0.05, 200)).tolist()
    costs = rng.uniform(0.01, 0.2, 200).tolist()
    s = schedule(arrivals, costs)
    assert len(s.processed) + s.dropped == 200 and s.processed == sorted(set(s.processed))
    for k, (i, start) in enumerate(zip(s.processed, s.starts, strict=True)):
        assert arrivals[i] <= start + 1e-12
        later = i + 1 < 200 and arrivals[i + 1] <= start
        assert not later, f"pick {k} took frame {i} although frame {i + 1} had arrived"
    assert next_frame(arrivals, 199, 1e9) is None


# -- bags written here ------------------------------------------------------------------------------
H, W = 60, 80
RGB, DEPTH = "/head_camera/rgb/image_raw", "/head_camera/depth_registered/image_raw"
INFO = "/head_camera/rgb/camera_info"
TRUTH = "/bomc_sim/instances"


@pytest.fixture(scope="module")
def site_world(tmp_path_factory):
    """A small generated office, built once: the map the bags' frames are put in."""
    root = tmp_path_factory.mktemp("replay")
    world = root / "office.yaml"
    assert bomc(["world", "office", "--out", str(world), "--size", "14x12", "--seed", "1", "--static"]) == 0
    run_build(world, root / "built")
    config = root / "replay.yaml"
    config.write_text(json.dumps({"perception": {"categories": world_categories(load_world(world))},
                                  "ros": {"frame_timeout": 2.0, "clock_timeout": 5.0, "server_timeout": 10.0}}))
    return root, world, config


def _site(root: Path, name: str) -> Path:
    dst = root / name
    shutil.copytree(root / "built", dst)
    return dst


def _write_bag(path: Path, frames: int, *, no_tf: set[int] = frozenset(), info_from: int = 0,
               no_info: bool = False, truncated: set[int] = frozenset()) -> Path:
    """``frames`` RGB-D frames at 2 Hz of a chair-sized object 2 m in front of a still robot."""
    import rosbag
    import rospy
    from geometry_msgs.msg import TransformStamped
    from sensor_msgs.msg import CameraInfo, Image
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage

    depth = np.full((H, W), 5.0, "<f4")
    instances = np.zeros((H, W), "<i4")
    depth[20:45, 30:50], instances[20:45, 30:50] = 2.0, 7
    with rosbag.Bag(str(path), "w") as bag:
        for i in range(frames):
            t = rospy.Time.from_sec(1.0 + 0.5 * i)

            def tf(parent, child, xyz, quat, t=t):
                m = TransformStamped()
                m.header.stamp, m.header.frame_id, m.child_frame_id = t, parent, child
                m.transform.translation.x, m.transform.translation.y, m.transform.translation.z = xyz
                (m.transform.rotation.x, m.transform.rotation.y, m.transform.rotation.z,
                 m.transform.rotation.w) = quat
                return m

            if i not in no_tf:
                bag.write("/tf", TFMessage([tf("map", "odom", (0, 0, 0), (0, 0, 0, 1)),
                                            tf("odom", "base_link", (4.0, 6.0, 0), (0, 0, 0, 1)),
                                            tf("base_link", "cam", (0.1, 0, 1.1), (-0.5, 0.5, -0.5, 0.5))]), t)
            if not no_info and i >= info_from:
                info = CameraInfo(height=H, width=W, K=[70.0, 0, W / 2, 0, 70.0, H / 2, 0, 0, 1])
                info.header.stamp, info.header.frame_id = t, "cam"
                bag.write(INFO, info, t)

            def image(encoding, data, step, t=t):
                msg = Image(height=H, width=W, encoding=encoding, step=step, data=data)
                msg.header.stamp, msg.header.frame_id = t, "cam"
                return msg

            rgb = np.zeros((H, W, 3), np.uint8).tobytes()
            bag.write(RGB, image("rgb8", rgb[: len(rgb) // 2] if i in truncated else rgb, W * 3), t)
            bag.write(DEPTH, image("32FC1", depth.tobytes(), W * 4), t)
            bag.write(TRUTH, image("32SC1", instances.tobytes(), W * 4), t)
            stamp = round(t.to_sec(), 6)
            bag.write(TRUTH + "/info", String(json.dumps({"stamp": stamp, "categories": {"7": "chair"},
                                                          "unoccluded": {"7": 500}})), t)
    return path


def _replay(bag: Path, site: Path, config: Path, *extra: str) -> int:
    return bomc(["replay", str(bag), "--site", str(site), "--session", "1", "--config", str(config), *extra])


@needs_ros
def test_missing_tf_and_camera_info_and_a_corrupt_image_are_one_line_each_and_counted(site_world, tmp_path,
                                                                                       capsys):
    root, _, config = site_world
    # frame 5's tf is interpolated between frames 4 and 6; frames 10 and 11 come after the last tf
    bag = _write_bag(tmp_path / "faulty.bag", 12, no_tf={5, 10, 11}, info_from=2, truncated={8})
    site = _site(root, "faulty")
    assert _replay(bag, site, config, "--as-fast-as-possible") == 0
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("bomc replay:")]
    assert len(lines) == 3 and len(err.strip().splitlines()) == 3, err
    assert any("2 of 12 frames skipped: no camera_info on /head_camera/rgb/camera_info" in x for x in lines)
    assert any("2 of 12 frames skipped: no tf map <- base_link at the image stamp" in x for x in lines)
    assert any("1 frame(s) skipped: corrupt message: image on cam is truncated" in x for x in lines)
    replay = json.loads((site / "sessions" / "1" / "report.json").read_text())["replay"]
    assert (replay["processed"], replay["skipped"], replay["dropped"], replay["frames_in_bag"]) == (7, 5, 0, 12)
    assert "frames processed 7, dropped 0, skipped 5 of 12" in out


@needs_ros
def test_a_bag_with_no_usable_frame_exits_2_and_leaves_the_site_untouched(site_world, tmp_path, capsys):
    root, _, config = site_world
    site = _site(root, "untouched")
    before = sorted(p.relative_to(site) for p in site.rglob("*"))
    assert _replay(_write_bag(tmp_path / "noinfo.bag", 4, no_info=True), site, config) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "4 of 4 frames skipped: no camera_info" in err[0]
    assert err[1].startswith("bomc: error: ") and "none of its 4 RGB-D frames can be mapped" in err[1]
    (tmp_path / "junk.bag").write_bytes(b"not a bag at all")
    assert _replay(tmp_path / "junk.bag", site, config) == 2
    assert "not a readable ROS 1 bag" in capsys.readouterr().err
    assert _replay(_write_bag(tmp_path / "ok.bag", 2), site, config, "--rate", "0") == 2
    assert "--rate" in capsys.readouterr().err
    assert sorted(p.relative_to(site) for p in site.rglob("*")) == before


@needs_ros
def test_frames_faster_than_the_pipeline_are_dropped_newest_first_on_the_wall_clock(site_world, tmp_path):
    from bomc_bt.replay import run_replay

    root, _, config_path = site_world
    bag = _write_bag(tmp_path / "fast.bag", 40)

    class Slow:  # 40 ms per frame: a model budget
        def __init__(self, detector, segmenter):
            self.detector, self.segmenter = detector, segmenter

        def detect(self, frame, categories):
            time.sleep(0.04)
            return self.detector.detect(frame, categories)

        def segment(self, frame, detections):
            return self.segmenter.segment(frame, detections)

    result = run_replay(bag, _site(root, "fast"), 1, build_config([str(config_path)]), rate=200.0,
                        detector_wrapper=lambda d, s: (Slow(d, s), Slow(d, s)))
    assert result.processed + result.dropped == 40 and result.skipped == 0
    # 40 frames arrive within 0.2 s and each takes >= 40 ms: at most 6 are processed, the
    # first and (newest wins) the last among them, however slow this machine is
    assert 2 <= result.processed <= 7 and result.dropped == 40 - result.processed
    assert result.summary["sim_time_s"] == 20.5  # the stamp of frame 39, the newest
    assert result.model_s >= 0.04 * result.processed
    assert math.isfinite(result.not_model_s) and result.not_model_s > 0


# -- a recording of a real pass ------------------------------------------------------------------------
@needs_ros
@pytest.mark.ros
def test_a_recorded_pass_replays_into_the_live_pass_graph(site_world, tmp_path):
    from bomc_bt.ros.bag import recorded_topics
    from bomc_bt.ros.missions import ros_params
    from bomc_bt.store import SiteStore

    root, world, config_path = site_world
    config = build_config([str(config_path)])
    live, replayed = _site(root, "live"), _site(root, "replayed")
    bag = tmp_path / "pass.bag"
    start = time.monotonic()
    with roscore(tmp_path) as env:
        proc = record_pass(env, world, live, 1, bag, config_path, recorded_topics(ros_params(config)))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert _replay(bag, replayed, config_path, "--as-fast-as-possible") == 0
    assert time.monotonic() - start < 90.0

    live_report = json.loads((live / "sessions" / "1" / "report.json").read_text())
    report = json.loads((replayed / "sessions" / "1" / "report.json").read_text())
    assert report["replay"]["processed"] == live_report["frames"] > 50  # every frame the live pass saw
    assert report["replay"]["dropped"] == report["replay"]["skipped"] == 0
    graphs = []
    for site in (live, replayed):
        with SiteStore(site / "site.db") as store:
            graphs.append(sorted(store.load_graph(config.association).nodes.values(),
                                 key=lambda n: (n.category, tuple(n.position))))
    assert len(graphs[0]) == len(graphs[1]) > 3
    for a, b in zip(*graphs, strict=True):
        assert a.category == b.category
        distance = config.association.per_category.get(a.category, config.association.default_distance)
        assert math.dist(a.position, b.position) <= distance
    f1 = [evaluate_session(world, site, 1, config).overall.f1 for site in (live, replayed)]
    assert f1[0] == f1[1] and f1[0] > 0.5
