"""Out of disk (issue 18): a build or a pass that cannot write ends with one line, exit 1,
and the site keeps what it had: the previous generation whole, the pass resumable.

Where the test may mount a tmpfs (root), the disk really fills up; everywhere the write
layer is made to fail as a full disk does (``ENOSPC`` from the file writes, SQLite's
``database or disk is full`` from a page limit on the store's connection).
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import sqlite3
import subprocess
import uuid
from pathlib import Path

import pytest
from site_files import BUILD_FILES, bomc, build_files

from bomc_bt import cli, run, store_schema
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.site import current_generation


@pytest.fixture(scope="module")
def small_site(tmp_path_factory):
    """A 16 x 12 m office, built (generation 1) and monitored once."""
    root = tmp_path_factory.mktemp("disk")
    world = root / "office.yaml"
    generate_office(OfficeParams(width=16, height=12, seed=5, sessions=2), world)
    built = root / "built"
    assert run.run_build(world, built, seed=0).succeeded
    monitored = shutil.copytree(built, root / "monitored")
    assert run.run_monitor(world, monitored, 1, seed=1).succeeded
    return {"world": world, "built": built, "monitored": monitored}


def one_failure_line(stderr: str) -> str:
    assert "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if line.startswith("bomc: failed:")]
    assert len(lines) == 1, stderr
    return lines[0]


def assert_generation_1_whole(site: Path, before: dict) -> None:
    assert current_generation(site) == 1
    assert build_files(site) == before
    assert not any(p.name.endswith(".partial") for p in site.glob("generations/*") if p.name == "current")
    assert (site / "current").read_text().strip() == "1"


def test_a_rebuild_out_of_disk_ends_in_one_line_and_keeps_the_old_generation(small_site, tmp_path, monkeypatch,
                                                                             capsys):
    site = shutil.copytree(small_site["built"], tmp_path / "site")
    before = build_files(site)

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(args[0]))

    monkeypatch.setattr("bomc_bt.grid.atomic_write", full)  # the map's write, as a full disk fails it
    code = cli.main(["build", "--world", str(small_site["world"]), "--site", str(site), "--quiet", "--seed", "1"])
    assert code == 1
    assert "No space left on device" in one_failure_line(capsys.readouterr().err)
    assert_generation_1_whole(site, before)
    monkeypatch.undo()  # space again: the next build succeeds and becomes generation 2
    assert cli.main(["build", "--world", str(small_site["world"]), "--site", str(site), "--quiet"]) == 0
    assert current_generation(site) == 2 and not list(site.glob("generations/*.partial"))


def test_a_pass_whose_store_fills_up_ends_in_one_line_and_resumes_later(small_site, tmp_path, monkeypatch, capsys):
    site = shutil.copytree(small_site["monitored"], tmp_path / "site")
    before = build_files(site)
    with contextlib.closing(sqlite3.connect(site / "site.db")) as db:
        db.execute("VACUUM")  # no free pages left inside the file either
    connect = store_schema.connect

    def small_disk(path, busy_timeout, readonly):
        db = connect(path, busy_timeout, readonly)
        if not readonly:  # no room to grow: SQLITE_FULL, as on a full disk
            pages = db.execute("PRAGMA page_count").fetchone()[0]
            db.execute(f"PRAGMA max_page_count = {pages}")
        return db

    monkeypatch.setattr("bomc_bt.store.connect", small_disk)
    args = ["monitor", "--world", str(small_site["world"]), "--site", str(site), "--session", "2", "--seed", "2",
            "--quiet"]
    assert cli.main(args) == 1
    assert "disk is full" in one_failure_line(capsys.readouterr().err)
    assert build_files(site) == before
    monkeypatch.undo()
    assert cli.main([*args, "--resume"]) == 0  # nothing was lost that the pass needs


@contextlib.contextmanager
def tiny_tmpfs(path: Path, size: str):
    path.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", f"bomc-{uuid.uuid4().hex[:8]}",
                              str(path)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root): the injected full disks above stand in")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def fill(folder: Path, leave: int) -> Path:
    filler = folder / "filler"
    stat = os.statvfs(folder)
    filler.write_bytes(b"\0" * max(0, stat.f_bavail * stat.f_frsize - leave))
    return filler


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_a_real_full_tmpfs_rebuild_and_pass(small_site, tmp_path):
    with tiny_tmpfs(tmp_path / "disk", "8m") as disk:
        site = shutil.copytree(small_site["monitored"], disk / "site")
        shutil.rmtree(site / "sessions")
        (site / "site.db").unlink()  # a built site without a graph: a re-build is allowed
        before = build_files(site)
        filler = fill(disk, 40_000)  # less than the new map needs
        result = bomc("build", "--world", str(small_site["world"]), "--site", str(site), "--quiet", "--seed", "1")
        assert result.returncode == 1, result.stderr
        assert "No space left on device" in one_failure_line(result.stderr)
        assert_generation_1_whole(site, before)
        filler.unlink()
        filler = fill(disk, 60_000)
        result = bomc("monitor", "--world", str(small_site["world"]), "--site", str(site), "--session", "1",
                      "--quiet")
        assert result.returncode == 1, result.stderr
        one_failure_line(result.stderr)
        assert build_files(site) == before
        filler.unlink()
        result = bomc("monitor", "--world", str(small_site["world"]), "--site", str(site), "--session", "1",
                      "--quiet", "--resume")
        assert result.returncode == 0, result.stderr
        assert all((site / name).exists() for name in BUILD_FILES)
