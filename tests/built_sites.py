"""Copies of a site built once per test session (the ``office_s_built`` fixture in conftest).

A build explores the whole floor; the tests that only need *a* built office-s to run passes
on start from a copy instead of exploring it again.
"""

from __future__ import annotations

import shutil
from pathlib import Path


def copy_site(built: dict, to: Path) -> Path:
    """A copy of the built site ``built["site"]`` at ``to`` (without its lock file), ready for passes."""
    shutil.copytree(built["site"], to, ignore=shutil.ignore_patterns(".lock"))
    return to
