"""Helpers for the site-integrity tests: run ``bomc`` in a subprocess, photograph a site's files."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from shared_data import SHARED

REPO = Path(__file__).resolve().parents[1]
LAB_B = SHARED / "worlds" / "lab-b.yaml"
BUILD_FILES = ("map.yaml", "map.pgm", "trajectory.csv", "build.json")


def bomc_command(*args: str) -> list[str]:
    return [sys.executable, "-m", "bomc_bt.cli", *args]


def bomc_env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(REPO), "PYTHONDONTWRITEBYTECODE": "1"}


def bomc(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(bomc_command(*args), capture_output=True, text=True, cwd=REPO, env=bomc_env(),
                          timeout=timeout)


def error_line(result: subprocess.CompletedProcess) -> str:
    """The one ``bomc: error:`` line of a refused command (exit 2, no traceback)."""
    assert result.returncode == 2, (result.returncode, result.stdout, result.stderr)
    assert "Traceback" not in result.stderr, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("bomc: error:")]
    assert len(lines) == 1, result.stderr
    return lines[0]


def snapshot(root: Path, mtimes: bool = False, skip: tuple[str, ...] = (".lock",)) -> dict[str, object]:
    """Every file under ``root`` (relative path -> bytes, with the mtime when asked); folders too."""
    files: dict[str, object] = {}
    for path in sorted(root.rglob("*")):
        rel = str(path.relative_to(root))
        if rel in skip:
            continue
        if path.is_dir():
            files[rel + "/"] = path.stat().st_mtime_ns if mtimes else None
        else:
            files[rel] = (path.read_bytes(), path.stat().st_mtime_ns) if mtimes else path.read_bytes()
    return files


def build_files(folder: Path) -> dict[str, bytes]:
    """The map, trajectory and build record in ``folder`` (missing ones as None)."""
    return {name: (folder / name).read_bytes() if (folder / name).exists() else None for name in BUILD_FILES}


def copy_site(source: Path, target: Path) -> Path:
    shutil.copytree(source, target, symlinks=True)
    return target
