"""Things that go wrong on a real robot, injected into the simulator on purpose (seeded).

* navigation goals that abort at a random moment (move_base giving up);
* people walking back and forth: moving discs the lidar sees and the robot cannot drive
  through, so behaviours meet transient blockages;
* localization noise on the reported pose once localized.
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.sim.scene import Scene

PERSON_RADIUS = 0.25  # m


class People:
    """People pacing along straight lines through open space.

    Each person starts on a random cell with room around it and walks in a random
    direction until the next step would bring them within ``PERSON_RADIUS`` plus a margin
    of anything solid, then turns back: in a building this makes them walk up and down
    corridors and across rooms. A person waits rather than walk into the robot.
    """

    def __init__(self, scene: Scene, count: int, speed: float, rng: np.random.Generator,
                 keep_clear: tuple[float, float] | None = None, keep_clear_radius: float = 1.5):
        """``keep_clear``: a point (the robot's start) no person starts near."""
        self.speed = speed
        self.scene = scene
        cells = scene.free_cells(PERSON_RADIUS + 0.35)
        if keep_clear is not None and len(cells):
            far = np.hypot(cells[:, 0] - keep_clear[0], cells[:, 1] - keep_clear[1]) > keep_clear_radius
            cells = cells[far] if far.any() else cells
        if count == 0 or len(cells) == 0:
            self.positions = np.zeros((0, 2))
            self.headings = np.zeros((0, 2))
            return
        pick = rng.choice(len(cells), size=count, replace=len(cells) < count)
        self.positions = cells[pick].astype(float)
        angles = rng.uniform(-math.pi, math.pi, count)
        self.headings = np.stack([np.cos(angles), np.sin(angles)], axis=1)

    def place(self, positions, headings=None) -> None:
        """Put people at given map-frame points (scripted scenarios); headings are angles (rad)."""
        self.positions = np.asarray(positions, dtype=float).reshape(-1, 2).copy()
        angles = np.zeros(len(self.positions)) if headings is None else np.asarray(headings, dtype=float)
        self.headings = np.stack([np.cos(angles), np.sin(angles)], axis=1)

    def __len__(self) -> int:
        return len(self.positions)

    def step(self, dt: float, robot_xy: np.ndarray, robot_radius: float) -> None:
        margin = PERSON_RADIUS + 0.1
        for i in range(len(self.positions)):
            nxt = self.positions[i] + self.headings[i] * self.speed * dt
            if self.scene.clearance(nxt[0], nxt[1]) < margin:
                self.headings[i] = -self.headings[i]
                continue
            if np.hypot(*(nxt - robot_xy)) < robot_radius + PERSON_RADIUS + 0.05:
                continue  # wait for the robot to pass
            self.positions[i] = nxt

    def blocks(self, xy: np.ndarray, radius: float) -> bool:
        """Whether a disc of ``radius`` at ``xy`` overlaps a person."""
        if len(self.positions) == 0:
            return False
        d = np.hypot(self.positions[:, 0] - xy[0], self.positions[:, 1] - xy[1])
        return bool((d < radius + PERSON_RADIUS).any())
