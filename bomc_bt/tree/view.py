"""What a running tree looks like: a live terminal view and a JSON-able snapshot.

:class:`TerminalView` is an ``on_tick`` hook for :class:`~bomc_bt.tree.runner.TreeRunner`.
On a terminal it redraws the tree in place (statuses and feedback messages) plus a
progress line, at most every ``interval_wall_s`` of wall time: wall time is used only
to spare the terminal, never to decide anything. When the output is a file or a pipe
(a log), it prints just the progress line every ``interval_sim_s`` robot seconds.
"""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

import py_trees
from py_trees.common import Status

from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.loop import Loop

SYMBOLS = {Status.SUCCESS: "✔", Status.FAILURE: "✕", Status.RUNNING: "●", Status.INVALID: "·"}


def kind_of(node: py_trees.behaviour.Behaviour) -> str:
    """The node's kind as a tree file spells it: sequence, selector, parallel, loop, decorator, behaviour."""
    if isinstance(node, Loop):
        return "loop"
    if isinstance(node, py_trees.composites.Sequence):
        return "sequence"
    if isinstance(node, py_trees.composites.Selector):
        return "selector"
    if isinstance(node, py_trees.composites.Parallel):
        return "parallel"
    if isinstance(node, py_trees.decorators.Decorator):
        return "decorator"
    return "behaviour"


def snapshot(root: py_trees.behaviour.Behaviour) -> dict[str, Any]:
    """The tree as nested plain dicts (name, kind, type, status, feedback, children)."""
    return {
        "name": root.name,
        "kind": kind_of(root),
        "type": type(root).__name__,
        "status": root.status.value.lower(),
        "feedback": root.feedback_message,
        "children": [snapshot(child) for child in root.children],
    }


def tree_ports(root: py_trees.behaviour.Behaviour) -> dict[str, dict[str, list[str]]]:
    """Blackboard key -> the names of the leaves that read and write it (the tree's data flow)."""
    ports: dict[str, dict[str, list[str]]] = {}
    for node in root.iterate():
        if isinstance(node, Leaf):
            for kind, logical in (("reads", node.reads), ("writes", node.writes)):
                for key in logical:
                    ports.setdefault(node.keys[key], {"reads": [], "writes": []})[kind].append(node.name)
    return ports


def render_tree(root: py_trees.behaviour.Behaviour, width: int | None = None) -> list[str]:
    """One line per node: indentation, status symbol, name, kind, feedback message."""
    lines: list[str] = []

    def visit(node: py_trees.behaviour.Behaviour, depth: int) -> None:
        kind = kind_of(node)
        label = kind if kind != "behaviour" else type(node).__name__
        line = f"{'  ' * depth}{SYMBOLS[node.status]} {node.name} [{label}]"
        if node.feedback_message:
            line += f" - {node.feedback_message}"
        if width is not None and len(line) > width:
            line = line[: max(width - 1, 0)] + "…"
        lines.append(line)
        for child in node.children:
            visit(child, depth + 1)

    visit(root, 0)
    return lines


class TerminalView:
    """The live view of a run; call it on every tick, then :meth:`close` once."""

    def __init__(
        self,
        stream: TextIO | None = None,
        interval_wall_s: float = 0.2,
        progress: Callable[[], str] | None = None,
        *,
        interval_sim_s: float = 10.0,
        tty: bool | None = None,
        wall_clock: Callable[[], float] = time.monotonic,
    ):
        self.stream = stream if stream is not None else sys.stdout
        self.interval_wall_s = interval_wall_s
        self.interval_sim_s = interval_sim_s
        self.progress = progress
        self.tty = tty if tty is not None else self.stream.isatty()
        self.wall_clock = wall_clock
        self.root: py_trees.behaviour.Behaviour | None = None
        self._drawn_lines = 0
        self._last_wall: float | None = None
        self._next_sim: float | None = None

    def __call__(self, runner: Any) -> None:
        """The on_tick hook: ``runner`` has ``root`` and ``robot.now()``."""
        self.root = runner.root
        if self.tty:
            now = self.wall_clock()
            if self._last_wall is None or now - self._last_wall >= self.interval_wall_s:
                self._last_wall = now
                self._redraw(self._frame(runner.root))
            return
        sim_now = runner.robot.now()
        if self._next_sim is None or sim_now >= self._next_sim:
            self._next_sim = sim_now + self.interval_sim_s
            if self.progress is not None:
                self.stream.write(f"[{sim_now:9.1f} s] {self.progress()}\n")
                self.stream.flush()

    def close(self, root: py_trees.behaviour.Behaviour | None = None) -> None:
        """Print the final tree (and progress) once, replacing the live view on a terminal."""
        root = root if root is not None else self.root
        if root is None:
            return
        lines = self._frame(root)
        if self.tty:
            self._redraw(lines)
        else:
            self.stream.write("\n".join(lines) + "\n")
            self.stream.flush()
        self._drawn_lines = 0

    def _frame(self, root: py_trees.behaviour.Behaviour) -> list[str]:
        width = shutil.get_terminal_size().columns if self.tty else None
        lines = render_tree(root, width)
        if self.progress is not None:
            line = self.progress()
            lines.append(line if width is None or len(line) <= width else line[: width - 1] + "…")
        return lines

    def _redraw(self, lines: list[str]) -> None:
        # move to the first line of the previous frame and clear to the end of the screen
        erase = f"\x1b[{self._drawn_lines}F\x1b[J" if self._drawn_lines else ""
        self.stream.write(erase + "\n".join(lines) + "\n")
        self.stream.flush()
        self._drawn_lines = len(lines)
