"""Shared pieces of the central-store tests: lab-b sites before and after a pass, and the central state.

The fixtures are imported by name (``from central_sites import lab_site, ...``) like the
server's (``tests/postgres_server.py``). Sites are lab-b with the perfect detector: a
build and a pass take seconds.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import psycopg
import pytest
from site_files import LAB_B, bomc, copy_site

from bomc_bt import run

TABLES = ("floors", "generations", "sessions", "nodes", "node_history", "progress", "files", "leases")
# columns that say when, not what: the first sync's time, the log's own id and time
WHEN = ("first_synced", "synced_at", "id")


@pytest.fixture(scope="module")
def perfect(tmp_path_factory):
    path = tmp_path_factory.mktemp("cfg") / "perfect.yaml"
    path.write_text("detector: {preset: perfect}\n")
    return path


@pytest.fixture(scope="module")
def lab_site(tmp_path_factory, perfect, shared):
    """lab-b built and monitored in session 1 (the state every test starts from: copy it)."""
    site = tmp_path_factory.mktemp("lab") / "site"
    config = run.build_config([str(perfect)])
    run.run_build(LAB_B, site, seed=0, config=config)
    assert run.run_monitor(LAB_B, site, 1, seed=1, config=config).succeeded
    return site


@pytest.fixture(scope="module")
def lab_site_2(lab_site, perfect, tmp_path_factory):
    """``lab_site`` after pass 2 (seed 2): what the same site holds once its next pass ran."""
    site = copy_site(lab_site, tmp_path_factory.mktemp("lab2") / "site")
    assert run.run_monitor(LAB_B, site, 2, seed=2, config=run.build_config([str(perfect)])).succeeded
    return site


def run_pass_2(site: Path, lab_site_2: Path) -> None:
    """Give ``site`` (a copy of lab_site) what its pass 2 writes: the graph, the reports, the plan.

    Passes are deterministic for a seed, so this is the pass's own result, without paying
    for the simulation in every test."""
    for name in ("site.db-wal", "site.db-shm"):
        (site / name).unlink(missing_ok=True)
    for name in ("site.db", "plan.json"):
        shutil.copy2(lab_site_2 / name, site / name)
    shutil.copytree(lab_site_2 / "sessions", site / "sessions", dirs_exist_ok=True)


def central_state(url: str, tables: tuple[str, ...] = TABLES) -> dict[str, list[tuple]]:
    """Every row of the central tables, sorted, without the columns that only say when.

    A database without the ``bomc`` schema holds no rows: every table is empty."""
    with psycopg.connect(url) as conn:
        out = {}
        for table in tables:
            cols = [r[0] for r in conn.execute(
                "SELECT column_name FROM information_schema.columns WHERE table_schema = 'bomc' AND table_name = %s"
                " ORDER BY ordinal_position", (table,)).fetchall() if r[0] not in WHEN]
            rows = conn.execute(f"SELECT {', '.join(cols)} FROM bomc.{table}").fetchall() if cols else []
            out[table] = sorted(map(tuple, rows), key=repr)
        return out


def monitor(site: Path, session: int, perfect: Path):
    """``bomc monitor`` of lab-b on ``site`` (a subprocess: the real command, its lease, its exit code)."""
    return bomc("monitor", "--world", str(LAB_B), "--site", str(site), "--session", str(session), "--seed",
                str(session), "--quiet", "--config", str(perfect))
