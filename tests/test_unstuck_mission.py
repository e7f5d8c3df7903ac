"""A monitor pass boxed in behind an object placed after the map was built ends early, with why.

Hand-made floor (18 x 3 m, a doorway at x = 3 m): the saved map has the
doorway open; in session 2 an unlabelled obstacle closes it. The robot starts in the left
room; every waypoint in the right room fails. Before the recovery, each was retried,
detoured and missed in turn; now the pass diagnoses ``boxed_in``, clears the obstacle
layer and backs out, and after ``recovery.max_rounds`` rounds ends early: outcome
``ended_early``, the diagnosis in the report and on the CLI line, exit status 1.
"""

from __future__ import annotations

import json

import numpy as np
import yaml

from bomc_bt.cli import main
from bomc_bt.grid import OccupancyGrid, save_map

RES = 0.05


def two_rooms() -> OccupancyGrid:
    """18 x 3 m inside walls; a wall across at x = 3 m with a 1.2 m doorway (y 0.9 to 2.1):
    a small room where the robot starts, and a long one beyond the doorway."""
    h, w = int(3.2 / RES), int(18.2 / RES)
    data = np.zeros((h, w), np.int8)
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = 100
    col = int(3.1 / RES)
    data[:, col - 1:col + 1] = 100
    data[int(1.0 / RES):int(2.2 / RES), col - 1:col + 1] = 0
    return OccupancyGrid(data, RES, (-0.1, -0.1))


def make_site(tmp_path):
    world_map = tmp_path / "floor.yaml"
    save_map(two_rooms(), world_map)
    world = tmp_path / "world.yaml"
    world.write_text(yaml.safe_dump({
        "version": 1, "name": "two-rooms", "map": "floor.yaml", "start": [1.2, 1.5, 0.0],
        "objects": [],
        "sessions": {2: {"obstacles": [{"position": [3.0, 1.55], "size": [0.6, 1.5], "height": 1.0}]}},
    }))
    site = tmp_path / "site"
    site.mkdir()
    save_map(two_rooms(), site / "map.yaml")  # the map as built: the doorway open
    (site / "trajectory.csv").write_text("t,x,y,yaw\n" + "".join(
        f"{i},{1.2 + 0.5 * i:.2f},1.5,0.0\n" for i in range(33)))
    return world, site


def test_a_pass_boxed_in_behind_a_new_obstacle_ends_early_with_the_diagnosis(tmp_path, capsys):
    world, site = make_site(tmp_path)
    # The plan's two waypoints beyond the doorway fail first; with the default (3 in a row)
    # the round starts only among the gap viewpoints, 300 s of robot time later: the same
    # logic, twice the CI time.
    config = tmp_path / "recovery.yaml"
    config.write_text("recovery: {max_missed: 2}\n")
    code = main(["monitor", "--world", str(world), "--site", str(site), "--session", "2", "--quiet",
                 "--config", str(config)])
    line = capsys.readouterr().out.strip().splitlines()[-1]
    report = json.loads((site / "sessions" / "2" / "report.json").read_text())
    assert code == 1, line
    assert report["outcome"] == "ended_early"
    assert "boxed_in" in report["reason"] and "recovery round" in report["reason"]
    assert line.startswith("session 2 ended_early") and "boxed in by objects the map does not have" in line
    rounds = report["recoveries"]
    assert [r["cause"] for r in rounds][-1] == "boxed_in"
    assert any("back_out" in r["action"] for r in rounds) and any("clear_obstacles" in r["action"] for r in rounds)
    assert rounds[-1]["result"] == "nowhere to back out to"  # it started next to the wall: no way back
    assert report["traversal"]["visited"] >= 1  # the small room was seen
    md = (site / "sessions" / "2" / "report.md").read_text()
    assert "ended_early" in md and "boxed in" in md
