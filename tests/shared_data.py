"""Where the shared worlds and maps live, for every test and benchmark that needs them.

One place decides: ``$BOMC_SHARED`` if set, else ``shared/`` beside the checkout (the
layout CI uses). Tests that need the data skip with the reason when it is missing, so the
suite still runs on a checkout without it.
"""

from __future__ import annotations

import functools
import os
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ["BOMC_SHARED"]) if os.environ.get("BOMC_SHARED") else REPO.parent / "shared"


def shared_path(relative: str) -> str:
    """``relative`` inside the shared folder (which may not exist: see :func:`require_shared`)."""
    return str(SHARED / relative)


def require_shared(path: str | Path | None = None) -> None:
    """Skip the calling test when the shared data (or ``path`` inside it) is missing."""
    target = Path(path) if path is not None else SHARED / "worlds"
    if not target.exists():
        pytest.skip(f"shared data not found at {target} (set BOMC_SHARED to the shared folder)")


_TEST_WORLDS = REPO / "tests" / "worlds"
_SHARED_MAPS = "../../../shared/maps/"  # how a test world names its map: the shared folder beside the checkout


def local_world(stem: str) -> Path:
    """``tests/worlds/<stem>.yaml`` with its map read from the shared folder this module
    found (``$BOMC_SHARED`` too, not only ``shared/`` beside the checkout): a copy in a
    temporary folder when the shared folder is elsewhere; skips when that map is missing."""
    path = _TEST_WORLDS / f"{stem}.yaml"
    text = path.read_text()
    line = next(x for x in text.splitlines() if x.startswith("map:"))
    name = line.split(_SHARED_MAPS, 1)[-1].strip()
    require_shared(SHARED / "maps" / name)
    if (path.parent / line[4:].strip()).resolve() == (SHARED / "maps" / name).resolve():
        return path
    copy = Path(_copies().name) / path.name
    if not copy.exists():
        copy.write_text(text.replace(line, f"map: {SHARED / 'maps' / name}"))
    return copy


@functools.cache
def _copies() -> tempfile.TemporaryDirectory:
    """One folder per test process for the rewritten worlds, removed when the process ends."""
    return tempfile.TemporaryDirectory(prefix="bomc-test-worlds-")
