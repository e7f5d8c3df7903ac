"""A build ends by itself, and says plainly when a limit cut it short (issue 15 item 1).

Without ``--max-time`` a build explores until no reachable frontier is left (termination
``done``, exit 0). A time limit ends it with termination ``time_limit``: the map is saved,
``build.json`` says how much unexplored border is left, and ``bomc build`` exits 1 with a
line saying the build is incomplete (README, "Build: how it ends").
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from bomc_bt.grid import FREE, OCCUPIED, OccupancyGrid, load_map, save_map

REPO = Path(__file__).resolve().parents[1]


def two_rooms(tmp_path: Path) -> Path:
    """An 8 m x 4 m floor split by a wall with a 1 m doorway; the robot starts in the left room."""
    data = np.full((90, 170), OCCUPIED, np.int8)  # 0.05 m cells, walls 0.25 m thick around
    data[5:85, 5:165] = FREE
    data[5:85, 83:87] = OCCUPIED
    data[35:55, 83:87] = FREE  # the doorway
    save_map(OccupancyGrid(data, 0.05, (0.0, 0.0)), tmp_path / "rooms-map.yaml")
    world = tmp_path / "rooms.yaml"
    world.write_text("version: 1\nname: rooms\nmap: rooms-map.yaml\nstart: [1.5, 2.25, 0.0]\n"
                     "wall_height: 2.5\nobjects: []\n")
    return world


def bomc(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "bomc_bt.cli", *args], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=300)


def test_build_without_a_limit_ends_by_itself_when_done(tmp_path):
    site = tmp_path / "site"
    result = bomc("build", "--world", str(two_rooms(tmp_path)), "--site", str(site), "--quiet")
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((site / "build.json").read_text())
    assert (summary["termination"], summary["outcome"], summary["time_limit_s"]) == ("done", "succeeded", None)
    left = summary["frontiers_left"]  # done: no reachable frontier left whose view adds min_gain
    assert left["reachable"] - left["blacklisted"] - left["below_min_gain"] == 0
    # both rooms mapped (2 x 3.9 m x 4 m of floor), in far less than the old 3600 s wall
    assert load_map(site / "map.yaml").free_area() > 25.0
    assert summary["sim_time_s"] < 600.0
    assert "build succeeded: done" in result.stdout


def test_time_limit_ends_with_time_limit_exit_1_and_the_map_saved(tmp_path):
    site = tmp_path / "site"
    result = bomc("build", "--world", str(two_rooms(tmp_path)), "--site", str(site), "--quiet",
                  "--max-time", "4")
    assert result.returncode == 1, result.stdout + result.stderr
    summary = json.loads((site / "build.json").read_text())
    assert (summary["termination"], summary["outcome"], summary["time_limit_s"]) == ("time_limit", "incomplete", 4.0)
    assert summary["sim_time_s"] <= 4.5
    assert summary["frontiers_left"]["reachable"] >= 1 and summary["frontiers_left"]["reachable_m"] > 0.5
    assert load_map(site / "map.yaml").free_area() > 5.0  # the partial map is there
    assert "build incomplete: time_limit" in result.stdout
    assert "bomc: build incomplete (time_limit)" in result.stderr and "partial map was saved" in result.stderr
