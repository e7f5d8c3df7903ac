"""Replay and corrections in ``bomc view`` (issue 19, items 3 and 4), in headless Chromium.

A real pass on a generated office leaves its timeline; the page is scrubbed to moments
picked from the file (read with ``json`` here, not with the viewer's reader) and must
show the robot where the file has it, that frame's detections (list, camera boxes and
their points on the map) and the tree's statuses at that moment; the screenshot is
checked for the robot's red at its place. A relabel from the page must land in the
site's history as an operator event and in ``bomc objects``; bad input, a request from
another page and a second writer holding the site lock change no byte of the site.
"""

from __future__ import annotations

import http.client
import json
import math
import shutil
import time
from pathlib import Path
from types import SimpleNamespace

import cv2
import pytest
from browser import Browser
from replay_site import make_replay_site, status_at, timeline_records
from site_files import bomc, snapshot

import bomc_bt.viewer.server as viewer_server
from bomc_bt.site_lock import SiteLock
from bomc_bt.store import SiteStore
from bomc_bt.viewer import serve_site
from bomc_bt.viewer.sections import category_hex

ARTIFACTS = Path(__file__).resolve().parents[1] / "artifacts"
ROBOT_RED = [0xE0, 0x20, 0x3A]
STATUS = {"s": "success", "f": "failure", "r": "running", "i": "invalid"}


@pytest.fixture(scope="module")
def office(tmp_path_factory):
    return make_replay_site(tmp_path_factory.mktemp("replay"))


def rgb(hex_colour: str) -> list[int]:
    return [int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)]


def close_to(pixel: list[int] | None, colour: list[int], tol: int = 14) -> bool:
    return pixel is not None and all(abs(p - c) <= tol for p, c in zip(pixel[:3], colour, strict=True))


def pixel(b: Browser, x: float, y: float, dx_px: float = 0.0) -> list[int]:
    return b.evaluate(f"bomcViewer.pixelAtWorld({x} + {dx_px} / bomcViewer.state.view.k, {y})")


def scrub(b: Browser, t: float) -> None:
    b.evaluate(f"(() => {{ const s = document.querySelector('#replay-t'); s.value = '{t}'; "
               "s.dispatchEvent(new Event('input')); })()")
    b.wait_for(f"document.querySelector('#replay').dataset.t === String({t})", what=f"the moment {t}")


def moment_with_detections(records: list[dict], after: float = 0.0) -> tuple[dict, list[float]]:
    """A frame with detections and map points at a localized moment, and the pose then."""
    poses = [r for r in records if r["k"] == "pose"]
    for f in (r for r in records if r["k"] == "frame"):
        before = [p for p in poses if p["t"] <= f["t"]]
        if f["t"] > after and f["d"] and f["o"] and before and before[-1]["p"]:
            return f, before[-1]["p"]
    raise AssertionError("no frame with detections in the pass")


def screen_pixel(b: Browser, shot: Path, x: float, y: float) -> list[int]:
    """The screenshot's colour (RGB) at the map's world point (x, y)."""
    at = b.evaluate(f"(() => {{ const r = document.querySelector('#map').getBoundingClientRect(); "
                    f"const p = bomcViewer.toCanvas(bomcViewer.state.view, {x}, {y}); "
                    "return [r.left + p[0], r.top + p[1]]; })()")
    bgr = cv2.imread(str(shot))[round(at[1]), round(at[0])]
    return [int(bgr[2]), int(bgr[1]), int(bgr[0])]


