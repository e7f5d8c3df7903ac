"""Property-based fuzzing of every input a user hands ``bomc`` (issue 18, item 4).

Command lines, world files, map YAML and images, config files, tree files and a
corrupted site store, each run in-process through :func:`bomc_bt.cli.main` on a fresh
copy of a small built and monitored site. Whatever the input: the exit code is 0, 1 or
2, nothing escapes as an exception (a traceback), and a refused input (exit 2) changed no
file of the site. The examples are bounded and derandomized, so CI runs the same ones.
(The loaders' own fuzzers are in test_world.py and test_tree_loader.py.)
"""

from __future__ import annotations

import contextlib
import io
import shutil
import sqlite3
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from site_files import snapshot
from yaml_fuzz import mutate, yaml_values

from bomc_bt import cli, run
from bomc_bt.config import resource_dir
from bomc_bt.errors import BomcError
from bomc_bt.officegen import OfficeParams, generate_office
from bomc_bt.site import Site
from bomc_bt.viewer.site import SiteView, load_site
from bomc_bt.viewer.store import StateStore

FUZZ = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

# Numbers and words a hostile user types: huge, negative, not numbers at all.
NUMBER_TEXT = st.one_of(
    st.integers(-(2**70), 2**70).map(str), st.sampled_from(["nan", "inf", "-inf", "1e400", "-0", "0x10", "", "½"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=6))
SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-(2**70), 2**70), st.floats(allow_nan=True),
                    st.text(max_size=8), st.sampled_from([10**400, -1, 0, 1e-300, "1e400", "\x00"]))
VALUES = yaml_values(SCALARS, st.text(max_size=5), max_keys=3, max_leaves=6)


@pytest.fixture(scope="module")
def site_kit(tmp_path_factory):
    """A 12 x 12 m office built and monitored in session 1, plus configs that keep missions short."""
    root = tmp_path_factory.mktemp("fuzz")
    world = root / "world" / "office.yaml"
    world.parent.mkdir()
    generate_office(OfficeParams(width=12, height=12, seed=2, sessions=2), world)
    site = root / "site"
    assert run.run_build(world, site, seed=0).succeeded
    assert run.run_monitor(world, site, 1, seed=1).succeeded
    short = root / "short.yaml"  # a build that stops after 5 s, a pass that never localizes
    short.write_text("exploration: {max_time: 5}\nrelocalization: {min_score: 0.999}\n")
    trees = shutil.copytree(resource_dir("trees"), root / "trees")
    return {"root": root, "world": world, "site": site, "short": short, "trees": trees}


class Sandbox:
    """A fresh copy of the kit's site per example, and ``bomc`` run in-process against it."""

    def __init__(self, kit: dict, name: str):
        self.kit = kit
        self.dir = kit["root"] / "runs" / name
        shutil.rmtree(self.dir, ignore_errors=True)
        self.dir.mkdir(parents=True)
        self.site = shutil.copytree(kit["site"], self.dir / "site", symlinks=True)

    def bomc(self, *args: str) -> tuple[int, str]:
        """Exit code and stderr of ``bomc args``; any exception escaping main() fails the test."""
        before = snapshot(self.site)
        err, out = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                code = cli.main(list(args))
            except SystemExit as exc:  # argparse's usage errors
                code = exc.code
        stderr = err.getvalue()
        assert code in (0, 1, 2), (args, code, stderr)
        assert "Traceback" not in stderr, (args, stderr)
        if code == 2:
            assert stderr.count("bomc: error:") == 1, (args, stderr)
            assert snapshot(self.site) == before, f"refused input changed the site: {args} {stderr}"
        return code, stderr


def draw_mutated(data, document):
    return mutate(document, data.draw, VALUES, st.one_of(st.text(max_size=6), st.integers(0, 4)))


# -- command lines ---------------------------------------------------------------------------------
OPTIONS = {
    "build": ["--seed", "--max-time", "--explorer", "--viewer-port"],
    "monitor": ["--session", "--seed", "--viewer-port"],
    "evaluate": ["--session"],
    "world": ["--size", "--seed", "--sessions", "--churn", "--resolution"],
}


