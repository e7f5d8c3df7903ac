"""Conversions between ROS 1 messages and the project's records, with numpy only.

Kept apart from the node code so the two directions (the robot adapter reads, the bridge
writes) share one definition of each encoding. Message classes are passed in or imported
lazily, so importing this module does not need ROS.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bomc_bt.errors import MissionFailed
from bomc_bt.geometry import Pose2D, matrix_from_quaternion, quaternion_from_matrix, se3
from bomc_bt.grid import OccupancyGrid
from bomc_bt.robot import LaserScan

DEPTH_ENCODINGS = ("32FC1", "16UC1")
_COLOUR = {
    "rgb8": (3, False),
    "bgr8": (3, True),
    "rgba8": (4, False),
    "bgra8": (4, True),
    "mono8": (1, False),
}


class SerializableArray(np.ndarray):
    """A numpy array that rospy's numpy serializer can write under numpy 2.

    ``rospy.numpy_msg`` calls ``ndarray.tostring()``, which numpy 2 removed; viewing the
    data as this subclass puts the old name back without copying.
    """

    def tostring(self) -> bytes:  # noqa: D401 - the name rospy calls
        return self.tobytes()


# -- images ------------------------------------------------------------------------------
def _rows(msg: Any, dtype: np.dtype, channels: int) -> np.ndarray:
    """The image's pixels as (H, W[, C]) honouring ``step`` padding and endianness."""
    itemsize = np.dtype(dtype).itemsize
    row_items = msg.step // itemsize
    raw = np.frombuffer(msg.data, dtype=np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<"))
    if raw.size < msg.height * row_items:
        raise MissionFailed(
            f"image on {msg.header.frame_id or '?'} is truncated "
            f"({raw.size} of {msg.height * row_items} values)"
        )
    img = raw[: msg.height * row_items].reshape(msg.height, row_items)[:, : msg.width * channels]
    img = img.astype(np.dtype(dtype).newbyteorder("="), copy=False)
    return img.reshape(msg.height, msg.width, channels) if channels > 1 else img


def decode_rgb(msg: Any) -> np.ndarray:
    """uint8 (H, W, 3) RGB from rgb8, bgr8, rgba8, bgra8 or mono8."""
    if msg.encoding not in _COLOUR:
        raise MissionFailed(
            f"colour image encoding {msg.encoding!r} is not supported (expected one of {', '.join(_COLOUR)})"
        )
    channels, bgr = _COLOUR[msg.encoding]
    img = _rows(msg, np.uint8, channels)
    if channels == 1:
        return np.repeat(img[:, :, None], 3, axis=2)
    img = img[:, :, :3]
    return np.ascontiguousarray(img[:, :, ::-1] if bgr else img)


def decode_depth(msg: Any) -> np.ndarray:
    """float32 metres, NaN where invalid, from 32FC1 (metres) or 16UC1 (millimetres)."""
    if msg.encoding == "32FC1":
        depth = _rows(msg, np.float32, 1).astype(np.float32, copy=True)
        depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
        return depth
    if msg.encoding == "16UC1":
        mm = _rows(msg, np.uint16, 1)
        depth = mm.astype(np.float32) * np.float32(0.001)
        depth[mm == 0] = np.nan
        return depth
    raise MissionFailed(f"depth image encoding {msg.encoding!r} is not supported (expected 32FC1 or 16UC1)")


def encode_depth(depth: np.ndarray, encoding: str) -> tuple[bytes, int]:
    """Bytes and row step of a float32-metres depth image in ``encoding``."""
    if encoding == "32FC1":
        data = np.nan_to_num(depth.astype("<f4"), nan=np.nan)
        return data.tobytes(), depth.shape[1] * 4
    if encoding == "16UC1":
        mm = np.where(np.isfinite(depth), np.rint(depth * 1000.0), 0.0)
        return np.clip(mm, 0, 65535).astype("<u2").tobytes(), depth.shape[1] * 2
    raise ValueError(f"depth encoding must be one of {DEPTH_ENCODINGS}")


def intrinsics(info: Any) -> np.ndarray:
    """K (3 x 3) from a CameraInfo; an all-zero K (an uncalibrated camera) is an error."""
    k = np.asarray(info.K, dtype=float).reshape(3, 3)
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise MissionFailed(f"camera_info for {info.header.frame_id or '?'} has no calibration (K = 0)")
    return k


# -- poses and transforms ------------------------------------------------------------------
def transform_matrix(t: Any) -> np.ndarray:
    """4 x 4 from a geometry_msgs/Transform."""
    q = t.rotation
    return se3(
        matrix_from_quaternion(q.x, q.y, q.z, q.w),
        np.array([t.translation.x, t.translation.y, t.translation.z]),
    )


def fill_transform(t: Any, matrix: np.ndarray) -> None:
    """Write a 4 x 4 into a geometry_msgs/Transform."""
    t.translation.x, t.translation.y, t.translation.z = (float(v) for v in matrix[:3, 3])
    qx, qy, qz, qw = quaternion_from_matrix(matrix[:3, :3])
    t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = float(qx), float(qy), float(qz), float(qw)


def pose2d_from_matrix(m: np.ndarray) -> Pose2D:
    return Pose2D(float(m[0, 3]), float(m[1, 3]), math.atan2(m[1, 0], m[0, 0]))


def fill_pose(p: Any, pose: Pose2D) -> None:
    """Write a planar pose into a geometry_msgs/Pose."""
    p.position.x, p.position.y, p.position.z = float(pose.x), float(pose.y), 0.0
    p.orientation.x, p.orientation.y = 0.0, 0.0
    p.orientation.z, p.orientation.w = math.sin(pose.yaw / 2.0), math.cos(pose.yaw / 2.0)


def pose2d_from_msg(p: Any) -> Pose2D:
    q = p.orientation
    yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    return Pose2D(float(p.position.x), float(p.position.y), yaw)


def planar_std(covariance: Any) -> tuple[float, float, float]:
    """x, y and yaw standard deviations from a 6 x 6 row-major pose covariance."""
    c = np.asarray(covariance, dtype=float).reshape(6, 6)
    return tuple(float(math.sqrt(max(v, 0.0))) for v in (c[0, 0], c[1, 1], c[5, 5]))  # type: ignore[return-value]


def covariance(xy_std: float, yaw_std: float) -> list[float]:
    c = np.zeros(36)
    c[0] = c[7] = xy_std**2
    c[35] = yaw_std**2
    return c.tolist()


# -- maps and scans ---------------------------------------------------------------------------
def grid_from_msg(msg: Any) -> OccupancyGrid:
    """nav_msgs/OccupancyGrid (numpy_msg or plain) to an OccupancyGrid.

    Both keep row 0 at the origin, so the data is a plain reshape. A rotated origin
    (rare; map_server never writes one) is not supported and is an error.
    """
    info = msg.info
    q = info.origin.orientation
    if abs(q.z) > 1e-6 or abs(q.x) > 1e-6 or abs(q.y) > 1e-6:
        raise MissionFailed("the /map origin is rotated; only axis-aligned maps are supported")
    data = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
    data = np.where((data < 0) | (data > 100), np.int8(-1), data).astype(np.int8)
    return OccupancyGrid(
        data=data,
        resolution=float(info.resolution),
        origin=(float(info.origin.position.x), float(info.origin.position.y)),
    )


def decimal_resolution(grid: OccupancyGrid) -> OccupancyGrid:
    """The grid with the decimal resolution its float32 message field stands for.

    nav_msgs/OccupancyGrid carries the resolution as float32: 0.05 arrives as
    0.0500000007, which moves cell boundaries (world_to_cell floors) off the saved map's
    and the simulator's. The shortest decimal that round-trips the float32 is what the
    sender (map_server reads a YAML decimal) meant.
    """
    resolution = float(str(np.float32(grid.resolution)))
    return OccupancyGrid(grid.data, resolution, tuple(grid.origin))


def lethal_cells(grid: OccupancyGrid) -> np.ndarray:
    """(N, 2) map-frame centres of a costmap's lethal cells (100: an obstacle, not inflation)."""
    return grid.cell_centres(grid.data >= 100)


def fill_grid(msg: Any, grid: OccupancyGrid) -> None:
    """Fill a numpy_msg(nav_msgs/OccupancyGrid) from a grid (row 0 = origin in both)."""
    msg.info.resolution = float(grid.resolution)
    msg.info.height, msg.info.width = int(grid.data.shape[0]), int(grid.data.shape[1])
    msg.info.origin.position.x, msg.info.origin.position.y = float(grid.origin[0]), float(grid.origin[1])
    msg.info.origin.orientation.w = 1.0
    msg.data = np.ascontiguousarray(grid.data, dtype=np.int8).reshape(-1).view(SerializableArray)


def scan_from_msg(msg: Any) -> LaserScan:
    """sensor_msgs/LaserScan to a LaserScan (angles relative to the laser's heading)."""
    ranges = np.asarray(msg.ranges, dtype=np.float32)
    ranges = np.where(
        np.isfinite(ranges) & (ranges >= msg.range_min) & (ranges <= msg.range_max),
        ranges,
        np.float32(np.inf),
    ).astype(np.float32)
    return LaserScan(
        stamp=msg.header.stamp.to_sec(),
        angle_min=float(msg.angle_min),
        angle_increment=float(msg.angle_increment),
        ranges=ranges,
        range_max=float(msg.range_max),
    )
