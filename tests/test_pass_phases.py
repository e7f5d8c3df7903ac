"""benchmarks/pass_phases.py: a pass's path and robot time per phase, from its timeline."""

from __future__ import annotations

import json
from pathlib import Path

from tests.benchmark_scripts import load


def _module():
    return load("pass_phases")


def _timeline(path: Path) -> Path:
    """Drive 3 m east in the coverage tour, turn on the spot for 4 s, then 1 m north to a gap viewpoint."""
    names = [["Visit Waypoints"], ["Look Around"], ["Visit Gap Viewpoints"]]
    recs = [{"k": "tree", "n": names},
            {"k": "st", "c": [[0, "r", 0]]},
            {"k": "pose", "t": 0.0, "p": [0.0, 0.0, 0.0]},
            {"k": "pose", "t": 5.0, "p": [3.0, 0.0, 0.0]},
            {"k": "st", "c": [[1, "r", 0]]},
            {"k": "pose", "t": 9.0, "p": [3.0, 0.0, 1.5]},
            {"k": "st", "c": [[1, "s", 0], [2, "r", 0]]},
            {"k": "pose", "t": 11.0, "p": [3.0, 1.0, 1.5]}]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(json.dumps(r) + "\n" for r in recs))
    return path


def test_each_step_counts_for_the_phase_running_at_its_tick(tmp_path):
    rows = _module().phases(_timeline(tmp_path / "timeline.jsonl"))
    assert rows["Visit Waypoints"] == [3.0, 5.0]
    assert rows["Look Around"] == [0.0, 4.0]
    assert rows["Visit Gap Viewpoints"] == [1.0, 2.0]


def test_a_site_folder_stands_for_its_sessions_in_order(tmp_path, capsys):
    for n in (10, 2, 1):
        _timeline(tmp_path / "site" / "sessions" / str(n) / "timeline.jsonl")
    assert _module().main([str(tmp_path / "site")]) == 0
    lines = capsys.readouterr().out.splitlines()
    sessions = [line.split("/timeline.jsonl")[0].rsplit("/", 1)[-1] for line in lines[1:]]
    assert sessions == ["1"] * 3 + ["2"] * 3 + ["10"] * 3


def test_a_path_that_is_neither_a_timeline_nor_a_site_is_one_line_and_exit_2(tmp_path, capsys):
    assert _module().main([str(tmp_path / "missing.jsonl")]) == 2
    assert _module().main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "missing.jsonl" in err[0] and "no sessions" in err[1]