@FUZZ
@given(data=st.data())
def test_fuzzed_command_lines(site_kit, data):
    box = Sandbox(site_kit, "cli")
    command = data.draw(st.sampled_from(sorted(OPTIONS)))
    chosen = data.draw(st.lists(st.sampled_from(OPTIONS[command]), min_size=1, max_size=3, unique=True))
    args = [a for option in chosen for a in (option, data.draw(NUMBER_TEXT))]
    if command == "world":
        box.bomc("world", "office", "--out", str(box.dir / "gen" / "w.yaml"), *args)
        return
    base = [command, "--world", str(site_kit["world"]), "--site", str(box.site)]
    if command in ("build", "monitor"):
        base += ["--config", str(site_kit["short"]), "--quiet"]
    if command in ("monitor", "evaluate") and "--session" not in chosen:
        base += ["--session", "2"]
    box.bomc(*base, *args)


# -- world files, map YAML and image ---------------------------------------------------------------
def world_copy(box: Sandbox) -> Path:
    folder = shutil.copytree(box.kit["world"].parent, box.dir / "world")
    return folder / "office.yaml"


@FUZZ
@given(data=st.data())
def test_fuzzed_world_files(site_kit, data):
    box = Sandbox(site_kit, "world")
    world = world_copy(box)
    world.write_text(yaml.safe_dump(draw_mutated(data, yaml.safe_load(world.read_text())), sort_keys=False))
    box.bomc("evaluate", "--world", str(world), "--site", str(box.site), "--session", "1")


@FUZZ
@given(data=st.data())
def test_fuzzed_map_yaml_and_image(site_kit, data):
    box = Sandbox(site_kit, "map")
    world = world_copy(box)
    map_yaml = world.with_name("office-map.yaml")
    if data.draw(st.booleans()):
        map_yaml.write_text(yaml.safe_dump(draw_mutated(data, yaml.safe_load(map_yaml.read_text()))))
    else:
        image = world.with_name("office-map.pgm")
        body = image.read_bytes().split(b"\n", 3)[-1]
        header = data.draw(st.sampled_from([b"P5\n100000 100000\n255\n", b"P5\n-3 4\n255\n", b"P5\n0 0\n255\n",
                                            b"P5\n240 240\n65535\n", b"P2\n2 2\n255\n", b"GIF89a"]))
        tail = data.draw(st.sampled_from([body, body[:100], b"", body + b"\xff" * 100]))
        image.write_bytes(header + tail)
    box.bomc("evaluate", "--world", str(world), "--site", str(box.site), "--session", "1")


# -- config and tree files -------------------------------------------------------------------------
@FUZZ
@given(data=st.data())
def test_fuzzed_config_files(site_kit, data):
    box = Sandbox(site_kit, "config")
    config = box.dir / "fuzz.yaml"
    defaults = yaml.safe_load((resource_dir("config") / "defaults.yaml").read_text())
    kind = data.draw(st.sampled_from(["mutated", "bytes", "nested"]))
    if kind == "mutated":
        config.write_text(yaml.safe_dump(draw_mutated(data, defaults)))
    elif kind == "bytes":
        config.write_bytes(data.draw(st.binary(max_size=40)))
    else:
        depth = data.draw(st.integers(50, 5000))
        config.write_text("a: " + "[" * depth + "]" * depth + "\n")
    code, _ = box.bomc("config", "--config", str(config))
    if code == 0:  # a config that loads is used for real by an evaluation
        box.bomc("evaluate", "--world", str(site_kit["world"]), "--site", str(box.site), "--session", "1",
                 "--config", str(config))


