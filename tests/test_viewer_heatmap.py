"""The change model's heat map in the site viewer (issue 20): /api/change_model and the red
overlay that ``static/heatmap.js`` draws over the map, checked on the canvas's pixels in
a real headless Chromium (tests/browser.py)."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import numpy as np
from browser import Browser

from bomc_bt.grid import OccupancyGrid, save_map
from bomc_bt.site import write_json
from bomc_bt.store import SiteStore
from bomc_bt.viewer import serve_site

RES, ORIGIN = 0.05, (0.0, 0.0)
HOT, COLD, SKIPPED = (2.0, 2.0), (10.0, 2.0), (6.0, 6.0)  # region centres (4 m squares from the origin)
FREE_GREY = 254  # map.png's free cell


def region_rows(session: int, changes: dict, skipped: tuple = ()) -> list[tuple]:
    """A 12 x 8 m floor: 2 x 3 regions of 4 m; ``changes`` found per region (i, j)."""
    return [(session, 4.0, i, j, 0.0 if (i, j) in skipped else 1.0, changes.get((i, j), 0), 100.0 * session)
            for i in range(2) for j in range(3)]


def make_site(root: Path) -> Path:
    """Three passes: region (0, 0) changes at every pass, the rest never; pass 3 had a budget
    and skipped region (1, 1)."""
    save_map(OccupancyGrid(np.zeros((160, 240), dtype=np.int8), RES, ORIGIN), root / "map.yaml")
    (root / "trajectory.csv").write_text("t,x,y,yaw\n0,1,1,0\n1,2,1,0\n")
    write_json(root / "build.json", {"explored_area": 96.0, "path_length": 1.0, "reason": "done"})
    with SiteStore(root) as store:
        for n in (1, 2, 3):
            store.begin_session(n, {"stamp": 100.0 * n})
            budget = {"seconds": 60.0, "full_pass": False, "skipped_regions": [
                {"x": SKIPPED[0], "y": SKIPPED[1], "last_seen": 2, "passes_since_seen": 2, "expected_waiting": 0.3}]}
            report = {"stamp": 100.0 * n + 50, **({"budget": budget} if n == 3 else {})}
            skipped = ((1, 1),) if n == 3 else ()
            store.end_session(n, "completed", report, region_rows(n, {(0, 0): 3} if n > 1 else {}, skipped))
    return root


def test_the_api_gives_each_regions_waiting_changes_and_the_regions_a_budgeted_pass_skipped(tmp_path):
    server = serve_site(make_site(tmp_path), port=0)
    try:
        with urllib.request.urlopen(server.url + "api/change_model", timeout=10) as reply:
            data = json.load(reply)
    finally:
        server.close()
    by_region = {(r["i"], r["j"]): r for r in data["regions"]}
    hot, cold = by_region[(0, 0)], by_region[(0, 2)]
    assert abs(hot["x"] - HOT[0]) < 0.1 and abs(cold["x"] - COLD[0]) < 0.1 and data["size_m"] == 4.0
    assert hot["waiting"] == data["max_waiting"] > 5 * cold["waiting"] > 0
    assert data["session"] == 4 and list(data["skipped"]) == ["3"]
    assert data["skipped"]["3"][0]["x"] == SKIPPED[0]


def pixel(b: Browser, xy: tuple[float, float]) -> list[int]:
    return b.evaluate(f"bomcViewer.pixelAtWorld({xy[0]}, {xy[1]})")


def test_the_heat_map_is_red_where_changes_wait_once_turned_on_and_goes_away_when_turned_off(browser, tmp_path):
    server = serve_site(make_site(tmp_path), port=0)
    try:
        browser.open(server.url + "?session=3")
        browser.wait_for("!!document.getElementById('heatmap-toggle') && !!bomcViewer.state.map.img",
                         what="the heat map and the map loaded")
        assert pixel(browser, HOT)[:3] == [FREE_GREY] * 3  # off at first: the plain map
        browser.evaluate("document.getElementById('heatmap-toggle').click()")
        browser.evaluate("window.dispatchEvent(new Event('resize'))")  # one more draw with both
        hot, cold, plain = pixel(browser, HOT), pixel(browser, COLD), pixel(browser, (2.0, 6.0))
        assert hot[0] > 200 and hot[1] < 150 and hot[2] < 150, hot  # strong red over the white floor
        assert cold[0] > cold[1] + 5 and cold[1] > hot[1] + 60, (cold, hot)  # a faint tint only
        assert plain[1] > hot[1] + 60, plain
        # the region session 3 skipped: outlined (dashed), its inside only tinted
        k = browser.evaluate("bomcViewer.state.view.k")
        edge_y = SKIPPED[1] - 2.0 + 0.5 / k  # half a pixel inside the square's lower edge
        edge = [pixel(browser, (SKIPPED[0] + dx, edge_y)) for dx in np.linspace(-1.5, 1.5, 13)]
        assert any(p[0] < 150 and p[2] > 100 for p in edge), edge  # purple dashes somewhere on the edge
        browser.screenshot(Path(__file__).resolve().parents[1] / "artifacts" / "viewer_heatmap.png")
        browser.evaluate("document.getElementById('heatmap-toggle').click()")
        off = pixel(browser, HOT)
        assert off[:3] == [FREE_GREY] * 3, off
        assert browser.errors == []
    finally:
        server.close()
