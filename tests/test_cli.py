"""The command line: exit codes and one-line errors for a user's mistakes (CONTRACTS 2)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def bomc(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "bomc_bt.cli", *args], capture_output=True, text=True,
                          cwd=cwd or REPO, env=env, timeout=300)


def assert_user_error(result: subprocess.CompletedProcess, *fragments: str) -> None:
    assert result.returncode == 2, (result.returncode, result.stdout, result.stderr)
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("bomc: error:")]
    assert len(lines) == 1, result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_missing_world_file(tmp_path):
    assert_user_error(bomc("build", "--world", str(tmp_path / "nope.yaml"), "--site", str(tmp_path / "s")),
                      "nope.yaml", "not found")


def test_malformed_world_names_the_entry(tmp_path, shared):
    world = tmp_path / "w.yaml"
    world.write_text(f"version: 1\nmap: {shared / 'worlds' / 'lab-b-map.yaml'}\nstart: [4.5, 6.5, 0]\n"
                     "objects:\n  - {name: c, category: chair, position: [1, 2], size: [1, 1, 1]}\n")
    assert_user_error(bomc("build", "--world", str(world), "--site", str(tmp_path / "s")),
                      "w.yaml", "objects[0].position")


def test_bad_config_key(tmp_path, shared):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("exploration: {alpah: 1}\n")
    assert_user_error(bomc("build", "--world", str(shared / "worlds" / "lab-b.yaml"), "--site", str(tmp_path / "s"),
                           "--config", str(cfg)), "c.yaml", "exploration.alpah")


def test_unknown_behaviour_in_a_tree(tmp_path, shared):
    tree = tmp_path / "t.yaml"
    tree.write_text("version: 1\nroot: {behaviour: SaveMapp}\n")
    assert_user_error(bomc("build", "--world", str(shared / "worlds" / "lab-b.yaml"), "--site", str(tmp_path / "s"),
                           "--tree", str(tree)), "t.yaml", "SaveMapp")


def test_monitor_without_a_build(tmp_path, shared):
    assert_user_error(bomc("monitor", "--world", str(shared / "worlds" / "lab-b.yaml"), "--site", str(tmp_path),
                           "--session", "1"), "map.yaml", "bomc build")


def test_corrupt_store_is_reported_and_left_alone(tmp_path, shared):
    world = str(shared / "worlds" / "lab-b.yaml")
    # cut short by --max-time: exit 1 (incomplete), but the map and the store are written
    assert bomc("build", "--world", world, "--site", str(tmp_path), "--quiet", "--max-time", "10").returncode == 1
    (tmp_path / "site.db").write_bytes(b"this is not a database" * 100)
    result = bomc("monitor", "--world", world, "--site", str(tmp_path), "--session", "1", "--quiet")
    assert_user_error(result, "site.db")
    assert (tmp_path / "site.db").read_bytes() == b"this is not a database" * 100
    assert (tmp_path / "map.yaml").exists()


def test_a_rotated_map_origin_is_refused_with_what_to_do(tmp_path):
    # MIT's Stata basement map (racecar_simulator) ships with origin yaw 3.14
    (tmp_path / "m.pgm").write_bytes(b"P5\n10 10\n255\n" + b"\xfe" * 100)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [25.9, 48.5, 3.14]\n")
    result = bomc("world", "map", "--map", str(tmp_path / "m.yaml"), "--out", str(tmp_path / "w.yaml"))
    assert_user_error(result, "m.yaml", "origin", "yaw 3.14", "set it to 0")
    assert not (tmp_path / "w.yaml").exists()


def test_argument_errors_exit_2():
    result = bomc("build")
    assert result.returncode == 2 and "Traceback" not in result.stderr


@pytest.mark.parametrize("image", [b"", b"P5\n10 10\n255\n" + b"\x00" * 5])
def test_broken_map_image(tmp_path, image):
    (tmp_path / "m.pgm").write_bytes(image)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    (tmp_path / "w.yaml").write_text("version: 1\nmap: m.yaml\nstart: [0.2, 0.2, 0]\n")
    assert_user_error(bomc("build", "--world", str(tmp_path / "w.yaml"), "--site", str(tmp_path / "s")), "m.yaml")
