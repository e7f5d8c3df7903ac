"""The configuration: shipped defaults match the code, and mistakes name file and field."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import typing
from collections.abc import Iterator
from dataclasses import field
from pathlib import Path

import pytest
import yaml

from bomc_bt.cli import main
from bomc_bt.config import Config, config_to_dict, defaults_yaml, load_config, resource_dir
from bomc_bt.config_docs import UNITS, FieldDoc, field_docs, summary
from bomc_bt.config_trees import leaves_with_params, mission_trees
from bomc_bt.errors import BomcError
from bomc_bt.tree import load_tree
from bomc_bt.tree.registry import load_registry


def test_shipped_defaults_match_the_code():
    text = (resource_dir("config") / "defaults.yaml").read_text()
    assert text == defaults_yaml(), "regenerate: bomc config --defaults > config/defaults.yaml"
    assert yaml.safe_load(text) == config_to_dict(Config())


def records(cls: type = Config, where: str = "") -> Iterator[tuple[str, type]]:
    """Every parameter record reachable from ``Config``, with its config path."""
    yield where or "(top)", cls
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if f.init and dataclasses.is_dataclass(hints[f.name]):
            yield from records(hints[f.name], f"{where}.{f.name}".lstrip("."))


def test_every_parameter_has_a_unit_and_a_meaning():
    undocumented = []
    for where, cls in records():
        docs = field_docs(cls)
        if where != "(top)" and not summary(cls):
            undocumented.append(f"{where}: no docstring")
        for f in dataclasses.fields(cls):
            if not f.init or dataclasses.is_dataclass(typing.get_type_hints(cls)[f.name]):
                continue
            doc = docs.get(f.name)
            if doc is None or doc.unit not in UNITS or len(doc.meaning) < 8:
                undocumented.append(f"{where}.{f.name}: {doc}")
    assert not undocumented, "\n".join(undocumented)


def test_defaults_show_each_value_with_its_unit_and_meaning():
    lines = defaults_yaml().splitlines()
    assert any(line.startswith("  expect_range: 5.0  # [m] a node farther from the camera") for line in lines)
    assert "  angular_step_deg: 2.0  # [deg] coarse grid step" in lines
    assert "# Mission-wide knobs that are not a single behaviour's parameters." in lines
    assert lines[lines.index("# Mission-wide knobs that are not a single behaviour's parameters.") + 1] == "mission:"


def test_field_docs_read_trailing_comments_and_comment_blocks_above():
    @dataclasses.dataclass
    class DemoParams:
        """A demo."""

        # -- section rule (not a doc: a trailing comment wins) --
        a: float = 1.0  # [m] first
        # [s] second, over
        # two lines
        b: float = field(default=2.0)
        c: int = 3

    assert field_docs(DemoParams) == {"a": FieldDoc("m", "first"), "b": FieldDoc("s", "second, over two lines")}


def test_reading_the_config_loads_neither_the_simulator_nor_opencv():
    code = ("import sys, bomc_bt.config; "
            "print([m for m in ('bomc_bt.sim.robot', 'bomc_bt.sim.camera', 'cv2', 'onnxruntime') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).parent.parent)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_a_removed_key_is_an_error_that_says_what_replaced_it(tmp_path):
    path = tmp_path / "old.yaml"
    path.write_text("sim:\n  scene: {lidar_height: 0.3}\n")
    with pytest.raises(BomcError, match=r"old\.yaml: sim\.scene\.lidar_height: removed: .*sim\.lidar\.height"):
        load_config([path])


def test_layers_override_in_order(tmp_path):
    extra = tmp_path / "mine.yaml"
    extra.write_text("exploration: {local_radius: 6.5}\nassociation: {per_category: {table: 1.0}}\n")
    config = load_config([extra])
    assert config.exploration.local_radius == 6.5
    assert config.association.per_category == {"table": 1.0}
    assert config.camera.scale == 0.5  # from config/sim.yaml
    assert config.source[-1] == str(extra)


def test_errors_name_the_file_and_field(tmp_path):
    cases = {
        "exploration: {local_radus: 3}\n": "mine.yaml: exploration.local_radus: unknown key",
        "sim: {dt: fast}\n": "mine.yaml: sim.dt: has the wrong type",
        "association: {mode: clever}\n": "mine.yaml: association",
        "association: {return_radius: 5}\n": "mine.yaml: association: return_radius must be in [0, 2] m",
        "camera: [1, 2]\n": "mine.yaml: camera: expected a mapping",
        "exploration: {local_radius: 3\n": "mine.yaml: line",
    }
    path = tmp_path / "mine.yaml"
    for text, expected in cases.items():
        path.write_text(text)
        try:
            load_config([path])
        except Exception as exc:  # noqa: BLE001 - the type is asserted below
            assert type(exc).__name__ == "BomcError", exc
            assert expected in str(exc), str(exc)
            assert "\n" not in str(exc)
        else:
            raise AssertionError(f"no error for {text!r}")


def test_a_key_written_twice_is_an_error_naming_file_line_and_key(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("exploration:\n  local_radius: 3.0\n  local_radius: 5.0\n")
    try:
        load_config([path])
    except BomcError as exc:
        assert str(exc) == f"{path}: line 3: invalid YAML: duplicate key 'local_radius'"
    else:
        raise AssertionError("a duplicate key was accepted")


def test_bomc_config_prints_the_effective_values_with_their_docs(tmp_path, capsys):
    mine = tmp_path / "mine.yaml"
    mine.write_text("exploration: {local_radius: 6.5}\n")
    assert main(["config", "--config", str(mine)]) == 0
    out = capsys.readouterr().out
    assert "  local_radius: 6.5  # [m] r_l, the local window" in out
    assert yaml.safe_load(out) == config_to_dict(load_config([mine]))


def test_bomc_config_trees_lists_every_leaf_parameter_of_the_shipped_trees(capsys):
    assert main(["config", "--trees"]) == 0
    listed = yaml.safe_load(capsys.readouterr().out)
    registry = load_registry()
    for path in mission_trees(resource_dir("trees")):
        root = load_tree(path, registry, None, lambda: 0.0)
        leaves = dict(leaves_with_params(root))
        assert leaves, path
        assert listed[path.name] == {where: config_to_dict(leaf.params) for where, leaf in leaves.items()}
    look = listed["monitor.yaml"]
    assert any(where.endswith("/ Look Around") and p["radius"] == 5.0 for where, p in look.items())


def test_angles_are_given_in_degrees_and_read_in_radians(tmp_path):
    mine = tmp_path / "mine.yaml"
    mine.write_text("relocalization: {search_angle_deg: 30}\n")
    config = load_config([mine])
    assert config.relocalization.search_angle == math.radians(30.0)
    assert config.relocalization.angular_step == 0.03490658503988659  # 2 deg, exactly the old radians default
    # defaults that are not whole degrees are written so that they give the old radians exactly
    motion, ros = config.sim.motion, config.ros
    assert (motion.max_turn_rate, motion.turn_in_place_angle, motion.yaw_tolerance) == (1.0, 0.8, 0.15)
    assert (config.sim.mapper.angular_update, config.sim.localization.lost_angle) == (0.25, 0.5)
    assert (ros.initial_yaw_std, ros.max_yaw_std, ros.progress_angle) == (0.3, 0.15, 0.3)
    mine.write_text("relocalization: {search_angle: 0.5}\n")
    with pytest.raises(BomcError, match=r"mine\.yaml: relocalization\.search_angle: renamed: .* search_angle_deg"):
        load_config([mine])
