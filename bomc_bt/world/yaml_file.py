"""Reading a world file's YAML strictly: duplicate keys are errors, syntax errors one line.

PyYAML silently keeps the last of two equal keys; in a hand-edited world file that
hides a typo (two ``sessions`` blocks, the first one lost), so this reader refuses them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from bomc_bt.errors import BomcError, read_input_text


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses duplicate mapping keys (PyYAML silently keeps the last)."""


def _construct_mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    loader.flatten_mapping(node)
    out: dict = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in out
        except TypeError:  # unhashable key (a list as a key): let the schema checks reject it
            raise yaml.constructor.ConstructorError(
                None, None, "unhashable mapping key", key_node.start_mark) from None
        if duplicate:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark)
        out[key] = loader.construct_object(value_node, deep=deep)
    return out


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def read_yaml(path: Path) -> Any:
    """Parse a YAML file; syntax errors become one line with the line number."""
    text = read_input_text(path, "world")
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # a SafeLoader subclass: no arbitrary objects
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        problem = " ".join(str(getattr(exc, "problem", None) or exc).split())
        line = f"line {mark.line + 1}" if mark is not None else None
        raise BomcError(f"YAML syntax error: {problem}", path, line) from None
    except RecursionError:
        raise BomcError("YAML nested too deeply", path) from None

