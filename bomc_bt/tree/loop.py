"""``loop``: run children in order, again and again, until an exit condition succeeds.

py_trees' only loop, ``Repeat``, goes on after each success, so a loop over a plan had to
end by *failing* (the step that finds nothing left fails, a ``failure_is_success`` turns
the failure into the loop's success) and a pass that went perfectly showed half its tree
red. A :class:`Loop` ends by succeeding: some children are its exit conditions
(``until``); one of them succeeding ends the loop with SUCCESS, one failing means "not
yet" (it is reset, so the viewer shows no red) and the loop goes on with the next child.
Any other child failing fails the loop: red means a real failure.

Timing matches ``repeat`` around a ``sequence`` with memory: a child RUNNING resumes on
the next tick, and once the last child succeeds the next iteration starts on the next tick.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import py_trees
from py_trees.common import Status

Node = py_trees.behaviour.Behaviour


class Loop(py_trees.composites.Composite):
    """Iterates over its children like a sequence with memory until an ``until`` child succeeds."""

    def __init__(self, name: str, children: Sequence[Node], until: Sequence[Node]):
        super().__init__(name, list(children))
        missing = [c.name for c in until if c not in self.children]
        if missing or not until:
            raise ValueError(f"until must name children of the loop, not {missing or 'nothing'}")
        self.until = list(until)

    def tick(self) -> Iterator[Node]:
        if self.status != Status.RUNNING or self.current_child is None:
            for child in self.children:  # a new iteration starts from the first child
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            if self.status != Status.RUNNING:
                self.initialise()
            self.current_child = self.children[0]
        index = self.children.index(self.current_child)
        for child in self.children[index:]:
            self.current_child = child
            yield from child.tick()
            status = child.status
            if child in self.until and status == Status.SUCCESS:
                self.stop(Status.SUCCESS)
                yield self
                return
            if child in self.until and status == Status.FAILURE:
                child.stop(Status.INVALID)  # "not yet": go on with the loop
                continue
            if status != Status.SUCCESS:
                if status == Status.RUNNING:
                    self.status = Status.RUNNING
                else:
                    self.stop(status)
                yield self
                return
        self.current_child = None  # iteration done: the next one starts on the next tick
        self.status = Status.RUNNING
        yield self
