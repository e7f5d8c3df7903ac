"""``loop``: ends by succeeding, ticks like ``repeat`` around a ``sequence`` with memory."""

from __future__ import annotations

import py_trees
import pytest
from py_trees.common import Status

from bomc_bt.errors import BomcError
from bomc_bt.tree.leaf import Leaf
from bomc_bt.tree.loader import load_tree
from bomc_bt.tree.loop import Loop
from bomc_bt.tree.registry import Registry
from bomc_bt.tree.view import kind_of

S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING


class Script(py_trees.behaviour.Behaviour):
    """Returns the next status of its script on each tick (the last one forever) and logs its ticks."""

    def __init__(self, name: str, script: list[Status], log: list[str]):
        super().__init__(name)
        self.script, self.log = list(script), log

    def update(self) -> Status:
        self.log.append(self.name)
        return self.script.pop(0) if len(self.script) > 1 else self.script[0]


def tick(root: py_trees.behaviour.Behaviour, n: int) -> list[Status]:
    out = []
    for _ in range(n):
        root.tick_once()
        out.append(root.status)
    return out


def test_exit_condition_first_is_checked_before_each_iteration_and_its_not_yet_is_not_shown_red():
    log: list[str] = []
    done = Script("Done", [F, F, S], log)
    work = Script("Work", [R, S, S], log)
    loop = Loop("Loop", [done, work], until=[done])
    assert tick(loop, 4) == [R, R, R, S]
    assert log == ["Done", "Work", "Work", "Done", "Work", "Done"]
    assert done.status == S and work.status == Status.INVALID  # the end of a good loop shows no red


def test_the_loop_ticks_like_repeat_around_a_sequence_with_memory():
    """The same statuses, tick by tick, as the ``failure_is_success(repeat(sequence))`` it replaces."""
    go = [R, S, R, R, S]
    old_log: list[str] = []
    old_body = py_trees.composites.Sequence("Visit", True, [Script("Next", [S, S, F], old_log),
                                                           Script("Go", go, old_log)])
    old = py_trees.decorators.FailureIsSuccess("Until Done", py_trees.decorators.Repeat("Each", old_body, -1))
    new_log: list[str] = []
    done = Script("Done", [F, F, S], new_log)
    new = Loop("Loop", [done, Script("Next", [S], new_log), Script("Go", go, new_log)], until=[done])
    assert tick(new, 6) == tick(old, 6) == [R, R, R, R, R, S]
    # the same work in the same ticks; where the old loop ended by a failing Next, Done succeeds
    assert [n for n in new_log if n != "Done"] == old_log[:-1] and old_log[-1] == "Next"


def test_exit_condition_last_ends_the_loop_in_the_tick_its_iteration_ends():
    log: list[str] = []
    over = Script("Over", [F, S], log)
    loop = Loop("Loop", [Script("Step", [S], log), over], until=[over])
    assert tick(loop, 2) == [R, S]
    assert log == ["Step", "Over", "Step", "Over"]


def test_a_failing_body_child_fails_the_loop():
    log: list[str] = []
    done = Script("Done", [F], log)
    loop = Loop("Loop", [done, Script("Bad", [F], log)], until=[done])
    assert tick(loop, 1) == [F]


def test_halting_the_loop_stops_its_running_child():
    log: list[str] = []
    done, work = Script("Done", [F], log), Script("Work", [R], log)
    loop = Loop("Loop", [done, work], until=[done])
    tick(loop, 1)
    assert work.status == R
    loop.stop(Status.INVALID)
    assert work.status == Status.INVALID and loop.status == Status.INVALID


def test_until_must_name_children_of_the_loop():
    with pytest.raises(ValueError, match="until"):
        Loop("L", [Script("A", [S], [])], until=[])


class Succeed(Leaf):
    def update(self) -> Status:
        return Status.SUCCESS


def test_a_tree_file_names_the_exit_conditions_among_the_children(tmp_path):
    registry = Registry()
    registry.add("Succeed", Succeed)
    tree = tmp_path / "t.yaml"
    body = "  children:\n    - {behaviour: Succeed, name: Work}\n    - {behaviour: Succeed, name: Done}\n"
    tree.write_text("version: 1\nroot:\n  loop: L\n  until: [Done]\n" + body)
    root = load_tree(tree, registry, None, clock=lambda: 0.0)
    assert isinstance(root, Loop) and [c.name for c in root.until] == ["Done"]
    tree.write_text("version: 1\nroot:\n  loop: L\n  until: [Dnoe]\n" + body)
    with pytest.raises(BomcError, match=r"root.until\[0\].*'Dnoe' is not a child name"):
        load_tree(tree, registry, None, clock=lambda: 0.0)
    tree.write_text("version: 1\nroot:\n  loop: L\n" + body)
    with pytest.raises(BomcError, match="missing: the names of the children"):
        load_tree(tree, registry, None, clock=lambda: 0.0)


def test_a_loop_is_shown_as_a_loop():
    done = Script("Done", [S], [])
    assert kind_of(Loop("L", [done], until=[done])) == "loop"
