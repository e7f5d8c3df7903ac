"""Names a tree file can use for leaves, and how a leaf is built from its YAML entry.

Behaviour modules register their leaves with ``@register("SaveMap")`` on the default
registry; tests build their own :class:`Registry` so they do not see (or pollute) it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

from bomc_bt.errors import BomcError
from bomc_bt.params import from_mapping
from bomc_bt.tree.leaf import Leaf

L = TypeVar("L", bound=type[Leaf])


class Registry:
    """A mapping from behaviour names (as written in tree files) to Leaf subclasses."""

    def __init__(self) -> None:
        self._leaves: dict[str, type[Leaf]] = {}

    def register(self, name: str) -> Callable[[L], L]:
        """Class decorator: make ``cls`` available in tree files as ``behaviour: name``."""

        def add(cls: L) -> L:
            self.add(name, cls)
            return cls

        return add

    def add(self, name: str, cls: type[Leaf]) -> None:
        """Register ``cls`` under ``name``; registering a different class twice is a bug."""
        if not (isinstance(cls, type) and issubclass(cls, Leaf)):
            raise TypeError(f"{cls!r} is not a Leaf subclass")
        if self._leaves.get(name, cls) is not cls:
            raise ValueError(f"behaviour {name!r} is already registered as {self._leaves[name].__name__}")
        self._leaves[name] = cls

    def get(self, name: str) -> type[Leaf]:
        """The class registered as ``name`` (KeyError if none)."""
        return self._leaves[name]

    def names(self) -> list[str]:
        """Registered names, sorted (for 'known: ...' in error messages)."""
        return sorted(self._leaves)

    def __contains__(self, name: object) -> bool:
        return name in self._leaves

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self._leaves)

    def create(
        self,
        behaviour: str,
        name: str,
        params: Any,
        context: Any,
        remap: Mapping[str, str] | None = None,
        *,
        file: str | Path | None = None,
        where: str = "",
    ) -> Leaf:
        """Build leaf ``behaviour`` named ``name``.

        ``params`` is either an instance of the leaf's ``Params`` dataclass or a YAML
        mapping (None = empty) validated against it; mistakes become a BomcError that
        names ``file`` and ``where``.
        """
        if behaviour not in self._leaves:
            known = ", ".join(self.names()) or "none registered"
            raise BomcError(f"unknown behaviour {behaviour!r} (known: {known})", file, where or None)
        cls = self._leaves[behaviour]
        fixed = sorted(set(params or ()) & set(cls.config_params)) if isinstance(params, Mapping) else []
        if fixed:
            path = cls.config_params[fixed[0]]
            message = f"{fixed[0]} is the configuration's {path}: set it there, not in the tree"
            raise BomcError(message, file, f"{where}.params" if where else "params")
        if not isinstance(params, cls.Params):
            params = from_mapping(cls.Params, params, file, f"{where}.params" if where else "params")
        try:
            cls.resolve_keys(remap)
        except ValueError as exc:
            raise BomcError(str(exc), file, f"{where}.remap" if where else "remap") from None
        return cls(name, params, context, remap)


REGISTRY = Registry()
"""The default registry that behaviour modules add their leaves to."""

register = REGISTRY.register


LEAF_PACKAGE = "behaviours"
"""The package whose import registers the production leaves (the top-level ``behaviours/``)."""


def load_registry(package: str = LEAF_PACKAGE) -> Registry:
    """The default registry once ``package`` has registered its leaves.

    The library never imports the leaves by name (they depend on it, not the other way
    round): a mission names the package that plugs its leaves in, and importing it runs
    their ``@register`` decorators.
    """
    importlib.import_module(package)
    return REGISTRY
