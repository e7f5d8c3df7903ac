"""From parameters to files: draft the office world in memory, then write it atomically.

:func:`draft_office` runs the whole generator (plan, session-1 furniture, timeline) from
one seeded generator and checks the result on the full map (every doorway reachable from
the dock, every object within view of a reachable pose), so a generator bug is a clear
error rather than a world a robot cannot finish. :func:`write_office` writes the world
file, the map YAML and the PGM into a temporary folder beside the target, loads the world
back through :func:`bomc_bt.world.load_world` (the loader validates everything and
replays the timeline), and only then renames the three files into place. The same
parameters always give byte-identical files.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bomc_bt.atomic import atomic_write
from bomc_bt.errors import BomcError
from bomc_bt.grid import save_map
from bomc_bt.officegen.connectivity import distance_to, reachable
from bomc_bt.officegen.floor import FloorPlan, plan_floor
from bomc_bt.officegen.furnish import Furnishing, furnish
from bomc_bt.officegen.layout import Item, Layout
from bomc_bt.officegen.params import OfficeParams
from bomc_bt.officegen.sessions import Timeline, plan_timeline
from bomc_bt.world import FORMAT_VERSION, World, load_world
from bomc_bt.world.records import box_corners

WALL_HEIGHT = 2.5


@dataclass
class OfficeDraft:
    """A generated office world before it is written: the plan, what was placed and the timeline."""

    params: OfficeParams
    plan: FloorPlan
    furnishing: Furnishing
    timeline: Timeline
    objects: list[dict[str, Any]]  # session 1, world-file form

    def document(self, name: str, map_file: str) -> dict[str, Any]:
        """The world file's content (CONTRACTS section 1; ``x-office`` is an extension key)."""
        p = self.params
        doc: dict[str, Any] = {
            "version": FORMAT_VERSION,
            "name": name,
            "map": map_file,
            "start": [round(v, 3) for v in self.plan.start],
            "wall_height": WALL_HEIGHT,
            "x-office": {
                "size": [p.width, p.height], "seed": p.seed, "churn": 0.0 if p.static else p.churn,
                "corridors": len(self.plan.corridors), "rooms": len(self.plan.rooms),
                "doorways": len(self.plan.doorways),
                "blocked_corridors": {k: c.index for k, c in self.timeline.blocked.items()},
                **({"corridor_chairs": self.timeline.corridor_chairs} if self.timeline.corridor_chairs else {}),
            },
            "objects": self.objects,
        }
        if self.timeline.sessions:
            doc["sessions"] = self.timeline.sessions
        if self.timeline.during:
            doc["during"] = self.timeline.during
        return doc


def draft_office(params: OfficeParams) -> OfficeDraft:
    """Generate the whole world in memory (deterministic for ``params``)."""
    params = dataclasses.replace(params).check()
    rng = np.random.default_rng(params.seed)
    plan = plan_floor(params, rng)
    layout = Layout(plan, params, rng)
    furnishing = furnish(layout)
    objects = sorted(layout.present.values(), key=_order)
    _verify_session_one(plan, params, objects)
    timeline = plan_timeline(layout)
    return OfficeDraft(params, plan, furnishing, timeline, [it.record() for it in objects])


def _order(item: Item) -> tuple[str, int]:
    """Doors first, then by category and number (chair-2 before chair-10)."""
    stem, _, number = item.name.rpartition("-")
    return ("" if item.category == "door" else item.category, int(number) if number.isdigit() else 0)


def _verify_session_one(plan: FloorPlan, params: OfficeParams, objects: list[Item]) -> None:
    """Every doorway reachable from the dock and every object within view of a reachable pose."""
    grid = plan.grid()
    boxes = [box_corners(it.x, it.y, it.size[0], it.size[1], it.yaw) for it in objects]
    reach = reachable(grid, boxes, params.robot_radius, plan.start[:2])
    for i, d in enumerate(plan.doorways):
        r, c = grid.world_to_cell(*d.centre)
        if not reach[r, c]:
            raise BomcError(f"generator bug: doorway {i} of room {d.room} at ({d.centre[0]:.2f}, "
                            f"{d.centre[1]:.2f}) is not reachable from the dock")
    to_reach = distance_to(reach, grid.resolution)
    for it in objects:
        r, c = grid.world_to_cell(it.x, it.y)
        if float(to_reach[r, c]) > params.view_reach + grid.resolution:
            raise BomcError(f"generator bug: {it.name} at ({it.x}, {it.y}) is out of the robot's reach")


def output_paths(out_path: str | Path) -> tuple[Path, Path, Path]:
    """The world file and, beside it, its map: ``NAME.yaml`` -> ``NAME-map.yaml``, ``NAME-map.pgm``."""
    out = Path(out_path)
    if out.suffix not in (".yaml", ".yml") or not out.stem:
        raise BomcError("the world file must be named NAME.yaml", out)
    map_yaml = out.with_name(f"{out.stem}-map.yaml")
    return out, map_yaml, map_yaml.with_suffix(".pgm")


def write_office(draft: OfficeDraft, out_path: str | Path, force: bool = False) -> World:
    """Write the world, its map YAML and PGM atomically, validated by loading them back."""
    out, map_yaml, map_pgm = output_paths(out_path)
    if not force:
        for path in (out, map_yaml, map_pgm):
            if path.exists():
                raise BomcError("already exists (use --force to replace it)", path)
    try:
        return _write(draft, out, map_yaml, map_pgm)
    except OSError as exc:  # an unwritable folder, a full disk: one line, not a traceback
        raise BomcError(f"cannot write the world ({exc.strerror or type(exc).__name__})", out) from None


def _write(draft: OfficeDraft, out: Path, map_yaml: Path, map_pgm: Path) -> World:
    out.parent.mkdir(parents=True, exist_ok=True)
    p = draft.params
    header = (f"# generated by: bomc world office --size {p.width:g}x{p.height:g} --seed {p.seed} "
              f"--sessions {p.sessions} {'--static' if p.static else f'--churn {p.churn:g}'} "
              f"--resolution {p.resolution:g}"
              f"{f' --corridor-chairs {p.corridor_chair_every}' if p.corridor_chair_every else ''}\n")
    doc = draft.document(p.name or out.stem, map_yaml.name)
    text = header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=110, allow_unicode=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.stem}."))
    try:
        save_map(draft.plan.grid(), tmp / map_yaml.name)
        atomic_write(tmp / out.name, text.encode("utf-8"))
        world = load_world(tmp / out.name)
        mode = 0o666 & ~_umask()  # temporary files are private; the results are ordinary files
        for path in (map_pgm, map_yaml, out):  # the world last: it names the map
            os.chmod(tmp / path.name, mode)
            os.replace(tmp / path.name, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return dataclasses.replace(world, path=out, map_path=map_yaml)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def generate_office(params: OfficeParams, out_path: str | Path, force: bool = False) -> World:
    """Generate an office world for ``params`` and write it to ``out_path`` (see the module docstring)."""
    return write_office(draft_office(params), out_path, force)
