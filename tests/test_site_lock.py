"""One writer per site, any number of readers (issue 18, item 2).

build and monitor hold an flock on ``<site>/.lock`` for their whole run: a second writer
is refused with exit 2 naming the holder's pid, and the kernel lets go when the holder
dies. evaluate and view open the store read-only: they change no byte (nor mtime) of the
site and work on a site nobody may write.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import urllib.request
from pathlib import Path

import pytest
from site_files import LAB_B, REPO, bomc, bomc_command, bomc_env, copy_site, error_line, snapshot

from bomc_bt import run
from bomc_bt.errors import BomcError
from bomc_bt.site_lock import SiteLock
from bomc_bt.store import SiteStore
from bomc_bt.viewer import serve_site

HOLDER = """
import sys, time
from bomc_bt.site_lock import SiteLock
lock = SiteLock.acquire(sys.argv[1], sys.argv[2])
print("locked", flush=True)
time.sleep(120)
"""


@pytest.fixture(scope="module")
def monitored(tmp_path_factory) -> Path:
    """lab-b built and monitored in session 1."""
    if not LAB_B.exists():
        pytest.skip(f"shared data not found at {LAB_B} (set BOMC_SHARED to the shared folder)")
    site = tmp_path_factory.mktemp("lock") / "site"
    assert run.run_build(LAB_B, site, seed=0).succeeded
    assert run.run_monitor(LAB_B, site, 1, seed=1).succeeded
    return site


def hold(site: Path, mission: str) -> subprocess.Popen:
    """A process that takes the site's writer lock and keeps it."""
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(site), mission], env=bomc_env(), cwd=REPO,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    return proc


@pytest.mark.parametrize("holder", ["build", "monitor"])
def test_a_second_writer_is_refused_naming_the_holder(monitored, tmp_path, holder):
    site = copy_site(monitored, tmp_path / "site")
    before = snapshot(site)
    proc = hold(site, holder)
    try:
        for args in (["monitor", "--session", "2"], ["build", "--new-map", "--max-time", "20"],
                     ["monitor", "--session", "1", "--resume"]):
            line = error_line(bomc(*args, "--world", str(LAB_B), "--site", str(site), "--quiet"))
            assert f"pid {proc.pid} ({holder}" in line and ".lock" in line, line
        with pytest.raises(BomcError, match=f"pid {proc.pid}"):
            run.run_monitor(LAB_B, site, 2, seed=2)
        assert snapshot(site) == before
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    SiteLock.acquire(site, "monitor").release()  # the kernel let go when the holder died
    assert run.run_monitor(LAB_B, site, 2, seed=2).succeeded


def test_a_writer_holds_the_lock_for_its_whole_run(monitored, tmp_path):
    site = copy_site(monitored, tmp_path / "site")
    seen = []

    def try_to_write(runner) -> None:
        if not seen:
            with pytest.raises(BomcError, match=f"pid {os.getpid()} \\(monitor"):
                SiteLock.acquire(site, "monitor")
            seen.append(runner)

    assert run.run_monitor(LAB_B, site, 2, seed=2, hooks=[try_to_write]).succeeded
    assert seen
    SiteLock.acquire(site, "build").release()


