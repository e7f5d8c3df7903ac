"""Viewer fixes seen while watching a pass in Chromium (issue 19, item 5), in headless Chromium.

* the connection badge of a mission (or a ``bomc view``) that ended is grey "mission ended"
  / "viewer stopped", not a red "reconnecting..." for ever;
* a 10-level tree reads at a glance: one line per node, long feedback cut with an ellipsis
  and whole on hover (``title``).

Screenshots are checked for what they show (the badge's colour, the running node's dot).
"""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import pytest
from browser import Browser

from bomc_bt.viewer import Server, StateStore

ARTIFACTS = Path(__file__).resolve().parents[1] / "artifacts"
LONG = ("waypoint 7/31: detour via (12.40, 3.10) after 2 failed goals; " * 4).strip()


def deep_tree(levels: int) -> dict:
    node = {"name": f"Leaf {levels}", "kind": "behaviour", "type": "Navigate", "status": "running",
            "feedback": LONG, "children": []}
    for depth in range(levels - 1, 0, -1):
        node = {"name": f"Level {depth}", "kind": "sequence", "type": "Sequence", "status": "running",
                "feedback": f"child {depth + 1} running", "children": [node]}
    return node


def centre_pixel(b: Browser, shot: Path, selector: str, inset: float | None = None) -> list[int]:
    """The screenshot's colour (RGB) in the first element matching ``selector``: at its middle,
    or ``inset`` pixels in from its left edge (beside a label's text)."""
    x = "r.left + r.width / 2" if inset is None else f"r.left + {inset}"
    rect = b.evaluate(f"(() => {{ const r = document.querySelector({selector!r}).getBoundingClientRect(); "
                      f"return [{x}, r.top + r.height / 2]; }})()")
    img = cv2.imread(str(shot))
    bgr = img[round(rect[1]), round(rect[0])]
    return [int(bgr[2]), int(bgr[1]), int(bgr[0])]


@pytest.mark.parametrize("mode, words", [("live", "mission ended"), ("site", "viewer stopped")])
def test_the_badge_of_an_ended_mission_is_grey_not_reconnecting(browser, mode, words):
    server = Server(StateStore(), port=0).start()
    server.state.update({"mode": mode, "tree": deep_tree(2)})
    browser.open(server.url)
    browser.wait_for("document.body.dataset.connected === 'yes'", what="connected")
    server.close()
    browser.wait_for("document.body.dataset.connected === 'ended'", what="the end of the mission")
    time.sleep(2.5)  # EventSource retries (every second) and fails: the page still says it ended
    assert browser.evaluate("document.body.dataset.connected") == "ended"
    assert browser.evaluate("document.querySelector('#conn').textContent") == words
    shot = browser.screenshot(ARTIFACTS / f"viewer_ended_{mode}.png")
    badge = centre_pixel(browser, shot, "#conn", inset=3)
    assert all(abs(v - c) < 20 for v, c in zip(badge, (0x6B, 0x72, 0x80), strict=True)), badge  # grey, not red
    assert browser.errors == []


def test_a_ten_level_tree_is_one_line_per_node_with_the_whole_message_on_hover(browser):
    with Server(StateStore(), port=0) as server:
        server.state.update({"mode": "live", "tree": deep_tree(10)})
        browser.open(server.url)
        browser.wait_for("document.querySelectorAll('#tree .node').length === 10", what="the tree")
        rows = browser.evaluate("Array.from(document.querySelectorAll('#tree .row')).map(r => r.offsetHeight)")
        line = browser.evaluate("parseFloat(getComputedStyle(document.querySelector('#tree .row')).lineHeight)")
        assert len(rows) == 10 and max(rows) < 1.6 * line, (rows, line)
        fb = "document.querySelector('#tree [data-name=\"Leaf 10\"] .fb')"
        assert browser.evaluate(f"{fb}.title") == LONG
        assert browser.evaluate(f"{fb}.scrollWidth > {fb}.clientWidth")  # cut, with an ellipsis
        assert browser.evaluate(f"getComputedStyle({fb}).textOverflow") == "ellipsis"
        shot = browser.screenshot(ARTIFACTS / "viewer_deep_tree.png")
        dot = centre_pixel(browser, shot, '#tree [data-name="Leaf 10"] .dot')
        assert abs(dot[0] - 0x2F) < 30 and abs(dot[1] - 0x6F) < 30 and abs(dot[2] - 0xD6) < 30, dot  # running blue
        # collapsible: one click folds the nine levels below the root
        browser.evaluate("document.querySelector('#tree .toggle').click()")
        browser.wait_for("document.querySelector('#tree [data-name=\"Leaf 10\"]').offsetParent === null",
                         what="the tree folded")
        assert browser.errors == []
