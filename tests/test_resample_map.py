"""benchmarks/resample_map.py: a map at another resolution keeps its walls shut."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bomc_bt.grid import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, load_map, save_map
from tests.benchmark_scripts import load


def _module():
    return load("resample_map")


def _room() -> OccupancyGrid:
    """4 x 2 m at 0.05 m: free inside, a one-cell wall across at x = 2.0 m, unknown round it."""
    data = np.full((40, 80), FREE, np.int8)
    data[:, 40] = OCCUPIED
    data[:, :2] = data[:, -2:] = UNKNOWN
    return OccupancyGrid(data, 0.05, (1.0, -3.0))


def test_coarser_cells_keep_a_one_cell_wall_shut_and_the_same_extent():
    out = _module().resample(_room(), 0.1)
    assert out.data.shape == (20, 40) and out.origin == (1.0, -3.0)
    assert (out.data[:, 20] == OCCUPIED).all()  # the wall at x = 2.0 m is still a full line
    assert (out.data[:, 0] == UNKNOWN).all() and (out.data[:, 10] == FREE).all()


def test_finer_cells_repeat_the_cell_they_lie_in(tmp_path):
    room = _room()
    assert _module().main([_save(room, tmp_path), "--resolution", "0.025", "--out", str(tmp_path / "fine.yaml")]) == 0
    fine = load_map(tmp_path / "fine.yaml")
    assert fine.data.shape == (80, 160) and fine.resolution == 0.025
    assert np.array_equal(fine.data[::2, ::2], room.data)


def test_a_resolution_out_of_range_is_one_line_and_exit_2(tmp_path, capsys):
    path = _save(_room(), tmp_path)
    assert _module().main([path, "--resolution", "5", "--out", str(tmp_path / "x.yaml")]) == 2
    assert "--resolution" in capsys.readouterr().err and not (tmp_path / "x.yaml").exists()


def _save(grid: OccupancyGrid, tmp_path: Path) -> str:
    save_map(grid, tmp_path / "room.yaml")
    return str(tmp_path / "room.yaml")


def test_the_source_map_and_an_existing_copy_are_never_overwritten_without_force(tmp_path, capsys):
    source = _save(_room(), tmp_path)
    before = (tmp_path / "room.pgm").read_bytes()
    assert _module().main([source, "--resolution", "0.1", "--out", source]) == 2
    assert _module().main([source, "--resolution", "0.1", "--out", str(tmp_path / "room.yml")]) == 2  # its PGM
    assert (tmp_path / "room.pgm").read_bytes() == before
    out = str(tmp_path / "coarse.yaml")
    assert _module().main([source, "--resolution", "0.1", "--out", out]) == 0
    assert _module().main([source, "--resolution", "0.2", "--out", out]) == 2
    assert load_map(out).resolution == 0.1  # the first copy stands
    assert _module().main([source, "--resolution", "0.2", "--out", out, "--force"]) == 0
    assert load_map(out).resolution == 0.2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "source map" in err[0] and "source map" in err[1] and "--force" in err[2]
