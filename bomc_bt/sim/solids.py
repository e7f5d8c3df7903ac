"""The scene's boxes as the camera draws them, built once per scene and culled per frame.

Why: a building-sized world has hundreds of objects and the camera renders at 2 Hz, but
a frame sees the few within ``depth_max`` in front of it. Building every box record and
its corners each frame, and asking each one whether it is on screen, cost more than
drawing the visible ones. :class:`SceneSolids` keeps the boxes and their corners while
the object and obstacle lists are the same (it compares them element by element, by
identity first), and :meth:`SceneSolids.candidates` drops with one numpy pass the boxes
that :func:`bomc_bt.sim.raycast.draw_box` would find entirely beyond ``depth_max`` or
behind the camera. The cull is conservative (a margin on both tests), so the boxes it
keeps are drawn exactly as before and the frames do not change.
"""

from __future__ import annotations

import numpy as np

from bomc_bt.sim.raycast import Box, scene_solids, solid_corners

_MARGIN = 1e-6  # m: slack of the cull, far above the rounding of the distances it compares


class SceneSolids:
    """Cached boxes and people cylinders of the scene a camera renders."""

    def __init__(self) -> None:
        self._key: tuple[tuple, tuple] | None = None
        self.boxes: list[Box] = []
        self.corners: list[np.ndarray] = []
        self._xy = np.zeros((0, 2))
        self._z = np.zeros(0)
        self._reach = np.zeros(0)

    def update(self, objects: list, obstacles: list, people: list) -> list[tuple[np.ndarray, int]]:
        """Refresh the boxes when the objects or obstacles changed; the people's cylinders."""
        key = (tuple(objects), tuple(obstacles))
        if key != self._key:
            self._key = key
            boxes, _ = scene_solids(objects, obstacles, [])
            self.boxes = boxes
            self.corners = [solid_corners(b) for b in boxes]
            self._xy = np.array([b.centre[:2] for b in boxes], dtype=float).reshape(-1, 2)
            self._z = np.array([b.centre[2] for b in boxes], dtype=float)
            self._reach = np.array([float(np.linalg.norm(b.half)) for b in boxes], dtype=float)
        base = len(objects) + len(obstacles)
        return [(np.array([float(x), float(y)]), base + k + 1) for k, (x, y) in enumerate(people)]

    def candidates(self, T_map_camera: np.ndarray, K: np.ndarray, shape: tuple[int, int],
                   depth_max: float, near: float) -> list[int]:
        """Indices of the boxes that may reach the image (see the module doc).

        A box is dropped when all its corners lie beyond ``depth_max`` along the optical
        axis, or not in front of ``near``, or outside one of the four planes through the
        camera and a line of pixels a few pixels off the image's edge. Its corners lie
        within its half diagonal of its centre, so one distance per plane decides.
        """
        if not self.boxes:
            return []
        rel = np.column_stack([self._xy - T_map_camera[:2, 3], self._z - T_map_camera[2, 3]])
        depth = rel @ T_map_camera[:3, 2]
        keep = (depth - self._reach <= depth_max + _MARGIN) & (depth + self._reach > near - _MARGIN)
        for normal in _outward_normals(K, shape):
            outward = rel @ (T_map_camera[:3, :3] @ normal)
            keep &= outward - self._reach <= _MARGIN
        return np.flatnonzero(keep).tolist()


def _outward_normals(K: np.ndarray, shape: tuple[int, int]) -> list[np.ndarray]:
    """Unit normals (optical frame) of the planes through the camera beyond which a point
    projects left of column -3, right of column w + 2, above row -3 or below row h + 2:
    far enough out that :func:`bomc_bt.sim.raycast.draw_box` finds no pixel to draw."""
    h, w = shape
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    planes = [-np.array([fx, 0.0, cx + 3.0]), np.array([fx, 0.0, cx - (w + 2.0)]),
              -np.array([0.0, fy, cy + 3.0]), np.array([0.0, fy, cy - (h + 2.0)])]
    return [n / np.linalg.norm(n) for n in planes]
