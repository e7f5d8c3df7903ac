"""The one YAML reader: config, world, map and tree files all go through :func:`read_yaml`.

PyYAML silently keeps the last of two equal keys, so a user who writes ``map:`` twice in a
world file or ``timeout:`` twice in a tree leaf gets one of them without a word. The loader
here is a ``SafeLoader`` (no arbitrary objects) that refuses duplicate keys, and every way
a file can fail to parse becomes one :class:`BomcError` line naming the file and the line:
``site.yaml: line 3: duplicate key 'map'``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import yaml

from bomc_bt.errors import BomcError


class UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses duplicate mapping keys (PyYAML silently keeps the last)."""


def _construct_mapping(loader: UniqueKeyLoader, node: yaml.MappingNode) -> Iterator[dict]:
    # A generator like PyYAML's own: the dict exists before its values, so a recursive
    # alias builds a cycle that the schema checks report, instead of failing here.
    out: dict = {}
    yield out
    loader.flatten_mapping(node)
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node)
        try:
            duplicate = key in out
        except TypeError:  # unhashable key (a list as a key): let the schema checks reject it
            raise yaml.constructor.ConstructorError(
                None, None, "unhashable mapping key", key_node.start_mark) from None
        if duplicate:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
        out[key] = loader.construct_object(value_node)


UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def parse_yaml(text: str, path: str | Path) -> Any:
    """Parse YAML ``text`` read from ``path``; any failure is one line naming file and line."""
    try:
        return yaml.load(text, Loader=UniqueKeyLoader)  # a SafeLoader subclass: no arbitrary objects
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = " ".join(str(exc.problem or exc.context or exc).split())
        if not isinstance(exc, yaml.constructor.ConstructorError):  # the text is not YAML at all
            problem = f"(YAML syntax error) {problem}"
        line = f"line {mark.line + 1}" if mark is not None else None
        raise BomcError(f"invalid YAML: {problem}", path, line) from None
    except RecursionError:
        raise BomcError("invalid YAML: nested too deeply", path) from None
    except Exception as exc:  # noqa: BLE001 - values PyYAML cannot build (a bad date, ...)
        raise BomcError(f"invalid YAML: {' '.join(str(exc).split())}", path) from None


def read_yaml(path: str | Path, what: str = "file") -> Any:
    """Read and parse the YAML file ``path``; ``what`` names it in "not found" ("world file")."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise BomcError(f"{what} not found", path) from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise BomcError(f"cannot read the {what} ({type(exc).__name__})", path) from None
    return parse_yaml(text, path)
