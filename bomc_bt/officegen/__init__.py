"""Office floors of any size, with many sessions: the worlds tests and benchmarks run in.

``bomc world office`` and :func:`generate_office` write a version-1 world file (CONTRACTS
section 1) with its map_server map: a lattice of corridors with rooms along them
(:mod:`.floor`), furnished with the paper's Environment A object mix scaled to the floor's
area (:mod:`.furnish`), and sessions of changes -- objects removed, brought back, moved
and added, a corridor closed by an obstacle every third session, one change during each
pass (:mod:`.sessions`). Every placement keeps doorways passable and every object within
view of the robot (:mod:`.rooms`), checked again on the whole floor (:mod:`.connectivity`).
The same parameters always give byte-identical files (:mod:`.generate`).
"""

from bomc_bt.officegen.generate import OfficeDraft, draft_office, generate_office, output_paths, write_office
from bomc_bt.officegen.params import OfficeParams

__all__ = ["OfficeDraft", "OfficeParams", "draft_office", "generate_office", "output_paths", "write_office"]
