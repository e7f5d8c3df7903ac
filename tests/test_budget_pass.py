"""``bomc monitor --budget`` end to end on a tiny generated office: bad budgets are refused
before anything is written, a budgeted pass stays within its robot time, ends at the dock,
reports the regions it skipped, and the viewer serves the change model as JSON."""

from __future__ import annotations

import hashlib
import json
import shutil
import urllib.request
from pathlib import Path

import pytest
from test_cli import assert_user_error, bomc

from bomc_bt.budget_pass import MAX_SHORTLIST, budget_outgrows_shortlist
from bomc_bt.viewer.server import serve_site


def digest(folder: Path) -> str:
    h = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h.update(str(path.relative_to(folder)).encode() + path.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def mapped_site(tmp_path_factory) -> tuple[Path, Path]:
    """A 14 x 12 m office with hot rooms, built and mapped by one full pass (session 1)."""
    root = tmp_path_factory.mktemp("budget")
    world, site = root / "office.yaml", root / "site"
    for args in (("world", "office", "--out", str(world), "--size", "14x12", "--seed", "2", "--sessions", "3",
                  "--hot-rooms", "0.3"),
                 ("build", "--world", str(world), "--site", str(site), "--quiet"),
                 ("monitor", "--world", str(world), "--site", str(site), "--session", "1", "--quiet")):
        result = bomc(*args)
        assert result.returncode == 0, result.stderr
    return world, site


@pytest.mark.parametrize("value", ["abc", "0", "-5", "nan", "inf", "1e9"])
def test_a_bad_budget_is_one_line_exit_2_and_nothing_saved_changes(mapped_site, value):
    world, site = mapped_site
    before = digest(site)
    result = bomc("monitor", "--world", str(world), "--site", str(site), "--session", "2", "--budget", value)
    assert_user_error(result, "--budget")
    assert digest(site) == before


def test_a_budgeted_pass_keeps_its_budget_comes_home_and_reports_what_it_skipped(mapped_site):
    world, site = mapped_site
    full = json.loads((site / "sessions" / "1" / "report.json").read_text())
    budget = round(0.3 * full["sim_time_s"], 1)
    result = bomc("monitor", "--world", str(world), "--site", str(site), "--session", "2", "--quiet",
                  "--budget", str(budget))
    assert result.returncode == 0, result.stderr
    report = json.loads((site / "sessions" / "2" / "report.json").read_text())
    assert report["sim_time_s"] <= budget
    # and spent, not left half unused: a plan that reckoned 4.5 s per heading came home after
    # 20 of 40 s. Since headings are turned through in the order that turns least, this
    # pass plans 2 stops in 27.7 s and drives them in 22.8 of its 38.5 s (0.59).
    assert report["sim_time_s"] >= 0.55 * budget
    b = report["budget"]
    assert b["seconds"] == budget and not b["full_pass"] and 0 < b["stops"] < b["stops_total"]
    assert b["regions"] > 0 and b["skipped_regions"], "a 30 % pass leaves regions unseen"
    assert all(r["passes_since_seen"] >= 1 for r in b["skipped_regions"])
    assert report["coverage"]["fraction"] < full["coverage"]["fraction"]
    plan = json.loads((site / "plan.json").read_text())
    dock = plan["waypoints"][-1]
    assert report["traversal"]["visited"] >= 1
    assert "regions not seen" in (site / "sessions" / "2" / "report.md").read_text()
    assert abs(dock[0]) < 50  # the plan ends at the dock (the world's start)

    with serve_site(site, port=0) as server, urllib.request.urlopen(
            f"http://127.0.0.1:{server.port}/api/change_model", timeout=10) as reply:
        model = json.loads(reply.read())
    assert model["session"] == 3 and model["regions"]
    stale = {(r["x"], r["y"]) for r in b["skipped_regions"]}
    waits = {(r["x"], r["y"]): r for r in model["regions"]}
    assert all(waits[xy]["passes_since"] >= 2 for xy in stale if xy in waits)
    assert model["max_waiting"] > 0


def test_a_budget_that_affords_more_than_max_stops_places_is_planned_over_more(mapped_site, tmp_path):
    """budget.max_stops is where the tour starts, not a ceiling on what a long budget buys:
    on a 93 x 90 m floor a budget as long as the build stopped after 60 stops, 38 % of it."""
    world, site = mapped_site
    copy = tmp_path / "site"
    shutil.copytree(site, copy)
    session = max(int(p.name) for p in (copy / "sessions").iterdir()) + 1
    full = json.loads((site / "sessions" / "1" / "report.json").read_text())
    few = tmp_path / "few.yaml"
    few.write_text("budget:\n  max_stops: 1\n")
    result = bomc("monitor", "--world", str(world), "--site", str(copy), "--session", str(session), "--quiet",
                  "--config", str(few), "--budget", str(round(0.8 * full["sim_time_s"], 1)))
    assert result.returncode == 0, result.stderr
    b = json.loads((copy / "sessions" / str(session) / "report.json").read_text())["budget"]
    assert not b["full_pass"]
    assert b["stops_total"] > 1 and b["stops"] > 1, b


def test_the_shortlist_grows_only_when_the_tour_exhausts_it_with_time_to_spare():
    assert budget_outgrows_shortlist(60, 60, 60, planned_s=2866.0, available_s=5644.0)
    assert not budget_outgrows_shortlist(59, 60, 60, planned_s=2767.0, available_s=5644.0)  # a place left out
    assert not budget_outgrows_shortlist(60, 60, 60, planned_s=5500.0, available_s=5644.0)  # the budget is spent
    assert not budget_outgrows_shortlist(40, 40, 60, planned_s=100.0, available_s=5644.0)  # nothing more to see
    assert not budget_outgrows_shortlist(MAX_SHORTLIST, MAX_SHORTLIST, MAX_SHORTLIST, 1.0, 1e6)