# ----------------------------------------------------------------------- replay
def test_scrubbing_shows_the_pose_detections_and_tree_of_that_moment(browser, office):
    records = timeline_records(office["site"], 1)
    frame, pose = moment_with_detections(records, after=20.0)
    t = frame["t"]
    server = serve_site(office["site"], port=0)
    try:
        browser.open(server.url)
        browser.wait_for("document.querySelector('#replay').dataset.ready === '1'", what="the timeline")
        assert not close_to(pixel(browser, pose[0], pose[1]), ROBOT_RED)  # the final map has no robot
        scrub(browser, t)
        assert browser.evaluate("document.querySelector('#replay-time').textContent").startswith(f"t = {t:.1f} s")
        # the robot where the file has it
        assert close_to(pixel(browser, pose[0], pose[1]), ROBOT_RED), pixel(browser, pose[0], pose[1])
        # that frame's detections: listed, boxed in the camera view, their points marked on the map
        listed = browser.evaluate("Array.from(document.querySelectorAll('#replay-detections li.det'))"
                                  ".map(li => [li.dataset.category, +li.dataset.score])")
        assert listed == [[d[0], d[5]] for d in frame["d"]]
        assert browser.evaluate("document.querySelector('#replay-camera').dataset.frame") == str(frame["n"])
        w, h = frame["wh"]
        k = min(240 / w, 150 / h)
        for cat, x0, y0, x1, y1, _ in frame["d"]:
            others = [d for d in frame["d"] if d[1] <= x0 + 2 and d[3] >= x0 - 2 and d[1:5] != [x0, y0, x1, y1]]
            if others:
                continue  # another box covers this edge
            px, py = (240 - w * k) / 2 + x0 * k, (150 - h * k) / 2 + (y0 + y1) / 2 * k
            edge = browser.evaluate(f"Array.from(document.querySelector('#replay-camera').getContext('2d')"
                                    f".getImageData({round(px)}, {round(py)}, 1, 1).data)")
            assert close_to(edge, rgb(category_hex(cat)), tol=40), (cat, edge)
        cat, ox, oy = frame["o"][0]
        assert close_to(pixel(browser, ox, oy, dx_px=7), rgb(category_hex(cat)), tol=30)
        # the tree as it stood then
        shown = browser.evaluate("Array.from(document.querySelectorAll('#replay-tree .node'))"
                                 ".map(n => n.dataset.status)")
        assert shown == [STATUS[s] for s in status_at(records, t)]
        assert "running" in shown
        shot = browser.screenshot(ARTIFACTS / "viewer_replay_moment.png")
        assert close_to(screen_pixel(browser, shot, pose[0], pose[1]), ROBOT_RED)
        # another moment: the robot is elsewhere, and only there
        later, pose2 = moment_with_detections(records, after=t + 20.0)
        assert math.dist(pose[:2], pose2[:2]) > 1.0
        scrub(browser, later["t"])
        assert close_to(pixel(browser, pose2[0], pose2[1]), ROBOT_RED)
        assert not close_to(pixel(browser, pose[0], pose[1]), ROBOT_RED)
        # play: robot time goes on by itself; "final map" ends the replay
        browser.evaluate("document.querySelector('#replay-speed').value = '100'; "
                         "document.querySelector('#replay-play').click()")
        browser.wait_for(f"bomcReplay.state.t > {later['t'] + 5}", what="playback")
        browser.evaluate("document.querySelector('#replay-play').click()")
        browser.evaluate("document.querySelector('#replay-exit').click()")
        assert not close_to(pixel(browser, pose2[0], pose2[1]), ROBOT_RED)
        assert browser.errors == []
    finally:
        server.close()


def test_a_session_without_a_timeline_says_so(browser, office, tmp_path):
    site = shutil.copytree(office["site"], tmp_path / "site")
    (site / "sessions" / "1" / "timeline.jsonl").unlink()
    server = serve_site(site, port=0)
    try:
        browser.open(server.url)
        browser.wait_for("document.querySelector('#replay-time').textContent.includes('no timeline recorded')",
                         what="the missing timeline said")
        assert browser.evaluate("document.querySelector('#replay-t').disabled") is True
        assert browser.errors == []
    finally:
        server.close()


