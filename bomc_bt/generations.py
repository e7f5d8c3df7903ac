"""Map generations: a build makes its map beside the current one and switches only when it succeeds.

A site is months of work; a failed, killed or mistaken re-build must not cost any of it.
So a build never writes where the current map lives::

    generations/<n>.partial/   the build in progress: map, trajectory, build.json
    generations/<n>/           a finished build (never changed afterwards)
    generations/<m>/graph/     the object graph made in map <m>, archived by ``--new-map``
    current                    "<n>": the number of the current generation
    map.yaml, map.pgm, trajectory.csv, build.json
                               copies of the current generation, for outside scripts
                               (CONTRACTS.md 3); bomc itself reads through ``current``

Every step below runs under the site's writer lock (:mod:`bomc_bt.site_lock`).

A build (:func:`begin_build`, :meth:`StagedBuild.finish`):

1. ``recover`` (below) whatever an earlier killed command left.
2. Refuse, before writing anything, a re-build over a graph (``site.db`` with sessions)
   unless ``--new-map`` asks for a new map: the graph's positions are in the old map.
3. Adopt a site built before generations (map files at the top level, no ``current``):
   copy its files into ``generations/1.partial``, rename that to ``generations/1``, write
   ``current``. The top-level files are not touched; readers see the same bytes.
4. Stage: delete leftover ``*.partial`` folders (builds that never finished), make
   ``generations/<n>.partial`` (n = highest + 1); the build writes only there.
5. Commit, only if the build succeeded (or the site had no map at all, so there is
   nothing to protect and the map is never lost):

   a. write ``commit.json`` (the previous generation, whether to archive the graph)
      into the partial folder;
   b. rename ``<n>.partial`` to ``<n>``: the build is now made, and from here on a kill
      is rolled forward by ``recover``;
   c. replace ``current`` with ``n`` (temporary file + ``os.replace``, folder fsynced):
      the one atomic switch; whoever reads through ``current`` sees the old generation
      whole before it and the new one whole after it;
   d. with ``--new-map``: move ``site.db`` (and its ``-wal``/``-shm``), ``sessions/`` and
      ``plan.json`` into ``generations/<m>/graph/``, one rename each;
   e. publish: each top-level copy whose bytes differ from generation ``n``'s is
      replaced (temporary file + ``os.replace``), one file at a time;
   f. delete ``commit.json``.

``recover`` (every writer, first thing after locking): for each finished generation that
still has a ``commit.json``, redo c-f (each is idempotent); then e for the current
generation; and delete temporary files a kill left in the site folder.

What a kill leaves, by where it lands:

* before 5b (during the run, or in 1-4): ``current``, the top-level files and the graph
  are exactly as before; the ``.partial`` folder is deleted by the next build.
* between 5b and 5c: generation ``n`` is finished but not current; the next command's
  ``recover`` makes it current (the build had succeeded and was allowed).
* between 5c and 5f: readers through ``current`` already see generation ``n`` whole;
  the top-level copies may be part old, part new, and with ``--new-map`` the old graph
  may still be at the top level beside the new map, until the next writer command
  (build or monitor) finishes the steps before doing anything else. A script that reads
  the top-level copies while a build commits can see the same mix for the milliseconds
  of 5e: read ``current`` and ``generations/<n>/`` when that matters.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from bomc_bt.atomic import atomic_write
from bomc_bt.errors import BomcError
from bomc_bt.site import GENERATIONS, POINTER, Site, current_generation, generation_dir, read_json
from bomc_bt.site_lock import SiteLock

PUBLISHED = ("map.pgm", "map.yaml", "trajectory.csv", "build.json")
GRAPH_FILES = ("site.db", "site.db-wal", "site.db-shm", "site.db-journal", "sessions", "plan.json")
INTENT = "commit.json"
ARCHIVE = "graph"
PARTIAL = ".partial"


@dataclass
class StagedBuild:
    """A build in progress: its generation number, what it replaces, and the held lock."""

    root: Path
    number: int
    previous: int | None
    archive_graph: bool
    lock: SiteLock
    site: Site  # the site as the build writes it: ``data`` is the partial generation
    published: bool = False

    def finish(self, succeeded: bool) -> bool:
        """Make the build current when it succeeded (or the site had no map); returns whether it did."""
        if not (succeeded or (self.previous is None and self.site.map_yaml.exists())):
            return False
        partial = self.site.data
        atomic_write(partial / INTENT, json.dumps(
            {"generation": self.number, "previous": self.previous, "archive_graph": self.archive_graph}).encode())
        _fsync_dir(partial)
        os.rename(partial, generation_dir(self.root, self.number))
        _fsync_dir(self.root / GENERATIONS)
        _complete(self.root, self.number)
        self.published = True
        return True

    def note(self) -> str:
        """One line for the operator about where this build's map went."""
        if self.published:
            return f"site: generation {self.number} is current" + (
                f"; the graph of generation {self.previous} is archived in "
                f"{generation_dir(self.root, self.previous or 0) / ARCHIVE}" if self.archive_graph else "")
        return (f"site: the build did not succeed: the site keeps generation {self.previous}; this build's files "
                f"are in {self.site.data} until the next build")

    def close(self) -> None:
        self.lock.release()


