"""Which of a site's files travel to the central store, and under which names.

A site keeps each map generation's files in ``generations/<n>/`` and the graph of the
current generation at the top level (an archived graph in ``generations/<m>/graph/``,
:mod:`bomc_bt.generations`). Centrally a file is keyed by building, floor, generation and
a name that does not depend on where the local copy keeps it:

* ``map/map.yaml``, ``map/map.pgm``, ``map/trajectory.csv``, ``map/build.json``: the build;
* ``graph/plan.json``, ``graph/sessions/<n>/<file>``: the passes' plan and reports.

``site.db`` is not a file here: its rows travel (:mod:`bomc_bt.central.rows`). A site
built before generations is generation 1 with its files at the top level.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from bomc_bt.generations import ARCHIVE, PUBLISHED
from bomc_bt.site import GENERATIONS, current_generation, generation_dir

MAP = "map/"
GRAPH = "graph/"


@dataclass(frozen=True)
class LocalGeneration:
    """One map generation of a local site: where its map files and its graph live."""

    number: int
    map_dir: Path
    graph_dir: Path | None  # None: no graph was made in this map

    @property
    def store(self) -> Path | None:
        path = None if self.graph_dir is None else self.graph_dir / "site.db"
        return path if path is not None and path.is_file() else None


def local_generations(root: Path) -> list[LocalGeneration]:
    """The finished generations of a site, oldest first (the current one with the top-level graph)."""
    root = Path(root)
    current = current_generation(root)
    if current is None:
        return [LocalGeneration(1, root, root)] if (root / "map.yaml").exists() else []
    out = []
    folder = root / GENERATIONS
    numbers = sorted(int(p.name) for p in folder.iterdir() if p.is_dir() and p.name.isdigit() and len(p.name) < 10)
    for n in numbers:
        archived = generation_dir(root, n) / ARCHIVE
        graph = root if n == current else (archived if archived.is_dir() else None)
        out.append(LocalGeneration(n, generation_dir(root, n), graph))
    return out


def local_files(gen: LocalGeneration) -> dict[str, Path]:
    """Central name -> local path of every file of ``gen`` that travels."""
    files = {MAP + name: gen.map_dir / name for name in PUBLISHED if (gen.map_dir / name).is_file()}
    if gen.graph_dir is not None:
        if (gen.graph_dir / "plan.json").is_file():
            files[GRAPH + "plan.json"] = gen.graph_dir / "plan.json"
        sessions = gen.graph_dir / "sessions"
        if sessions.is_dir():
            for path in sorted(sessions.rglob("*")):
                if path.is_file() and not path.name.startswith("."):
                    files[GRAPH + path.relative_to(gen.graph_dir).as_posix()] = path
    return files


def local_path(root: Path, generation: int, name: str) -> Path:
    """Where a pulled file goes in a site whose current generation is ``generation``."""
    if name.startswith(MAP):
        return generation_dir(root, generation) / name[len(MAP):]
    return Path(root) / name[len(GRAPH):]


def sha256(payload: bytes) -> str:
    return hashlib.sha256(payload).hexdigest()


def safe_name(name: str) -> bool:
    """A central file name we are willing to write locally: no absolute path, no ``..``."""
    parts = name.split("/")
    return (name.startswith((MAP, GRAPH)) and all(p not in ("", ".", "..") for p in parts)
            and (not name.startswith(MAP) or (len(parts) == 2 and parts[1] in PUBLISHED)))
