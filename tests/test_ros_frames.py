"""``RosRobot.frame`` pairs a camera image with the sim bridge's ground truth, message by message.

The whole path runs through a real roscore in ``test_ros.py``; these tests pin what a
loaded machine does to it now and then, which a real roscore shows only by chance: the
instance image of one camera frame is dropped by a queue that overran, or comes late.
Messages are delivered here by hand, so "lost" and "late" are exact.
"""

from __future__ import annotations

import json
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from bomc_bt.errors import BomcError, MissionFailed
from bomc_bt.ros.image_pairs import ImagePairs, PassedOver
from bomc_bt.ros.params import RosParams

try:
    from bomc_bt.ros import import_ros

    rospy = import_ros()
    from sensor_msgs.msg import CameraInfo, Image
    from std_msgs.msg import String

    from bomc_bt.ros.convert import encode_depth
    from bomc_bt.ros.ground_truth import GroundTruthChannel, info_topic
    from bomc_bt.ros.robot import RosRobot
except (BomcError, ImportError) as exc:  # no ROS 1 Python packages on this machine
    pytest.skip(f"ROS 1 is not importable: {exc}", allow_module_level=True)

TOPIC = "/bomc_sim/instances"
H, W = 4, 6


class Camera:
    """A RosRobot without a node: its camera and ground-truth callbacks fed by the test."""

    def __init__(self) -> None:
        self.callbacks: dict[str, object] = {}
        self.warnings: list[str] = []
        self.clock = 0.0
        robot = RosRobot.__new__(RosRobot)
        robot.params = RosParams(instances_topic=TOPIC, frame_timeout=2.0)
        robot.rospy = SimpleNamespace(logwarn=self.warnings.append)
        robot._lock = threading.Lock()
        robot.images, robot._pending = ImagePairs(robot.params.sync_slop), None
        robot._info = CameraInfo(height=H, width=W, K=[5.0, 0, 3, 0, 5.0, 2, 0, 0, 1])
        robot._lookup = lambda *_args: np.eye(4)
        robot.now = lambda: self.clock
        robot.ground_truth = GroundTruthChannel(rospy, TOPIC, self._subscribe)
        self.robot = robot

    def _subscribe(self, topic, _type, callback, **_kwargs):
        self.callbacks[topic] = callback
        return SimpleNamespace(unregister=lambda: None)

    def image(self, t: float) -> None:
        """The bridge's RGB and depth images stamped ``t``."""
        depth, step = encode_depth(np.full((H, W), 2.0, np.float32), "32FC1")
        for kind, encoding, data, row in (("depth", "32FC1", depth, step), ("rgb", "rgb8", bytes(H * W * 3), W * 3)):
            self.robot.images.add(kind, self._msg(t, encoding, data, row), self.clock)

    def truth(self, t: float) -> None:
        """The instance image of ``t`` and its info record."""
        instances = np.full((H, W), 7, "<i4")
        self.callbacks[TOPIC](self._msg(t, "32SC1", instances.tobytes(), W * 4))
        info = {"stamp": t, "categories": {"7": "chair"}, "unoccluded": {"7": H * W}}
        self.callbacks[info_topic(TOPIC)](String(data=json.dumps(info)))

    @staticmethod
    def _msg(t: float, encoding: str, data: bytes, step: int) -> Image:
        msg = Image(height=H, width=W, encoding=encoding, is_bigendian=0, step=step, data=data)
        msg.header.stamp = rospy.Time.from_sec(t)
        return msg


def test_a_frame_whose_instance_image_was_lost_is_skipped_for_the_next_one():
    camera = Camera()
    camera.clock = 2.0
    camera.image(2.0)
    assert camera.robot.frame() is None  # waiting for the ground truth of 2.0 s
    camera.clock = 2.2
    camera.image(2.2)
    camera.truth(2.2)  # the instance image of 2.0 s never comes: a queue dropped it
    frames = [camera.robot.frame() for _ in range(3)]
    got = [f for f in frames if f is not None]
    assert len(got) == 1 and got[0].stamp == pytest.approx(2.2)
    assert got[0].instance_categories == {7: "chair"}
    assert any("2.00 s was lost" in w for w in camera.warnings)
    assert camera.robot.images.passed_over == {"ground truth lost": 1}  # what the ROS tests read
    assert list(camera.robot.images.last_passed_over) == [PassedOver(2.0, "ground truth lost")]


def test_a_newer_pair_passes_the_older_images_over_and_says_so():
    camera = Camera()
    for t in (1.0, 1.5, 2.0):  # three frames came before the leaf asked for one
        camera.clock = t
        camera.image(t)
        camera.truth(t)
    frame = camera.robot.frame()
    assert frame is not None and frame.stamp == pytest.approx(2.0)
    assert camera.robot.images.passed_over == {"newer pair": 2}
    assert list(camera.robot.images.last_passed_over) == [PassedOver(1.0, "newer pair"), PassedOver(1.5, "newer pair")]
    assert camera.robot.frame() is None  # nothing newer yet: no frame twice


def test_a_late_instance_image_is_waited_for_not_skipped():
    camera = Camera()
    camera.clock = 2.0
    camera.image(2.0)
    assert camera.robot.frame() is None  # its ground truth is not here yet
    camera.clock = 3.5
    camera.truth(2.0)
    frame = camera.robot.frame()
    assert frame is not None and frame.stamp == pytest.approx(2.0) and not camera.warnings


def test_no_instance_image_at_all_is_an_error_once_the_frame_timeout_passed():
    camera = Camera()
    camera.clock = 2.0
    camera.image(2.0)
    assert camera.robot.frame() is None
    camera.clock = 4.5
    with pytest.raises(MissionFailed, match=r"no instance image on /bomc_sim/instances for the image at 2\.00 s "
                                            r"\(none has come whole\)"):
        camera.robot.frame()


def test_the_error_says_what_did_come():
    """A topic far behind the camera's, or an image whose info alone came: the one who reads
    the error sees which."""
    camera = Camera()
    camera.truth(1.5)
    camera.clock = 2.0
    camera.image(2.0)
    camera.callbacks[info_topic(TOPIC)](String(data=json.dumps({"stamp": 2.0, "categories": {}, "unoccluded": {}})))
    assert camera.robot.frame() is None
    camera.clock = 4.5
    with pytest.raises(MissionFailed, match=r"at 2\.00 s \(the newest whole one is of 1\.50 s; its info came\)"):
        camera.robot.frame()