def begin_build(root: Path, new_map: bool = False) -> StagedBuild:
    """Lock the site, recover, refuse or adopt, and stage a new generation (steps 1-4)."""
    root = Path(root)
    lock = SiteLock.acquire(root, "build", create=True)
    with released_on_error(lock, root, "prepare the new map generation"):
        recover(root)
        sessions = _graph_sessions(root)
        previous = current_generation(root)
        if sessions and not new_map:
            made_in = f"map generation {previous}" if previous else "the current map"
            count = f"{sessions} session" + ("s" if sessions > 1 else "")
            raise BomcError(f"the object graph ({count}) was made in {made_in}; a new build makes a new map: add "
                            "--new-map to archive the graph with its map and start a new one",
                            root / "site.db", "--new-map")
        if previous is None and (root / "map.yaml").exists():
            previous = _adopt(root)
        number = 1 + max(_finished(root), default=0)
        for leftover in (root / GENERATIONS).glob(f"*{PARTIAL}"):
            shutil.rmtree(leftover)
        partial = root / GENERATIONS / f"{number}{PARTIAL}"
        partial.mkdir(parents=True)
        site = Site(root, data=partial)
        return StagedBuild(root, number, previous, bool(sessions), lock, site)


def recover(root: Path) -> None:
    """Finish what a killed build left (see the module docstring); the caller holds the lock."""
    root = Path(root)
    for number in sorted(_finished(root)):
        if (generation_dir(root, number) / INTENT).exists():
            _complete(root, number)
    current = current_generation(root)
    if current is not None:
        _publish(root, current)
    for name in (*PUBLISHED, POINTER):
        for temp in root.glob(f".{name}.*"):
            temp.unlink(missing_ok=True)


def _complete(root: Path, number: int) -> None:
    """Steps c-f for finished generation ``number``."""
    gen = generation_dir(root, number)
    intent = read_json(gen / INTENT)
    if not isinstance(intent, dict):
        raise BomcError("not a commit record", gen / INTENT)
    atomic_write(root / POINTER, f"{number}\n".encode())
    _fsync_dir(root)
    if intent.get("archive_graph"):
        previous = intent.get("previous")
        _archive_graph(root, previous if isinstance(previous, int) else 0)
    _publish(root, number)
    (gen / INTENT).unlink()
    _fsync_dir(gen)


def _archive_graph(root: Path, previous: int) -> None:
    target = generation_dir(root, previous) / ARCHIVE
    target.mkdir(parents=True, exist_ok=True)
    for name in GRAPH_FILES:
        if (root / name).exists():
            if (target / name).is_dir():
                raise BomcError(f"cannot archive the graph: {target / name} already exists", root / name)
            os.replace(root / name, target / name)
    _fsync_dir(target)
    _fsync_dir(root)


def _publish(root: Path, number: int) -> None:
    """Make the top-level copies equal to generation ``number``'s files (step e)."""
    gen = generation_dir(root, number)
    for name in PUBLISHED:
        source, copy = gen / name, root / name
        if not source.exists():
            copy.unlink(missing_ok=True)
            continue
        payload = source.read_bytes()
        if not copy.is_file() or copy.read_bytes() != payload:
            atomic_write(copy, payload)
    _fsync_dir(root)


def _adopt(root: Path) -> int:
    """Make a site built before generations into generation 1 (step 3); the top level is not touched."""
    partial = root / GENERATIONS / f"1{PARTIAL}"
    if partial.exists():
        shutil.rmtree(partial)
    partial.mkdir(parents=True)
    for name in PUBLISHED:
        if (root / name).is_file():
            atomic_write(partial / name, (root / name).read_bytes())
    os.rename(partial, generation_dir(root, 1))
    atomic_write(root / POINTER, b"1\n")
    _fsync_dir(root)
    return 1


def _finished(root: Path) -> list[int]:
    """The numbers of the finished generations (folders named by a number)."""
    folder = root / GENERATIONS
    if not folder.is_dir():
        return []
    return [int(p.name) for p in folder.iterdir() if p.is_dir() and p.name.isdigit() and len(p.name) < 10]


def _graph_sessions(root: Path) -> int:
    """How many monitor sessions the site's graph holds (0 without a graph); read-only."""
    from bomc_bt.store import SiteStore

    path = root / "site.db"
    if not path.exists():
        return 0
    with SiteStore(path, readonly=True) as store:
        return len(store.sessions())


def _fsync_dir(path: Path) -> None:
    """Make renames and new entries in ``path`` durable (a power cut keeps the switch)."""
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def lock_for_monitor(root: Path) -> SiteLock:
    """The writer lock of a monitor pass, after finishing whatever a killed build left."""
    lock = SiteLock.acquire(Path(root), "monitor")
    with released_on_error(lock, root, "finish the last build's switch"):
        recover(Path(root))
    return lock


@contextlib.contextmanager
def released_on_error(lock: SiteLock, root: Path, doing: str):
    """Release ``lock`` if the block fails; a file-system error becomes one line naming the site."""
    try:
        yield
    except OSError as exc:
        lock.release()
        raise BomcError(f"cannot {doing} ({exc.strerror})", root) from None
    except BaseException:
        lock.release()
        raise
