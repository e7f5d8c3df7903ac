"""The site directory: everything a build and the monitor passes leave behind.

Layout (CONTRACTS.md section 3 fixes the first three entries)::

    map.yaml, map.pgm        the occupancy map (map_server format)
    trajectory.csv           exploration poses t,x,y,yaw
    build.json               the build summary (area, path length, sim time, reason)
    site.db                  object graph, events and sessions (bomc_bt.store)
    plan.json                the traversal plan of the last monitor pass
    sessions/<n>/            per-session report (JSON + Markdown) and semantic map PNG
    current                  the number of the current map generation (absent on old sites)
    generations/<n>/         one build each: map, trajectory, build.json (bomc_bt.generations)
    .lock                    the writer's lock (bomc_bt.site_lock)
    site.json                building / floor / robot in the central store (bomc_bt.central.identity)

The map, trajectory and build record are *read* from the current generation when the
site has a ``current`` pointer (it is read once, when the :class:`Site` is made, so one
reader never mixes two generations), else from the top level (a site built before
generations existed). The top-level copies are for outside scripts (CONTRACTS.md 3).

Files are written so that a crash loses nothing already observed: the trajectory is an
append-only CSV flushed row by row, JSON files are replaced atomically.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from bomc_bt.atomic import atomic_write
from bomc_bt.errors import BomcError

POINTER = "current"
GENERATIONS = "generations"


class _SiteFile:
    """A read-only attribute of :class:`Site`: the path of one fixed file in the site directory.

    ``of_build`` files belong to a map generation: they live in :attr:`Site.data`.
    """

    def __init__(self, name: str, of_build: bool = False):
        self.name = name
        self.of_build = of_build

    def __get__(self, site: Site, owner: type | None = None) -> Path:
        return (site.data if self.of_build and site.data is not None else site.root) / self.name


@dataclass(frozen=True)
class Site:
    """Paths inside one site directory (the layout in the module docstring).

    ``data`` is where the build's files are: the current generation, resolved once here,
    or the top level of a site without generations; a build passes its new generation.
    """

    root: Path
    data: Path | None = None  # resolved in __post_init__ when not given

    map_yaml = _SiteFile("map.yaml", of_build=True)
    trajectory_csv = _SiteFile("trajectory.csv", of_build=True)
    build_json = _SiteFile("build.json", of_build=True)
    store_path = _SiteFile("site.db")
    plan_json = _SiteFile("plan.json")

    def __post_init__(self) -> None:
        object.__setattr__(self, "root", Path(self.root))
        if self.data is None:
            number = current_generation(self.root)
            object.__setattr__(self, "data", self.root if number is None else generation_dir(self.root, number))

    def session_dir(self, number: int) -> Path:
        return self.root / "sessions" / str(number)

    def create(self) -> Site:
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BomcError(f"cannot create the site directory ({exc.strerror})", self.root) from None
        return self

    def require_build(self) -> None:
        """A monitor pass needs the map and the trajectory of a build."""
        for path in (self.map_yaml, self.trajectory_csv):
            if not path.exists():
                raise BomcError("missing: run `bomc build` for this site first", path)


def generation_dir(root: Path, number: int) -> Path:
    return Path(root) / GENERATIONS / str(number)


def current_generation(root: Path) -> int | None:
    """The number in ``root/current``, or None on a site without generations."""
    pointer = Path(root) / POINTER
    try:
        text = pointer.read_text()
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as exc:
        raise BomcError(f"unreadable generation pointer ({type(exc).__name__})", pointer) from None
    if not text.strip().isdigit() or len(text.strip()) > 9 or int(text) < 1:
        raise BomcError(f"not a generation number: {text[:20]!r}", pointer)
    number = int(text)
    if not generation_dir(root, number).is_dir():
        raise BomcError(f"generation {number} is missing ({generation_dir(root, number)})", pointer)
    return number


def write_json(path: Path, payload: Any) -> None:
    """Replace ``path`` atomically with ``payload`` as indented JSON."""
    text = json.dumps(payload, indent=2, sort_keys=False, default=_jsonable) + "\n"
    atomic_write(path, text.encode())


def read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise BomcError("not found", path) from None
    except (OSError, ValueError) as exc:
        raise BomcError(f"unreadable JSON ({exc})", path) from None


def _jsonable(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


class TrajectoryRecorder:
    """Appends exploration poses to ``trajectory.csv`` at a fixed rate of robot time.

    Each row is flushed as it is written, so a killed build keeps every pose recorded so
    far; a resumed build appends to the existing file.
    """

    HEADER = "t,x,y,yaw\n"

    def __init__(self, path: Path, period: float, append: bool = False):
        self.path = path
        self.period = period
        self._last_t = -math.inf
        self._last_xy: tuple[float, float] | None = None
        self.length = 0.0
        self.rows = 0
        exists = append and path.exists() and path.stat().st_size > 0
        self._file: TextIO = open(path, "a" if exists else "w")  # noqa: SIM115 - kept open for the run
        if not exists:
            self._file.write(self.HEADER)
            self._file.flush()

    def record(self, t: float, x: float, y: float, yaw: float, force: bool = False) -> bool:
        if self._last_xy is not None:
            self.length += math.hypot(x - self._last_xy[0], y - self._last_xy[1])
        self._last_xy = (x, y)
        if not force and t - self._last_t < self.period - 1e-9:
            return False
        self._last_t = t
        self._file.write(f"{t:.3f},{x:.4f},{y:.4f},{yaw:.4f}\n")
        self._file.flush()
        self.rows += 1
        return True

    def close(self) -> None:
        if not self._file.closed:
            os.fsync(self._file.fileno())
            self._file.close()
