"""Where the shared worlds and maps live, for every test and benchmark that needs them.

One place decides: ``$BOMC_SHARED`` if set, else ``shared/`` beside the checkout (the
layout CI uses). Tests that need the data skip with the reason when it is missing, so the
suite still runs on a checkout without it.
"""

from __future__ import annotations

import os
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