@FUZZ
@given(data=st.data())
def test_fuzzed_tree_files(site_kit, data):
    box = Sandbox(site_kit, "tree")
    trees = shutil.copytree(site_kit["trees"], box.dir / "trees")
    name = data.draw(st.sampled_from(["monitor.yaml", "traverse.yaml", "build.yaml"]))
    tree = trees / name
    tree.write_text(yaml.safe_dump(draw_mutated(data, yaml.safe_load(tree.read_text())), sort_keys=False))
    mission = "build" if name == "build.yaml" else "monitor"
    command = [mission, "--world", str(site_kit["world"]), "--site", str(box.site), "--tree",
               str(trees / f"{mission}.yaml"), "--config", str(site_kit["short"]), "--quiet"]
    box.bomc(*command, *(["--session", "2"] if mission == "monitor" else ["--new-map"]))


# -- a corrupted store -----------------------------------------------------------------------------
COLUMNS = {
    "nodes": ["category", "x", "y", "z", "confidence", "first_session", "last_session", "state", "observations",
              "misses", "fx0"],
    "node_history": ["id", "session", "stamp", "kind", "category", "x", "y", "z", "confidence", "px"],
    "sessions": ["number", "started_stamp", "started_wall", "ended_stamp", "ended_wall", "outcome", "counts",
                 "report", "info"],
    "progress": ["value"],
    "schema_version": ["version"],
}
GARBAGE = st.one_of(st.sampled_from(["{not json", "[1, 2", "null", '"text"', "1e999", "NaN", "", "[]", "{}",
                                     "12abc", "-1", "present", "removed"]),
                    st.text(max_size=8), st.integers(-(2**63), 2**63 - 1), st.floats(allow_nan=True),
                    st.binary(max_size=8), st.none())


@FUZZ
@given(data=st.data())
def test_corrupted_store(site_kit, data):
    box = Sandbox(site_kit, "store")
    db = box.site / "site.db"
    with contextlib.closing(sqlite3.connect(db)) as con:
        for _ in range(data.draw(st.integers(1, 3))):
            table = data.draw(st.sampled_from(sorted(COLUMNS)))
            column = data.draw(st.sampled_from(COLUMNS[table]))
            rows = [r[0] for r in con.execute(f"SELECT rowid FROM {table}")]
            if not rows:
                continue
            row = data.draw(st.sampled_from(rows))
            with contextlib.suppress(sqlite3.IntegrityError):  # NOT NULL, PRIMARY KEY: SQLite refuses itself
                con.execute(f"UPDATE {table} SET {column} = ? WHERE rowid = ?", (data.draw(GARBAGE), row))
        con.commit()
    box.bomc("evaluate", "--world", str(site_kit["world"]), "--site", str(box.site), "--session", "1")
    try:  # what `bomc view` shows, without serving it
        load_site(StateStore(), SiteView(box.site))
    except BomcError as exc:
        assert "\n" not in str(exc)
    box.bomc("monitor", "--world", str(site_kit["world"]), "--site", str(box.site), "--session", "2",
             "--config", str(site_kit["short"]), "--quiet")


# -- the bad inputs the issue found, one by one ---------------------------------------------------
def _write(path: Path, text: str | bytes) -> Path:
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


def _corrupt(site: Path, sql: str) -> None:
    with contextlib.closing(sqlite3.connect(site / "site.db")) as con:
        con.execute(sql)
        con.commit()


