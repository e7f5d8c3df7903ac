"""Simulation worlds: the ground truth a simulated mission runs in and is scored against.

The public face of the package; import from here. The parts, one job each:

* :mod:`.records` -- objects, obstacles and changes (plain frozen records);
* :mod:`.timeline` -- :class:`World` and :func:`apply_change`: what is where in session
  *n* at time *t* (the timeline rules are written there);
* :mod:`.walls` -- which map cells are solid and whether a box stands inside a wall;
* :mod:`.loader` -- the world file format and its validation (:func:`load_world`), with
  :mod:`.fields` (typed field reads with one-line errors); strict YAML comes from :mod:`bomc_bt.yaml_io`.
"""

from bomc_bt.world.loader import DEFAULT_WALL_HEIGHT, FORMAT_VERSION, load_world
from bomc_bt.world.records import Change, DuringChange, Obstacle, WorldObject
from bomc_bt.world.timeline import World, apply_change, lands_on
from bomc_bt.world.walls import embedded_in_wall, wall_mask

__all__ = [
    "DEFAULT_WALL_HEIGHT",
    "FORMAT_VERSION",
    "Change",
    "DuringChange",
    "Obstacle",
    "World",
    "WorldObject",
    "apply_change",
    "lands_on",
    "embedded_in_wall",
    "load_world",
    "wall_mask",
]
