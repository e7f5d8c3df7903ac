"""How generated objects look: a colour per object, drawn from its kind's few models.

Both generators use it: ``bomc world office`` (:mod:`bomc_bt.officegen`) and ``bomc world
map`` (:mod:`bomc_bt.worldgen`).

An office's chairs are not all one chair: a floor is furnished from a handful of models
(a grey task chair, a blue visitor chair, an orange one in the cafe), and so are its bins,
tables and plants. Worlds written before objects had colours drew every object of a
category in the category's colour, which hides the one cue a robot has to tell a chair
carried across the floor from a chair taken away while another was brought in
(:mod:`bomc_bt.graph.looks`). Each category here has a few models; an object's model is a
hash of the world's seed and its name, so it keeps its look when it is moved or brought
back, the layout's random draws stay as they were (same seed, same floor), and a new
object gets a model like any other. Several models are neutral (grey, white, black): their
colours differ in brightness only, which a camera cannot tell from lighting, so objects of
those models look alike to the robot, as they would.

Colours are RGB 0-255 (the world file's ``colour``), flat as the simulator renders them.
A category without models here (one a user adds) keeps the category colour.
"""

from __future__ import annotations

import zlib

MODELS: dict[str, tuple[tuple[int, int, int], ...]] = {
    "chair": ((45, 60, 140), (160, 45, 40), (50, 120, 60), (200, 130, 40), (90, 90, 95)),
    "trash bin": ((60, 90, 160), (40, 130, 70), (150, 150, 150), (190, 160, 40)),
    "potted plant": ((60, 140, 50), (170, 90, 50), (225, 225, 220)),
    "table": ((190, 150, 100), (110, 70, 45), (225, 225, 220)),
    "cabinet": ((150, 150, 150), (190, 150, 100), (60, 70, 110)),
    "sofa": ((130, 40, 50), (60, 70, 120), (90, 90, 95)),
    "television": ((30, 30, 35),),
    "door": ((200, 170, 120), (230, 230, 225)),
}


def model_colour(seed: int, name: str, category: str) -> tuple[int, int, int] | None:
    """The colour of object ``name`` in the world of ``seed`` (None: the category's colour)."""
    models = MODELS.get(category)
    if not models:
        return None
    return models[zlib.crc32(f"{seed}:{name}".encode()) % len(models)]
