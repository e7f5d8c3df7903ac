"""Contact: what a step of the simulated base does when it would run into something solid.

The simulator refuses a translation that takes the base's body (a disc of
``motion.body_radius``) closer to anything solid than that radius, unless it moves away.
Refusing is not all a real base does, so a refused step is resolved here, in this order:

* a glancing contact is deflected along the surface (:func:`slide_along`), or, where the
  clearance has no gradient to slide along (a lane one collision cell wide), turned by the
  least angle that lets it go on;
* anything else stops the base, which a bumper pushes off one collision cell
  (:func:`slide_out`), so a base wedged tighter than its body is never held for ever.

People are never pushed into or slid along: a step onto one is no way out.
"""

from __future__ import annotations

import math

import numpy as np

from bomc_bt.geometry import Pose2D
from bomc_bt.sim.faults import People
from bomc_bt.sim.scene import Scene


def allowed(before: float, after: float, radius: float) -> bool:
    """A step from clearance ``before`` to ``after`` (m) keeps the body clear or moves away."""
    return after >= radius or after > before


def slide_along(scene: Scene, people: People, t: Pose2D, x: float, y: float,
                radius: float) -> tuple[float, float] | None:
    """Contact at a glancing angle: the part of the step from ``t`` to (x, y) along the
    surface touched, or None when there is none worth taking.

    A round base that grazes a jamb is deflected along it, not stopped. Refusing the whole
    step left a robot threading a gap 0.08 m wider than its body a few degrees off the
    gap's axis refused at every step, pushed back, driven in again, until the goal was given
    up (hospital, a doorway in a dotted wall: the build ended "stuck"). The step loses its
    component into the surface (the clearance's gradient over one cell each side); what is
    left must be at least half the step and obey the rule of any step (:func:`allowed`).
    """
    c = scene.clearance
    h = scene.grid.resolution
    gx = c(t.x + h, t.y) - c(t.x - h, t.y)
    gy = c(t.x, t.y + h) - c(t.x, t.y - h)
    norm = math.hypot(gx, gy)
    if norm == 0.0:
        return _turned_step(scene, people, t, x, y, radius)
    dx, dy = x - t.x, y - t.y
    into = (dx * gx + dy * gy) / norm
    if into >= 0.0:
        return None
    sx, sy = dx - into * gx / norm, dy - into * gy / norm
    if math.hypot(sx, sy) < 0.5 * math.hypot(dx, dy):
        return None
    nx, ny = t.x + sx, t.y + sy
    if people.blocks(np.array([nx, ny]), radius) or not allowed(c(t.x, t.y), c(nx, ny), radius):
        return None
    return nx, ny


def _turned_step(scene: Scene, people: People, t: Pose2D, x: float, y: float,
                 radius: float) -> tuple[float, float] | None:
    """The step from ``t`` to (x, y) turned by the least angle (up to 60 degrees, in 7.5
    degree steps) that makes it allowed, shortened to its projection on the new direction;
    None when no turn does.

    In a lane one collision cell wide (a doorway 0.06-0.1 m wider than the body) the
    clearance is the same on both sides of the base, so it has no gradient to slide along,
    and a step a few degrees off the lane's axis was refused at every try: pure pursuit
    cutting the corner beyond a 0.58 m doorway held the base there for good (hospital,
    seed-57 world, the build ended "stuck"). A round base there is turned by the jambs.
    """
    c = scene.clearance
    before = c(t.x, t.y)
    dx, dy = x - t.x, y - t.y
    for k in range(1, 9):
        turn = math.radians(7.5 * k)
        options = []
        for sign in (1.0, -1.0):
            ca, sa = math.cos(sign * turn), math.sin(sign * turn)
            nx, ny = t.x + ca * (ca * dx - sa * dy), t.y + ca * (sa * dx + ca * dy)
            after = c(nx, ny)
            if not people.blocks(np.array([nx, ny]), radius) and allowed(before, after, radius):
                options.append((after, nx, ny))
        if options:
            _, nx, ny = max(options)
            return nx, ny
    return None


def slide_out(scene: Scene, people: People, t: Pose2D, radius: float) -> tuple[float, float]:
    """A base pressed against something slides a little away from it (or stays at ``t``).

    Without it a robot wedged in a spot tighter than its body (a half-seen doorway, a chair
    leg) could refuse every forward and backward step for ever; a real base's bumper pushes
    it off instead. The step is one cell of the collision map, to the neighbouring point of
    most clearance: clearance is read per cell, so a shorter step lands on the same value
    and a wedged robot (between a chair and a pillar, both its forward and its backward step
    refused) never moved (hospital, issue 16). A person is not pushed: a step onto one is no
    way out (people wait for the robot, the base never slides into them; it did, and its
    lidar then saw nothing but the person).
    """
    c = scene.clearance
    step = scene.grid.resolution
    angles = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    xs, ys = t.x + step * np.cos(angles), t.y + step * np.sin(angles)
    room = [-math.inf if people.blocks(np.array([x, y]), radius) else c(float(x), float(y))
            for x, y in zip(xs, ys, strict=True)]
    best = int(np.argmax(room))
    return (float(xs[best]), float(ys[best])) if room[best] > c(t.x, t.y) else (t.x, t.y)
