"""The parameters written in the shipped tree files, as documented YAML (``bomc config --trees``).

Some settings live next to the behaviour that uses them, in a leaf's ``params:`` in
``trees/*.yaml``, not in ``config/``. This module builds each mission tree the way a
mission does (the production leaves from :func:`~bomc_bt.tree.registry.load_registry`,
the files through the tree loader, so every value is validated) and lists every leaf
that has parameters with its values, units and meanings.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import fields
from pathlib import Path

from bomc_bt.config_docs import documented_yaml, summary
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.loader import Node, load_tree
from bomc_bt.tree.registry import load_registry
from bomc_bt.yaml_io import read_yaml

HEADER = """\
# Leaf parameters in the shipped trees (trees/*.yaml), by tree and node path.
# Change them in a copy of the tree file, run with --tree FILE.
"""


def mission_trees(trees_dir: Path) -> list[Path]:
    """The tree files that are missions (have a ``root:``), not only libraries of subtrees."""
    return [p for p in sorted(trees_dir.glob("*.yaml")) if "root" in (read_yaml(p, "tree file") or {})]


def leaves_with_params(root: Node) -> Iterator[tuple[str, Leaf]]:
    """(node path, leaf) for every leaf under ``root`` whose parameters have fields."""
    for node in root.iterate():
        if isinstance(node, Leaf) and fields(node.params):
            yield node_path(node), node


def node_path(node: Node) -> str:
    """``Monitor / Traverse / Look Around``: the names from the root down to ``node``."""
    names = []
    while node is not None:
        names.insert(0, node.name)
        node = node.parent
    return " / ".join(names)


def trees_yaml(trees_dir: Path) -> str:
    """Every mission tree's leaf parameters as YAML, each value with its documentation."""
    registry = load_registry()
    parts = [HEADER]
    for path in mission_trees(trees_dir):
        root = load_tree(path, registry, context=None, clock=lambda: 0.0)
        parts.append(f"{path.name}:\n")
        for where, leaf in leaves_with_params(root):
            parts.append(f"  # {type(leaf).__name__}: {summary(type(leaf)) or summary(type(leaf.params))}\n")
            parts.append(f"  {json.dumps(where)}:\n")
            parts.append(documented_yaml(leaf.params, indent=4))
    return "".join(parts)