KNOWN_BAD = {
    # name: (prepare(box) -> argv, text the error line must contain)
    "seed -1": (lambda b: ["build", "--world", str(b.kit["world"]), "--site", str(b.site), "--seed", "-1"],
                "--seed"),
    "seed 2**64": (lambda b: ["monitor", "--world", str(b.kit["world"]), "--site", str(b.site), "--session", "2",
                              "--seed", str(2**64)], "--seed"),
    "viewer port": (lambda b: ["build", "--world", str(b.kit["world"]), "--site", str(b.site), "--viewer",
                               "--viewer-port", "99999"], "--viewer-port"),
    "view port": (lambda b: ["view", str(b.site), "--port", "99999", "--no-browser"], "--port"),
    "session 1e9": (lambda b: ["monitor", "--world", str(b.kit["world"]), "--site", str(b.site), "--session",
                               "1000000000"], "--session"),
    "session beyond": (lambda b: ["monitor", "--world", str(b.kit["world"]), "--site", str(b.site), "--session",
                                  "40"], "beyond what the site and the world hold"),
    "world session 1e9": (lambda b: ["evaluate", "--world", str(_world_with(b, "during:\n- {session: 1000000000, "
                                                                              "at: 1.0, remove: []}\n")),
                                     "--site", str(b.site), "--session", "1"], "during[0].session"),
    "config huge int": (lambda b: ["config", "--config", str(_write(b.dir / "c.yaml", "sim: {dt: " + "9" * 400
                                                                     + "}\n"))], "sim.dt"),
    "config negative period": (lambda b: ["config", "--config", str(_write(
        b.dir / "c.yaml", "sim: {obstacles: {update_period: -1}}\n"))], "update_period"),
    "config negative dropout": (lambda b: ["config", "--config", str(_write(
        b.dir / "c.yaml", "detector: {dropouts: [[-5, -1]]}\n"))], "dropout"),
    "config not utf-8": (lambda b: ["config", "--config", str(_write(b.dir / "c.yaml", b"\xff\xfe: 1\n"))],
                         "c.yaml"),
    "map negate list": (lambda b: ["evaluate", "--world", str(_map_with(b, "negate: [1]\n")), "--site",
                                   str(b.site), "--session", "1"], "negate"),
    "map huge resolution": (lambda b: ["evaluate", "--world", str(_map_with(b, "resolution: " + "9" * 400 + "\n")),
                                       "--site", str(b.site), "--session", "1"], "resolution"),
    "pgm 100000 x 100000": (lambda b: ["evaluate", "--world", str(_pgm_with(b, b"P5\n100000 100000\n255\n")),
                                       "--site", str(b.site), "--session", "1"], "100000 x 100000"),
    "store json": (lambda b: _corrupt(b.site, "UPDATE sessions SET report = '{not json'") or [
        "evaluate", "--world", str(b.kit["world"]), "--site", str(b.site), "--session", "1"], "sessions.report"),
    "store text number": (lambda b: _corrupt(b.site, "UPDATE nodes SET x = 'removed'") or [
        "monitor", "--world", str(b.kit["world"]), "--site", str(b.site), "--session", "2", "--quiet"], "nodes.x"),
    "garbage build.json": (lambda b: _write(Site(b.site).build_json, '{"termination": 3}') and [
        "view", str(b.site), "--no-browser", "--port", "0"], "build.json"),
    "build with the monitor tree": (lambda b: ["build", "--world", str(b.kit["world"]), "--site", str(b.site),
                                               "--new-map", "--tree", str(b.kit["trees"] / "monitor.yaml")],
                                    "--tree"),
}


def _world_with(box: Sandbox, extra: str) -> Path:
    world = world_copy(box)
    world.write_text(world.read_text().split("during:")[0] + extra)
    return world


def _map_with(box: Sandbox, line: str) -> Path:
    world = world_copy(box)
    map_yaml = world.with_name("office-map.yaml")
    key = line.split(":")[0]
    kept = [x for x in map_yaml.read_text().splitlines(keepends=True) if not x.startswith(key + ":")]
    map_yaml.write_text("".join(kept) + line)
    return world


def _pgm_with(box: Sandbox, header: bytes) -> Path:
    world = world_copy(box)
    _write(world.with_name("office-map.pgm"), header + b"\0" * 100)
    return world


@pytest.mark.parametrize("name", sorted(KNOWN_BAD))
def test_known_bad_inputs_are_refused_in_one_line(site_kit, name):
    box = Sandbox(site_kit, f"known-{name.replace(' ', '-')}")
    prepare, expected = KNOWN_BAD[name]
    code, stderr = box.bomc(*prepare(box))
    assert code == 2, stderr
    assert expected in stderr, stderr
