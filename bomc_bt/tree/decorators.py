"""Decorators a tree file can wrap a node in, and the parameters each takes.

Most are py_trees builtins. ``timeout`` is our :class:`ClockTimeout`, because
py_trees' Timeout reads wall time and a mission's time limits must follow the robot
clock (simulated time runs far faster than wall time; ROS time may be paused).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Literal

import py_trees
from py_trees.common import Status

from bomc_bt.tree.leaf import NoParams, blackboard_key

Clock = Callable[[], float]


class ClockTimeout(py_trees.decorators.Decorator):
    """Fail (and stop the child) when the child has run ``duration`` seconds of robot time.

    The deadline is set when the decorator starts (not on every tick) and is checked
    after each tick of the child, as py_trees' own Timeout does, but against ``clock``.
    """

    def __init__(self, name: str, child: py_trees.behaviour.Behaviour, duration: float, clock: Clock):
        super().__init__(name=name, child=child)
        self.duration = duration
        self.clock = clock
        self.deadline = 0.0

    def initialise(self) -> None:
        self.deadline = self.clock() + self.duration
        self.feedback_message = ""

    def update(self) -> Status:
        remaining = self.deadline - self.clock()
        if self.decorated.status == Status.RUNNING and remaining <= 0.0:
            self.feedback_message = f"timed out after {self.duration:g} s"
            self.decorated.stop(Status.INVALID)  # cancel the child's work in flight
            return Status.FAILURE
        if self.decorated.status == Status.RUNNING:
            self.feedback_message = f"{remaining:.1f} s left"
        else:
            self.feedback_message = ""
        return self.decorated.status


def _at_least(minimum: float, message: str) -> Any:
    """A required params field whose value must be >= ``minimum`` (else ``message``)."""
    return dataclasses.field(metadata={"minimum": minimum, "message": message})


class _BoundedParams:
    """Checks every field declared with :func:`_at_least` when the params are built."""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            if "minimum" in f.metadata and getattr(self, f.name) < f.metadata["minimum"]:
                raise ValueError(f"{f.name} {f.metadata['message']}")


@dataclasses.dataclass(frozen=True)
class RetryParams(_BoundedParams):
    """``retry``: re-run the child after a failure, failing on the ``num_failures``-th."""

    num_failures: int = _at_least(1, "must be at least 1")  # [count] failures that make retry fail


@dataclasses.dataclass(frozen=True)
class TimeoutParams(_BoundedParams):
    """``timeout``: fail the child after ``duration`` seconds of robot time."""

    duration: float = _at_least(0.0, "must not be negative")  # [s] robot time the child may run


@dataclasses.dataclass(frozen=True)
class RepeatParams:
    """``repeat``: re-run the child after a success; succeed after ``num_success`` (-1: never)."""

    num_success: int  # [count] successes that end the repeat; -1 repeats forever

    def __post_init__(self) -> None:
        if self.num_success < 1 and self.num_success != -1:
            raise ValueError("num_success must be at least 1, or -1 to repeat forever")


@dataclasses.dataclass(frozen=True)
class OneShotParams:
    """``one_shot``: run the child to completion once, then keep returning that result.

    ``on: success`` latches only a success (a failure may be retried by a later tick);
    ``on: completion`` latches success or failure.
    """

    on: Literal["success", "completion"] = "success"


@dataclasses.dataclass(frozen=True)
class StatusToBlackboardParams:
    """``status_to_blackboard``: write the child's status to blackboard ``key``."""

    key: str

    def __post_init__(self) -> None:
        blackboard_key(self.key)


@dataclasses.dataclass(frozen=True)
class DecoratorEnv:
    """What the loader offers decorator factories: the robot clock and key remapping."""

    clock: Clock
    key: Callable[[str], str]  # a logical key, remapped through the enclosing subtrees


Factory = Callable[[str, py_trees.behaviour.Behaviour, Any, DecoratorEnv], py_trees.decorators.Decorator]


@dataclasses.dataclass(frozen=True)
class DecoratorKind:
    """One decorator a tree file can name: its parameters, factory and default node name."""

    Params: type
    build: Factory
    default_name: str
    summary: str


def _simple(cls: type[py_trees.decorators.Decorator]) -> Factory:
    return lambda name, child, params, env: cls(name=name, child=child)


def _one_shot(name: str, child: py_trees.behaviour.Behaviour, p: OneShotParams, env: DecoratorEnv):
    policy = (
        py_trees.common.OneShotPolicy.ON_SUCCESSFUL_COMPLETION
        if p.on == "success"
        else py_trees.common.OneShotPolicy.ON_COMPLETION
    )
    return py_trees.decorators.OneShot(name=name, child=child, policy=policy)


def _status_to_blackboard(name, child, p: StatusToBlackboardParams, env: DecoratorEnv):
    return py_trees.decorators.StatusToBlackboard(name=name, child=child, variable_name=env.key(p.key))


STATUS_MAPS = ("failure_is_success", "failure_is_running", "success_is_failure", "success_is_running",
               "running_is_failure", "running_is_success")
"""py_trees' status-mapping decorators: ``a_is_b`` reports the child's status A as B."""


def _status_map(key: str) -> DecoratorKind:
    """``failure_is_success`` -> py_trees' FailureIsSuccess, named "Failure Is Success"."""
    title = key.replace("_", " ").title()
    before, _, after = key.partition("_is_")
    decorator = getattr(py_trees.decorators, title.replace(" ", ""))
    return DecoratorKind(NoParams, _simple(decorator), title, f"{before.upper()} -> {after.upper()}")


DECORATORS: dict[str, DecoratorKind] = {
    "retry": DecoratorKind(
        RetryParams,
        lambda name, child, p, env: py_trees.decorators.Retry(name, child, p.num_failures),
        "Retry",
        "RUNNING after each of the first num_failures - 1 failures, so the child is re-run",
    ),
    "repeat": DecoratorKind(
        RepeatParams,
        lambda name, child, p, env: py_trees.decorators.Repeat(name, child, p.num_success),
        "Repeat",
        "RUNNING after each success until num_success successes; a failure fails",
    ),
    "timeout": DecoratorKind(
        TimeoutParams,
        lambda name, child, p, env: ClockTimeout(name, child, p.duration, env.clock),
        "Timeout",
        "FAILURE (child stopped) once the child has run duration robot-clock seconds",
    ),
    "one_shot": DecoratorKind(OneShotParams, _one_shot, "One Shot", "run to completion once, then latch"),
    "status_to_blackboard": DecoratorKind(
        StatusToBlackboardParams, _status_to_blackboard, "Status To Blackboard", "write child status to key"
    ),
    "inverter": DecoratorKind(
        NoParams, _simple(py_trees.decorators.Inverter), "Inverter", "swap SUCCESS and FAILURE"
    ),
    **{key: _status_map(key) for key in STATUS_MAPS},
}
"""Decorator names usable in tree files (``retry: {num_failures: 3}`` + ``child:``)."""
