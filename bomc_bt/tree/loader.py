"""Load a tree file (YAML, format version 1) into a py_trees tree.

A tree file names a ``root`` node and may define ``subtrees`` and ``include`` other
files for theirs; the format is documented in ``trees/README.md``. Every mistake in
a file is a :class:`BomcError` naming the file and the node path
(``trees/build.yaml: root.children[1].child: unknown behaviour 'SaveMapp' ...``): a
tree file is user input, so no other exception may escape :func:`load_tree`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import py_trees
from py_trees.common import ParallelPolicy

from bomc_bt.errors import BomcError
from bomc_bt.params import from_mapping
from bomc_bt.tree.decorators import DECORATORS, DecoratorEnv
from bomc_bt.tree.leaf import blackboard_key
from bomc_bt.tree.loop import Loop
from bomc_bt.tree.registry import Registry
from bomc_bt.tree.spec import as_list, check_keys, check_ports, describe, is_file, node_name, remap_spec
from bomc_bt.yaml_io import read_yaml

Node = py_trees.behaviour.Behaviour
TreeError = BomcError
"""Errors in tree files are ordinary BomcErrors (one line: file, node path, message)."""

FORMAT_VERSION = 1
MAX_DEPTH = 64  # deeper is a mistake (or a recursive YAML alias), not a mission
MAX_NODES = 10_000  # bounds the work an alias-heavy file can cause

COMPOSITES = ("sequence", "selector", "parallel", "loop")
NODE_KINDS = ("behaviour", "subtree", *COMPOSITES, *DECORATORS)
FILE_KEYS = ("version", "name", "description", "values", "include", "subtrees", "root")
PARALLEL_POLICIES = ("success_on_all", "success_on_one", "success_on_selected")


def load_tree(
    path: str | Path,
    registry: Registry,
    context: Any,
    clock: Callable[[], float],
    extra_search_paths: Iterable[str | Path] = (),
    require_ports: bool = False,
) -> Node:
    """Build the tree in ``path``; leaves get ``context``, timeouts read ``clock``.

    Included files are looked up next to the including file, then in
    ``extra_search_paths`` (e.g. the installed ``share/bomc-bt/trees``). A leaf's
    ``ports:`` is always checked against the keys it declares; ``require_ports`` also
    makes it mandatory for every leaf that has keys (the shipped trees list them all).
    """
    builder = _Builder(registry, context, clock, [Path(p) for p in extra_search_paths], require_ports)
    try:
        return builder.build_file(Path(path))
    except RecursionError:
        raise BomcError("the tree is nested too deeply", path) from None


@dataclasses.dataclass(frozen=True)
class _Definition:
    """A named subtree: its YAML node and where it was written."""

    spec: Any
    file: Path
    where: str


@dataclasses.dataclass
class _Frame:
    """A ``subtree:`` reference being built: its remap and the keys its leaves used."""

    remap: dict[str, str]
    used: set[str] = dataclasses.field(default_factory=set)


class _Builder:
    """Reads the files, then turns YAML nodes into behaviours, tracking node paths."""

    def __init__(self, registry: Registry, context: Any, clock: Callable[[], float], search: list[Path],
                 require_ports: bool = False):
        self.require_ports = require_ports
        self.registry = registry
        self.context = context
        self.clock = clock
        self.search = search
        self.subtrees: dict[str, _Definition] = {}
        self.loaded: set[Path] = set()
        self.frames: list[_Frame] = []
        self.active: list[str] = []  # subtree references being expanded (cycle check)
        self.referenced: set[str] = set()
        self.nodes = 0

    # ----------------------------------------------------------------- files

    def build_file(self, path: Path) -> Node:
        data = self.read_file(path, chain=())
        if "root" not in data:
            raise BomcError("missing (the node the mission starts from)", path, "root")
        root = self.node(data["root"], path, "root", depth=0)
        self.check_unreferenced()
        return root

    def read_file(self, path: Path, chain: tuple[Path, ...]) -> dict:
        """Parse ``path``, load its includes, register its subtrees; returns its mapping."""
        data = read_yaml(path, "tree file")
        if not isinstance(data, dict):
            raise BomcError(f"a tree file must be a mapping, got {describe(data)}", path)
        for key in data:
            if key not in FILE_KEYS:
                raise BomcError(f"unknown key (expected one of: {', '.join(FILE_KEYS)})", path, str(key))
        version = data.get("version", FORMAT_VERSION)
        if version != FORMAT_VERSION or isinstance(version, bool):
            raise BomcError(f"unsupported format version {version!r} (this is version 1)", path, "version")
        for key in ("name", "description"):
            if key in data and not isinstance(data[key], str):
                raise BomcError(f"must be a string, got {describe(data[key])}", path, key)
        if not isinstance(data.get("values", {}), dict):  # named values, used through YAML anchors
            raise BomcError(f"must be a mapping of name: value, got {describe(data['values'])}", path, "values")
        resolved = path.resolve()
        self.loaded.add(resolved)
        for i, include in enumerate(as_list(data.get("include"), path, "include")):
            self.include(include, path, f"include[{i}]", (*chain, resolved))
        subtrees = data.get("subtrees") or {}
        if not isinstance(subtrees, dict):
            raise BomcError(f"must be a mapping of name: node, got {describe(subtrees)}", path, "subtrees")
        for name, spec in subtrees.items():
            self.define(name, spec, path)
        return data

    def include(self, name: Any, path: Path, where: str, chain: tuple[Path, ...]) -> None:
        if not isinstance(name, str) or not name:
            raise BomcError(f"must be a file name, got {describe(name)}", path, where)
        candidates = [path.parent / name, *(base / name for base in self.search)]
        found = next((c for c in candidates if is_file(c)), None)
        if found is None:
            looked = ", ".join(str(c.parent) for c in candidates)
            raise BomcError(f"include file {name!r} not found (looked in: {looked})", path, where)
        resolved = found.resolve()
        if resolved in chain:
            cycle = " -> ".join(p.name for p in (*chain[chain.index(resolved):], resolved))
            raise BomcError(f"include cycle: {cycle}", path, where)
        if resolved not in self.loaded:  # a file included twice (diamond) is read once
            self.read_file(found, chain)

    def define(self, name: Any, spec: Any, path: Path) -> None:
        if not isinstance(name, str) or not name:
            raise BomcError(f"subtree names must be strings, got {describe(name)}", path, "subtrees")
        where = f"subtrees.{name}"
        if name in self.subtrees:
            first = self.subtrees[name].file
            raise BomcError(f"subtree {name!r} is already defined in {first}", path, where)
        self.subtrees[name] = _Definition(spec, path, where)

    def check_unreferenced(self) -> None:
        """Build (and discard) subtrees no reference reached, so their mistakes show now."""
        for name in sorted(set(self.subtrees) - self.referenced):
            definition = self.subtrees[name]
            self.active = [name]
            node = self.node(definition.spec, definition.file, definition.where, depth=1)
            for behaviour in node.iterate():
                for client in behaviour.blackboards:
                    _unregister(client)
        self.active = []

    # ----------------------------------------------------------------- nodes

    def node(self, spec: Any, file: Path, where: str, depth: int) -> Node:
        if depth > MAX_DEPTH:
            raise BomcError(f"nested deeper than {MAX_DEPTH} levels", file, where)
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise BomcError(f"more than {MAX_NODES} nodes", file, where)
        if not isinstance(spec, dict):
            raise BomcError(f"expected a node (a mapping), got {describe(spec)}", file, where)
        kinds = [key for key in spec if key in NODE_KINDS]
        if not kinds:
            unknown = [k for k in spec if k not in ("name", "children", "child", "params", "remap", "memory", "ports")]
            hint = f"unknown key {unknown[0]!r}; " if unknown else ""
            raise BomcError(
                f"{hint}a node needs one of: behaviour, subtree, {', '.join(COMPOSITES)}, "
                f"or a decorator ({', '.join(DECORATORS)})",
                file,
                where,
            )
        if len(kinds) > 1:
            message = f"a node is exactly one kind, this one has {kinds[0]!r} and {kinds[1]!r}"
            raise BomcError(message, file, where)
        kind = kinds[0]
        if kind == "behaviour":
            return self.leaf(spec, file, where)
        if kind == "subtree":
            return self.reference(spec, file, where, depth)
        if kind in COMPOSITES:
            return self.composite(kind, spec, file, where, depth)
        return self.decorator(kind, spec, file, where, depth)

    def leaf(self, spec: dict, file: Path, where: str) -> Node:
        check_keys(spec, ("behaviour", "name", "params", "remap", "ports"), file, where)
        behaviour = spec["behaviour"]
        if not isinstance(behaviour, str):
            raise BomcError(f"must name a behaviour, got {describe(behaviour)}", file, f"{where}.behaviour")
        if behaviour not in self.registry:
            known = ", ".join(self.registry.names()) or "none registered"
            raise BomcError(f"unknown behaviour {behaviour!r} (known: {known})", file, where)
        name = node_name(spec.get("name", behaviour), file, where)
        remap = remap_spec(spec.get("remap"), file, f"{where}.remap")
        cls = self.registry.get(behaviour)
        unknown = sorted(set(remap) - set(cls.logical_keys()))
        if unknown:
            keys = ", ".join(cls.logical_keys()) or "none"
            message = f"{behaviour} has no blackboard key {unknown[0]!r} (its keys: {keys})"
            raise BomcError(message, file, f"{where}.remap")
        self.ports(spec, cls, remap, file, where)
        resolved = {key: self.key(remap.get(key, key)) for key in cls.logical_keys()}
        params = spec.get("params")
        return self.registry.create(behaviour, name, params, self.context, resolved, file=file, where=where)

    def ports(self, spec: dict, cls: type, remap: dict[str, str], file: Path, where: str) -> None:
        """Check the leaf's ``ports:`` (required with ``require_ports`` when it has keys)."""
        reads = tuple(remap.get(k, k) for k in cls.reads)
        writes = tuple(remap.get(k, k) for k in cls.writes)
        if "ports" in spec or (self.require_ports and (reads or writes)):
            check_ports(spec.get("ports"), reads, writes, file, f"{where}.ports")

    def reference(self, spec: dict, file: Path, where: str, depth: int) -> Node:
        check_keys(spec, ("subtree", "name", "remap"), file, where)
        target = spec["subtree"]
        if not isinstance(target, str):
            raise BomcError(f"must name a subtree, got {describe(target)}", file, f"{where}.subtree")
        if target not in self.subtrees:
            known = ", ".join(sorted(self.subtrees)) or "none defined"
            raise BomcError(f"unknown subtree {target!r} (defined: {known})", file, where)
        if target in self.active:
            cycle = " -> ".join([*self.active[self.active.index(target):], target])
            raise BomcError(f"subtree cycle: {cycle}", file, where)
        name = node_name(spec["name"], file, where) if "name" in spec else None
        frame = _Frame(remap_spec(spec.get("remap"), file, f"{where}.remap"))
        definition = self.subtrees[target]
        self.referenced.add(target)
        self.active.append(target)
        self.frames.append(frame)
        try:
            node = self.node(definition.spec, definition.file, definition.where, depth + 1)
        finally:
            self.frames.pop()
            self.active.pop()
        unused = sorted(set(frame.remap) - frame.used)
        if unused:
            used = ", ".join(sorted(frame.used)) or "none"
            message = f"subtree {target!r} uses no blackboard key {unused[0]!r} (it uses: {used})"
            raise BomcError(message, file, f"{where}.remap")
        if name is not None:
            node.name = name
            node.qualified_name = f"{type(node).__qualname__}/{name}"
        return node

    def composite(self, kind: str, spec: dict, file: Path, where: str, depth: int) -> Node:
        extra = {"parallel": ("policy", "synchronise", "selected"), "loop": ("until",)}.get(kind, ("memory",))
        check_keys(spec, (kind, "children", *extra), file, where)
        name = node_name(spec[kind], file, where)
        children = self.children(spec, file, where, depth)
        if kind == "loop":
            until = self.named_children(spec, "until", children, file, where)
            return Loop(name=name, children=children, until=until)
        if kind == "parallel":
            policy = self.policy(spec, children, file, where)
            return py_trees.composites.Parallel(name=name, policy=policy, children=children)
        if "memory" not in spec:
            raise BomcError(
                f"missing: a {kind} must say 'memory: true' (resume at the running child) or "
                f"'memory: false' (start again from the first child on every tick); py_trees 2 requires it",
                file,
                f"{where}.memory",
            )
        memory = spec["memory"]
        if not isinstance(memory, bool):
            raise BomcError(f"must be true or false, got {describe(memory)}", file, f"{where}.memory")
        cls = py_trees.composites.Sequence if kind == "sequence" else py_trees.composites.Selector
        return cls(name=name, memory=memory, children=children)

    def children(self, spec: dict, file: Path, where: str, depth: int) -> list[py_trees.behaviour.Behaviour]:
        if "children" not in spec:
            raise BomcError("missing (a list of nodes)", file, f"{where}.children")
        items = spec["children"]
        if not isinstance(items, list) or not items:
            message = f"must be a non-empty list of nodes, got {describe(items)}"
            raise BomcError(message, file, f"{where}.children")
        children = []
        seen: dict[str, int] = {}
        for i, item in enumerate(items):
            child = self.node(item, file, f"{where}.children[{i}]", depth + 1)
            if child.name in seen:
                raise BomcError(
                    f"duplicate name {child.name!r} (also children[{seen[child.name]}]); "
                    "give one of them a distinct 'name:'",
                    file,
                    f"{where}.children[{i}]",
                )
            seen[child.name] = i
            children.append(child)
        return children

    def policy(self, spec: dict, children: list, file: Path, where: str) -> ParallelPolicy.Base:
        policy = spec.get("policy")
        if policy not in PARALLEL_POLICIES:
            got = "missing" if "policy" not in spec else f"got {describe(policy)}"
            raise BomcError(f"must be one of {', '.join(PARALLEL_POLICIES)} ({got})", file, f"{where}.policy")
        synchronise = spec.get("synchronise", True)
        if not isinstance(synchronise, bool):
            message = f"must be true or false, got {describe(synchronise)}"
            raise BomcError(message, file, f"{where}.synchronise")
        if policy == "success_on_one" and "synchronise" in spec:
            raise BomcError("does not apply to success_on_one", file, f"{where}.synchronise")
        if policy != "success_on_selected":
            if "selected" in spec:
                raise BomcError("only applies to policy success_on_selected", file, f"{where}.selected")
            if policy == "success_on_one":
                return ParallelPolicy.SuccessOnOne()
            return ParallelPolicy.SuccessOnAll(synchronise=synchronise)
        selected = self.named_children(spec, "selected", children, file, where)
        return ParallelPolicy.SuccessOnSelected(children=selected, synchronise=synchronise)

    def named_children(self, spec: dict, key: str, children: list, file: Path, where: str) -> list[Node]:
        """The children named in ``spec[key]`` (a parallel's ``selected``, a loop's ``until``)."""
        by_name = {child.name: child for child in children}
        names = as_list(spec.get(key), file, f"{where}.{key}")
        if not names:
            raise BomcError(f"missing: the names of the children ({key})", file, f"{where}.{key}")
        for i, name in enumerate(names):
            if not isinstance(name, str) or name not in by_name:
                raise BomcError(
                    f"{describe(name)} is not a child name (children: {', '.join(by_name)})",
                    file,
                    f"{where}.{key}[{i}]",
                )
        return [by_name[n] for n in dict.fromkeys(names)]

    def decorator(self, kind: str, spec: dict, file: Path, where: str, depth: int) -> Node:
        if "children" in spec:
            message = "a decorator wraps exactly one 'child:', not 'children:'"
            raise BomcError(message, file, f"{where}.children")
        check_keys(spec, (kind, "name", "child"), file, where)
        decorator = DECORATORS[kind]
        params = from_mapping(decorator.Params, spec[kind], file, f"{where}.{kind}")
        name = node_name(spec.get("name", decorator.default_name), file, where)
        if "child" not in spec:
            raise BomcError(f"missing: {kind} wraps exactly one node", file, f"{where}.child")
        item = spec["child"]
        if isinstance(item, list):
            message = f"a decorator wraps exactly one node, got a list of {len(item)}"
            raise BomcError(message, file, f"{where}.child")
        child = self.node(item, file, f"{where}.child", depth + 1)
        return decorator.build(name, child, params, DecoratorEnv(clock=self.clock, key=self.key))

    def key(self, name: str) -> str:
        """Remap a key through the enclosing subtree references, innermost first."""
        key = name.lstrip("/")
        for frame in reversed(self.frames):
            frame.used.add(key)
            key = frame.remap.get(key, key)
        return blackboard_key(key)


def _unregister(client: py_trees.blackboard.Client) -> None:
    """Unregister ``client``, each of its keys once, leaving the stored values.

    ``Client.unregister`` walks its read, write and exclusive keys one set after the other and
    fails with a KeyError on a key in two of them (FindDetour reads and writes
    ``detours_tried``): the first pass already dropped it. A user's tree that includes
    traverse.yaml without using its ``traverse`` subtree stopped with that traceback.
    """
    for key in set(client.read) | set(client.write) | set(client.exclusive):
        client.unregister_key(key, clear=False, update_namespace_cache=False)
    del py_trees.blackboard.Blackboard.clients[client.unique_identifier]
