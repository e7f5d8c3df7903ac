"""Shared fixtures: where the shared worlds and maps live."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def shared() -> Path:
    if not (SHARED / "worlds").is_dir():
        pytest.skip(f"shared data not found at {SHARED}")
    return SHARED
