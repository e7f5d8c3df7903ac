"""Behaviour trees from YAML: leaves, the registry, the loader, the runner and views."""

from bomc_bt.tree.action import ActionLeaf
from bomc_bt.tree.decorators import DECORATORS, ClockTimeout
from bomc_bt.tree.leaf import Leaf, NoParams, blackboard_key
from bomc_bt.tree.loader import TreeError, load_tree
from bomc_bt.tree.loop import Loop
from bomc_bt.tree.registry import REGISTRY, Registry, register
from bomc_bt.tree.runner import RunResult, TreeRunner
from bomc_bt.tree.view import TerminalView, render_tree, snapshot, tree_ports

__all__ = [
    "DECORATORS",
    "ActionLeaf",
    "Loop",
    "REGISTRY",
    "ClockTimeout",
    "Leaf",
    "NoParams",
    "Registry",
    "RunResult",
    "TerminalView",
    "TreeError",
    "TreeRunner",
    "blackboard_key",
    "load_tree",
    "register",
    "render_tree",
    "snapshot",
    "tree_ports",
]
