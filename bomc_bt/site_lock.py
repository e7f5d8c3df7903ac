"""One writer per site: ``bomc build`` and ``bomc monitor`` hold an OS lock for their whole run.

Two passes writing one graph at once corrupt it logically (each associates against a graph
the other is changing), and a build beside a pass swaps the map under the pass. So every
writer takes ``fcntl.flock(LOCK_EX | LOCK_NB)`` on ``<site>/.lock`` before it reads or
writes anything of the site, and keeps it until it ends. The kernel drops the lock when
the process dies (kill -9 included), so a crash never leaves a stale lock behind: the
file may stay, the lock does not.

After locking, the holder writes its pid and command line into the file, so the writer
that is refused can name it (exit 2, one line). The file's content is only that note: it
is rewritten by every writer and is not part of the site's data. Readers (evaluate, view)
take no lock: they open the store read-only and may run beside a writer.
"""

from __future__ import annotations

import fcntl
import json
import os
import shlex
import sys
from pathlib import Path

from bomc_bt.errors import BomcError

LOCK_FILE = ".lock"


class SiteLock:
    """The exclusive writer lock of one site, held from :meth:`acquire` until :meth:`release`."""

    def __init__(self, path: Path, fd: int):
        self.path = path
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, root: Path, mission: str, create: bool = False) -> SiteLock:
        """Lock ``root`` for ``mission`` ("build" / "monitor"), or raise a one-line BomcError.

        ``create`` makes the site directory first (a first build); otherwise a missing
        directory means the site was never built.
        """
        root = Path(root)
        path = root / LOCK_FILE
        if create:
            try:
                root.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise BomcError(f"cannot create the site directory ({exc.strerror})", root) from None
        elif not root.is_dir():
            raise BomcError("not a site directory: run `bomc build` for this site first", root)
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise BomcError(f"cannot lock the site for writing ({exc.strerror})", path) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = _holder(fd)
            os.close(fd)
            raise BomcError(f"another writer holds this site: {holder}; wait for it to end "
                            "(the lock goes when that process does)", path) from None
        lock = cls(path, fd)
        try:
            note = json.dumps({"pid": os.getpid(), "mission": mission, "command": _command_line()}) + "\n"
            os.ftruncate(fd, 0)
            os.pwrite(fd, note.encode(), 0)
        except OSError:  # a full disk must not stop the writer that holds the lock: the note is a courtesy
            pass
        return lock

    def release(self) -> None:
        """Unlock (closing the descriptor drops the flock); safe to call twice."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> SiteLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _command_line() -> str:
    argv = list(sys.argv)
    if argv and (argv[0].endswith("bomc_bt/cli.py") or Path(argv[0]).name == "bomc"):
        argv[0] = "bomc"
    return " ".join(shlex.quote(a) for a in argv)


def _holder(fd: int) -> str:
    """'pid N (command)' from the holder's note, as far as it can be read."""
    try:
        data = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
    except (OSError, ValueError):
        data = {}
    if not isinstance(data, dict) or not isinstance(data.get("pid"), int):
        return "a process that has not written its pid yet"
    return f"pid {data['pid']} ({data.get('mission', '?')}: {data.get('command', '?')})"