def test_extensions_that_load_after_the_site_data_still_show_it(browser, office, tmp_path, monkeypatch):
    """replay.js and corrections.js arriving after the site's data (a slow disk, a busy server)."""
    real, delayed = viewer_server.mimetypes.guess_type, []

    def slow_extensions(name: str, *args, **kwargs):
        if name in ("replay.js", "corrections.js"):
            time.sleep(1.5)
            delayed.append(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(viewer_server, "mimetypes", SimpleNamespace(guess_type=slow_extensions))
    site = shutil.copytree(office["site"], tmp_path / "site")
    server = serve_site(site, port=0)
    try:
        browser.open(server.url)
        browser.wait_for("document.querySelector('#replay').dataset.ready === '1'", what="the timeline")
        browser.wait_for("document.querySelector('#corrections').dataset.available === 'yes' && "
                         "document.querySelectorAll('#edit-node option').length > 0", what="the corrections form")
        assert browser.errors == []
        assert sorted(delayed) == ["corrections.js", "replay.js"]  # the race this test is about did happen
    finally:
        server.close()


# ------------------------------------------------------------------ corrections
def present_node(site: Path):
    with SiteStore(site, readonly=True) as store:
        return sorted(store.nodes(), key=lambda n: n.id)[0]


def apply_edit(b: Browser, node_id: int, action: str, value: str = "") -> tuple[str, str]:
    b.evaluate("document.querySelector('#edit-result').dataset.state = ''")
    b.evaluate(f"(() => {{ document.querySelector('#edit-node').value = '{node_id}'; "
               f"const a = document.querySelector('#edit-action'); a.value = '{action}'; "
               "a.dispatchEvent(new Event('change')); "
               f"document.querySelector('#edit-value').value = {json.dumps(value)}; "
               "document.querySelector('#edit-apply').click(); })()")
    state = b.wait_for("document.querySelector('#edit-result').dataset.state", what=f"the {action} answer")
    return state, b.evaluate("document.querySelector('#edit-result').textContent")


def test_a_relabel_from_the_viewer_is_an_operator_event_and_bomc_objects_shows_it(browser, office, tmp_path):
    site = shutil.copytree(office["site"], tmp_path / "site")
    node = present_node(site)
    x, y = float(node.position[0]), float(node.position[1])
    server = serve_site(site, port=0)
    try:
        browser.open(server.url)
        browser.wait_for("document.querySelector('#corrections').dataset.available === 'yes' && "
                         "document.querySelectorAll('#edit-node option').length > 0", what="the corrections form")
        assert close_to(pixel(browser, x, y), rgb(category_hex(node.category)))
        before = snapshot(site)
        # bad input and a second writer: refused, in the page, and the site unchanged
        state, text = apply_edit(browser, node.id, "relabel", "")
        assert state == "error" and "non-empty CATEGORY" in text
        with SiteLock.acquire(site, "monitor"):
            state, text = apply_edit(browser, node.id, "delete")
        assert state == "error" and "another writer holds this site" in text
        assert snapshot(site) == before
        # the relabel: the page, the history, bomc objects
        state, text = apply_edit(browser, node.id, "relabel", "filing cabinet")
        assert state == "done" and "'filing cabinet'" in text, text
        browser.wait_for(f"!!document.querySelector('#edit-history li[data-kind=relabelled][data-id=\"{node.id}\"]')",
                         what="the relabel in the history list")
        browser.wait_for(f"(() => {{ const p = bomcViewer.pixelAtWorld({x}, {y}); const c = "
                         f"{rgb(category_hex('filing cabinet'))}; return p && p.slice(0, 3).every((v, i) => "
                         "Math.abs(v - c[i]) <= 14); })()", what="the node drawn in its new colour")
        shot = browser.screenshot(ARTIFACTS / "viewer_relabelled.png")
        assert close_to(screen_pixel(browser, shot, x, y), rgb(category_hex("filing cabinet")))
        with SiteStore(site, readonly=True) as store:
            last = store.events(operator=True)[-1]
        assert (last.kind, last.node_id, last.category) == ("relabelled", node.id, "filing cabinet")
        assert last.detail["by"] == "operator" and last.detail["from"] == node.category
        listed = bomc("objects", str(site), "--format", "json", timeout=60)
        assert listed.returncode == 0, listed.stderr
        objects = {o["id"]: o for o in json.loads(listed.stdout)["objects"]}
        assert objects[node.id]["category"] == "filing cabinet"
        # delete, then restore: the node leaves the map and comes back
        assert apply_edit(browser, node.id, "delete")[0] == "done"
        browser.wait_for(f"!!document.querySelector('#edit-history li[data-kind=deleted][data-id=\"{node.id}\"]')")
        assert not close_to(pixel(browser, x, y), rgb(category_hex("filing cabinet")))
        listed = json.loads(bomc("objects", str(site), "--format", "json", timeout=60).stdout)
        assert node.id not in {o["id"] for o in listed["objects"]}
        assert apply_edit(browser, node.id, "restore")[0] == "done"
        browser.wait_for(f"!!document.querySelector('#edit-history li[data-kind=restored][data-id=\"{node.id}\"]')")
        assert browser.errors == []
    finally:
        server.close()


def post(port: int, body: bytes, headers: dict[str, str]) -> tuple[int, dict]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request("POST", "/api/edit", body=body, headers=headers)
    reply = conn.getresponse()
    return reply.status, json.loads(reply.read() or b"{}")


@pytest.mark.parametrize("body, headers, words", [
    (b'{"action": "delete", "id": 0}', {"Content-Type": "text/plain"}, "application/json"),
    (b'{"action": "delete", "id": 0}', {"Content-Type": "application/json", "Origin": "http://evil.example"},
     "own page"),
    (b"{" + b" " * 5000 + b"}", {"Content-Type": "application/json"}, "1 to 4096 bytes"),
    (b"not json", {"Content-Type": "application/json"}, "not JSON"),
    (b'["delete", 0]', {"Content-Type": "application/json"}, "JSON object"),
    (b'{"action": "delete", "id": 0, "why": 1}', {"Content-Type": "application/json"}, "unknown field"),
    (b'{"action": "delete", "id": true}', {"Content-Type": "application/json"}, "node's id"),
    (b'{"action": "paint", "id": 0}', {"Content-Type": "application/json"}, "unknown edit"),
    (b'{"action": "delete", "id": 99999}', {"Content-Type": "application/json"}, "no node 99999"),
    (b'{"action": "relabel", "id": 0, "value": "a\\nb"}', {"Content-Type": "application/json"}, "printable"),
])
def test_bad_edit_requests_are_refused_and_change_nothing(office, tmp_path, body, headers, words):
    site = shutil.copytree(office["site"], tmp_path / "site")
    before = snapshot(site)
    server = serve_site(site, port=0)
    try:
        status, reply = post(server.port, body, headers)
    finally:
        server.close()
    assert status == 400 and words in reply["error"], reply
    assert snapshot(site) == before
