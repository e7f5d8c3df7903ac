"""Run a ``bomc`` command that kills itself with SIGKILL at its N-th step: a kill -9 at a chosen point.

    python tests/kill_points.py N COUNT_FILE bomc-args...

A *step* is a moment where a process dies differently: before each SQL statement sent to
PostgreSQL (``execute``, ``executemany``), before each row streamed by ``COPY``, before
and after each transaction's end (commit or rollback), and before and after each file
rename (``os.replace``, ``os.rename``: what makes a local write visible). At step ``N``
the process sends itself SIGKILL: nothing of Python runs after it (no ``finally``, no
rollback, no atexit), exactly as ``kill -9`` from outside. With ``N = 0`` it runs to the
end and writes to ``COUNT_FILE`` (JSON) how many steps it took and which steps come right
after a transaction ended, so a test can pick points over the whole command and knows
where a commit lies.

Why not a random delay: the interesting part of a sync is a fraction of the process's
life (most of it is Python starting), so a random delay mostly kills it before it has
connected; counting steps puts every kill inside the work, reproducibly.
"""

from __future__ import annotations

import functools
import json
import os
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psycopg

_steps = 0
_kill_at = 0
_after_transactions: list[int] = []


def _step() -> None:
    global _steps
    _steps += 1
    if _steps == _kill_at:
        os.kill(os.getpid(), signal.SIGKILL)


def _before(fn: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        _step()
        return fn(*args, **kwargs)
    return wrapper


def _around(fn: Callable[..., Any], marks: list[int] | None = None) -> Callable[..., Any]:
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        _step()
        out = fn(*args, **kwargs)
        if marks is not None:
            marks.append(_steps + 1)
        _step()
        return out
    return wrapper


def install() -> None:
    psycopg.Cursor.execute = _before(psycopg.Cursor.execute)
    psycopg.Cursor.executemany = _before(psycopg.Cursor.executemany)
    psycopg.Copy.write_row = _before(psycopg.Copy.write_row)
    psycopg.Transaction.__exit__ = _around(psycopg.Transaction.__exit__, _after_transactions)
    os.replace = _around(os.replace)
    os.rename = _around(os.rename)


def main() -> int:
    global _kill_at
    _kill_at = int(sys.argv[1])
    count_file = Path(sys.argv[2])
    install()
    from bomc_bt.cli import main as bomc_main

    code = bomc_main(sys.argv[3:])
    count_file.write_text(json.dumps({"steps": _steps, "after_transactions": _after_transactions}))
    return code


if __name__ == "__main__":
    sys.exit(main())
