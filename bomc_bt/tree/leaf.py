"""The base class of every leaf in a bomc-bt tree.

A leaf is a thin py_trees behaviour: it reads its inputs from the blackboard, calls
library code (exploration, perception, the robot port) and writes its outputs back.
It declares the blackboard keys it touches by *logical* name (``reads`` / ``writes``)
so a tree file can wire two instances of the same leaf to different blackboard entries
with ``remap: {goal: waypoint_goal}`` without the leaf knowing. Those keys are the leaf's
ports (Nav2's input and output ports): tree files list them in ``ports:`` and the viewer's
blackboard panel shows them. A parameter that is a configuration value (the camera's
expect range) is named in ``config_params``: the leaf reads it from the configuration and a
tree file may not set it, so the value is defined once.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import Any, ClassVar

import py_trees

KEY_PATTERN = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
"""Blackboard key syntax: identifiers joined by ``/`` ('.' is py_trees' nested-attribute access)."""


def read_key(name: str, default: Any = None) -> Any:
    """The value on the blackboard under ``name`` (what the leaves wrote), or ``default``.

    For code outside the tree that reports on a mission (the session report reads the
    ``localized`` key the Relocalize leaf writes).
    """
    try:
        return py_trees.blackboard.Blackboard.get(blackboard_key(name))
    except KeyError:
        return default


def config_value(config: Any, path: str) -> Any:
    """``config.projection.expect_range`` for ``path`` ``"projection.expect_range"``."""
    value = config
    for part in path.split("."):
        value = getattr(value, part)
    return value


def blackboard_key(name: str) -> str:
    """The absolute blackboard key for ``name`` (``goal`` -> ``/goal``); ValueError if malformed."""
    if not isinstance(name, str) or not KEY_PATTERN.match(name):
        raise ValueError(f"{name!r} is not a blackboard key (letters, digits, '_' and '/' separators)")
    return name if name.startswith("/") else "/" + name


@dataclasses.dataclass(frozen=True)
class NoParams:
    """Parameters of a leaf that has none (so ``params:`` must be empty or absent)."""


class Leaf(py_trees.behaviour.Behaviour):
    """Base of all bomc-bt leaves: typed parameters, a mission context, remappable keys.

    Subclasses set ``Params`` (a dataclass the tree file's ``params:`` is validated
    against), ``reads`` and ``writes`` (logical blackboard keys), and implement the usual
    py_trees hooks (``initialise``, ``update``, ``terminate``). ``terminate`` is where a
    leaf cancels work in flight: the runner stops the tree with INVALID on Ctrl-C.
    """

    Params: ClassVar[type] = NoParams
    reads: ClassVar[tuple[str, ...]] = ()
    writes: ClassVar[tuple[str, ...]] = ()
    config_params: ClassVar[dict[str, str]] = {}
    """Parameter field -> dotted configuration path it is read from (never set in a tree file)."""

    def __init__(
        self,
        name: str,
        params: Any = None,
        context: Any = None,
        remap: Mapping[str, str] | None = None,
    ):
        super().__init__(name=name)
        params = self.Params() if params is None else params
        if context is not None and self.config_params:
            values = {name: config_value(context.config, path) for name, path in self.config_params.items()}
            params = dataclasses.replace(params, **values)
        self.params = params
        self.context = context
        self.keys = self.resolve_keys(remap)
        self.blackboard = self.attach_blackboard_client(name=name)
        for key in self.reads:
            self.blackboard.register_key(key, access=py_trees.common.Access.READ, remap_to=self.keys[key])
        for key in self.writes:
            self.blackboard.register_key(key, access=py_trees.common.Access.WRITE, remap_to=self.keys[key])

    @classmethod
    def logical_keys(cls) -> tuple[str, ...]:
        """Every logical key the leaf declares, reads first, without repeats."""
        return tuple(dict.fromkeys((*cls.reads, *cls.writes)))

    @classmethod
    def resolve_keys(cls, remap: Mapping[str, str] | None) -> dict[str, str]:
        """Map each logical key to its absolute blackboard key, applying ``remap``."""
        remap = dict(remap or {})
        unknown = sorted(set(remap) - set(cls.logical_keys()))
        if unknown:
            raise ValueError(
                f"{cls.__name__} has no blackboard key {unknown[0]!r} "
                f"(its keys: {', '.join(cls.logical_keys()) or 'none'})"
            )
        return {key: blackboard_key(remap.get(key, key)) for key in cls.logical_keys()}

    def get(self, key: str, default: Any = None) -> Any:
        """Read logical key ``key``; ``default`` while nothing has been written there yet."""
        self._check_declared(key)
        try:
            return self.blackboard.get(key)
        except KeyError:
            return default

    def set(self, key: str, value: Any) -> None:
        """Write logical key ``key`` (must be listed in ``writes``)."""
        if key not in self.writes:
            raise KeyError(f"{type(self).__name__} does not declare {key!r} in writes")
        self.blackboard.set(key, value, overwrite=True)

    def _check_declared(self, key: str) -> None:
        if key not in self.keys:
            raise KeyError(f"{type(self).__name__} does not declare {key!r} in reads or writes")
