"""Hypothesis building blocks for fuzzing YAML input files (worlds, trees).

A fuzz test takes a valid document, mutates values at random paths inside it and
checks that loading either succeeds or fails with one clean :class:`BomcError`.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator
from typing import Any

from hypothesis import strategies as st


def yaml_values(scalars: st.SearchStrategy, keys: st.SearchStrategy, max_keys: int,
                max_leaves: int) -> st.SearchStrategy:
    """Nested lists and mappings of ``scalars``: any value a YAML file could hold."""
    return st.recursive(
        scalars,
        lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=max_keys)),
        max_leaves=max_leaves,
    )


def paths_of(value: Any, prefix: tuple = ()) -> Iterator[tuple]:
    """Every key/index path inside a parsed YAML value, the root (``()``) first."""
    yield prefix
    if isinstance(value, dict):
        for k, v in value.items():
            yield from paths_of(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from paths_of(v, (*prefix, i))


def mutate(document: Any, draw, values: st.SearchStrategy, keys: st.SearchStrategy, max_edits: int = 3) -> Any:
    """A copy of ``document`` with 1 to ``max_edits`` values replaced, deleted or added at
    random paths (``draw`` is hypothesis' ``data.draw``)."""
    doc = copy.deepcopy(document)
    for _ in range(draw(st.integers(1, max_edits))):
        paths = [p for p in paths_of(doc) if p]
        if not paths:
            return draw(values)
        path = draw(st.sampled_from(paths))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "delete" and isinstance(parent, dict):
            del parent[path[-1]]
        elif action == "add" and isinstance(parent, dict):
            parent[draw(keys)] = draw(values)
        else:
            parent[path[-1]] = draw(values)
    return doc