def test_readers_open_the_store_read_only_and_change_nothing(monitored, tmp_path):
    site = copy_site(monitored, tmp_path / "site")
    before = snapshot(site, mtimes=True, skip=())
    with SiteStore(site / "site.db", readonly=True) as store:
        assert [s.number for s in store.sessions()] == [1]
        with pytest.raises(BomcError, match="readonly"):
            store.set_progress("x", 1)
    result = bomc("evaluate", "--world", str(LAB_B), "--site", str(site), "--session", "1", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["overall"]["f1"] > 0.9
    server = serve_site(site, port=0)
    try:
        page = urllib.request.urlopen(server.url, timeout=10).read()
        state = json.loads(urllib.request.urlopen(server.url + "state.json", timeout=10).read())
    finally:
        server.close()
    assert b"<html" in page.lower() and state["sections"]["site"]["sessions"][0]["number"] == 1
    assert snapshot(site, mtimes=True, skip=()) == before


def test_a_reader_sees_what_a_killed_writer_left_in_the_wal(monitored, tmp_path):
    """A -wal file (a writer running, or killed) is read with mode=ro, so its frames count."""
    site = copy_site(monitored, tmp_path / "site")
    writer = SiteStore(site / "site.db")
    writer.set_progress("probe", 7)  # committed to the WAL, not yet checkpointed into site.db
    try:
        assert (site / "site.db-wal").exists()
        with SiteStore(site / "site.db", readonly=True) as reader:
            assert reader.get_progress("probe") == 7
    finally:
        writer.close()


def _popen_taking_sigint(*args, **kwargs) -> subprocess.Popen:
    """Popen whose child stops on SIGINT like one started from a terminal. A suite started as
    a background job of a script has SIGINT ignored, and a child keeps an ignored signal
    across exec (`bomc view` then ran on after the test's Ctrl-C); a handled one is reset to
    the default there."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return subprocess.Popen(*args, **kwargs)
    finally:
        signal.signal(signal.SIGINT, previous)


def _as_nobody() -> list[str] | None:
    """The command prefix that drops root to nobody, or None where that is not possible."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        return None
    prefix = [setpriv, "--reuid=nobody", "--regid=nogroup", "--clear-groups"]
    # nobody must be able to run bomc from this checkout (a clone under a 0700 temp dir cannot)
    probe = subprocess.run(prefix + [sys.executable, "-c", "import bomc_bt.cli"], capture_output=True,
                           cwd="/", env=bomc_env(), timeout=60)
    return prefix if probe.returncode == 0 else None


def test_evaluate_and_view_work_on_a_site_nobody_may_write(monitored):
    prefix = _as_nobody()
    if prefix is None:
        pytest.skip("running as root, and nobody cannot run bomc from this checkout (no setpriv, or the "
                    "checkout is not readable by other users): cannot drop the permission to write")
    parent = Path(tempfile.mkdtemp(prefix="bomc-ro-"))
    try:
        parent.chmod(0o755)
        site = copy_site(monitored, parent / "site")
        subprocess.run(["chmod", "-R", "a-w", str(site)], check=True)
        before = snapshot(site, mtimes=True, skip=())
        env = {**bomc_env(), "HOME": str(parent), "PYTHONUNBUFFERED": "1"}
        result = subprocess.run(prefix + bomc_command("evaluate", "--world", str(LAB_B), "--site", str(site),
                                                      "--session", "1"),
                                capture_output=True, text=True, cwd=REPO, env=env, timeout=120)
        assert result.returncode == 0, result.stderr
        assert "overall" in result.stdout
        view = _popen_taking_sigint(prefix + bomc_command("view", str(site), "--no-browser", "--port", "0"),
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO, env=env)
        try:
            line = view.stdout.readline()
            url = re.search(r"http://\S+/", line)
            assert url, (line, view.stderr.read() if view.poll() is not None else "")
            state = json.loads(urllib.request.urlopen(url.group(0) + "state.json", timeout=10).read())
            assert state["sections"]["site"]["sessions"][0]["number"] == 1
        finally:
            view.send_signal(signal.SIGINT)
            view.wait(timeout=30)
        writer = subprocess.run(prefix + bomc_command("monitor", "--world", str(LAB_B), "--site", str(site),
                                                      "--session", "2", "--quiet"),
                                capture_output=True, text=True, cwd=REPO, env=env, timeout=120)
        assert "cannot lock the site for writing" in error_line(writer)
        assert snapshot(site, mtimes=True, skip=()) == before
    finally:
        subprocess.run(["chmod", "-R", "u+w", str(parent)], check=False)
        shutil.rmtree(parent, ignore_errors=True)
