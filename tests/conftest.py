"""Shared fixtures: where the shared worlds and maps live; headless Chromium. Property tests
run the same examples every time (CI must be deterministic); set HYPOTHESIS_PROFILE=explore
to let hypothesis search afresh."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from built_sites import copy_site
from hypothesis import settings
from shared_data import SHARED, require_shared

settings.register_profile("deterministic", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium for the viewer tests (skipped, saying what to install, where there is none)."""
    from browser import INSTALL_HINT, Browser, BrowserError, find_chromium

    if find_chromium() is None:
        pytest.skip(INSTALL_HINT)
    try:
        b = Browser()
    except BrowserError as exc:
        pytest.skip(f"headless Chromium did not start ({exc}); {INSTALL_HINT}")
    yield b
    b.close()


@pytest.fixture(scope="session")
def shared() -> Path:
    require_shared()
    return SHARED


@pytest.fixture(scope="session")
def office_s_built(shared, tmp_path_factory):
    """office-s built once (seed 0, default configuration) and its build result.

    A build does not read the detector settings, so the mission tests with either detector
    and the fault test each start from a copy of this site (:func:`built_sites.copy_site`) instead of
    exploring office-s again (a build of it is about 15 s of CPU).
    """
    from bomc_bt import run

    world = shared / "worlds" / "office-s.yaml"
    site = tmp_path_factory.mktemp("office-s-built") / "site"
    result = run.run_build(world, site, seed=0, config=run.build_config())
    return {"world": world, "site": site, "result": result}


@pytest.fixture(scope="session")
def office_realistic(office_s_built, tmp_path_factory):
    """office-s built once and monitored in sessions 1-3 with the realistic detector.

    Shared by the mission tests (F1) and the robustness tests (fault-free baseline,
    the blocked corridor of session 3), so the slow passes run once per test session.
    """
    from bomc_bt import run
    from bomc_bt.evaluate_site import evaluate_session

    world = office_s_built["world"]
    site = copy_site(office_s_built, tmp_path_factory.mktemp("office-realistic") / "site")
    config = run.build_config()
    passes = {}
    for n in (1, 2, 3):
        result = run.run_monitor(world, site, n, seed=n, config=config)
        passes[n] = {"result": result, "f1": evaluate_session(world, site, n, config).overall.f1}
    return {"world": world, "site": site, "config": config, "passes": passes}


def pytest_collection_modifyitems(items):
    """With pytest-xdist (``scripts/test.sh`` runs ``--dist loadgroup``) each test file runs
    on one worker, so its module fixtures are built once; the tests that run passes on
    ``office_s_built`` carry their own group, ``office-s``, across files."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))
