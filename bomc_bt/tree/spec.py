"""Checks on the YAML of a tree file that do not depend on the tree being built.

The small value checks every node kind shares
(names, remaps, lists, allowed keys) and a leaf's ``ports:`` entry. Each mistake is a
:class:`~bomc_bt.errors.BomcError` naming the file and the node path.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.tree.leaf import blackboard_key


def is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except (OSError, ValueError):  # a name with a NUL byte, too long, ...
        return False


def check_keys(spec: dict, allowed: tuple[str, ...], file: Path, where: str) -> None:
    for key in spec:
        if key not in allowed:
            raise BomcError(f"unknown key {key!r} here (expected one of: {', '.join(allowed)})", file, where)


def node_name(value: Any, file: Path, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise BomcError(f"a node name must be a non-empty string, got {describe(value)}", file, where)
    return value


def remap_spec(value: Any, file: Path, where: str) -> dict[str, str]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise BomcError(f"must be a mapping of key: blackboard key, got {describe(value)}", file, where)
    remap = {}
    for key, target in value.items():
        for item in (key, target):
            try:
                blackboard_key(item)
            except ValueError as exc:
                raise BomcError(str(exc), file, where) from None
        remap[key.lstrip("/")] = target.lstrip("/")
    return remap


def as_list(value: Any, file: Path, where: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise BomcError(f"must be a list, got {describe(value)}", file, where)
    return value


def describe(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return f"{type(value).__name__} {value!r}"[:60]


def check_ports(value: Any, reads: tuple[str, ...], writes: tuple[str, ...], file: Path, where: str) -> None:
    """A leaf's ``ports: {reads: [...], writes: [...]}`` must list exactly the keys it uses.

    The keys are as this file names them (after the leaf's ``remap``). Listing them is how
    a tree file shows its data flow; the check keeps that listing true.
    """
    expected = {"reads": sorted(reads), "writes": sorted(writes)}
    right = "ports: {reads: [" + ", ".join(expected["reads"]) + "], writes: [" + ", ".join(expected["writes"]) + "]}"
    if not isinstance(value, Mapping) or set(value) - {"reads", "writes"}:
        raise BomcError(f"must be a mapping with reads and writes lists; this leaf: {right}", file, where)
    for kind in ("reads", "writes"):
        listed = value.get(kind) or []
        if not isinstance(listed, list) or sorted(map(str, listed)) != expected[kind]:
            raise BomcError(f"{kind} lists {listed!r}, but the leaf {kind} {expected[kind]}; write {right}",
                            file, f"{where}.{kind}")
