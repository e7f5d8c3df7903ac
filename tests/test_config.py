"""The configuration: shipped defaults match the code, and mistakes name file and field."""

from __future__ import annotations

import yaml

from bomc_bt.config import Config, config_to_dict, load_config, resource_dir
from bomc_bt.errors import BomcError


def test_shipped_defaults_match_the_code():
    shipped = yaml.safe_load((resource_dir("config") / "defaults.yaml").read_text())
    assert shipped == config_to_dict(Config()), "regenerate: bomc config --defaults > config/defaults.yaml"


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
