"""One YAML reader: every kind of input file refuses a key written twice, naming file and line."""

from __future__ import annotations

import pytest

from bomc_bt.config import load_config
from bomc_bt.errors import BomcError
from bomc_bt.grid import load_map
from bomc_bt.tree import Registry, load_tree
from bomc_bt.world import load_world

TWICE = {
    "config": (load_config, "sim:\n  dt: 0.1\n  dt: 0.2\n", 3, "dt"),
    "world": (load_world, "version: 1\nmap: a.yaml\nstart: [0, 0]\nmap: b.yaml\n", 4, "map"),
    "map": (load_map, "image: a.pgm\nresolution: 0.05\nimage: b.pgm\n", 3, "image"),
    "tree": (lambda p: load_tree(p, Registry(), None, lambda: 0.0),
             "root:\n  sequence: S\n  sequence: T\n", 3, "sequence"),
}


@pytest.mark.parametrize("kind", sorted(TWICE))
def test_a_key_written_twice_is_one_line_naming_file_line_and_key(tmp_path, kind):
    load, text, line, key = TWICE[kind]
    path = tmp_path / f"{kind}.yaml"
    path.write_text(text)
    with pytest.raises(BomcError) as err:
        load([path] if kind == "config" else path)
    assert str(err.value) == f"{path}: line {line}: invalid YAML: duplicate key {key!r}"


def test_text_that_is_not_yaml_names_the_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("sim:\n  dt: [0.1\n")
    with pytest.raises(BomcError, match=r"broken\.yaml: line 3: invalid YAML: \(YAML syntax error\)"):
        load_config([path])
