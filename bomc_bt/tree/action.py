"""The base class of leaves that drive the robot (Nav2's ``bt_action_node``).

An action leaf sends one request to the robot port (navigate, relocalize, turn the head)
and polls its :class:`~bomc_bt.robot.Handle` once per tick. The base class owns what every
such leaf must get right the same way: the request is sent when the leaf starts, the
deadline is kept on the *robot* clock (never wall time), a request still in flight when
the deadline passes is cancelled, and a leaf halted by the tree (a higher-priority branch
took over, a timeout decorator, Ctrl-C: ``terminate(INVALID)``) cancels its request so
the robot does not keep driving for nobody. Subclasses say what to send and what each
outcome means:

- :meth:`send` the request (None: nothing was sent, :meth:`idle` decides);
- :meth:`on_success`, :meth:`on_failure`, :meth:`on_timeout`, :meth:`on_running`;
- :meth:`before_poll` for a check that comes before the handle is read (time is up);
- :meth:`timeout` the robot-clock seconds one request may take (None: no limit).
"""

from __future__ import annotations

import abc
import math

from py_trees.common import Status

from bomc_bt.robot import Handle
from bomc_bt.robot import Status as Request
from bomc_bt.tree.leaf import Leaf


class ActionLeaf(Leaf, metaclass=abc.ABCMeta):
    """A leaf that sends a robot request on start, polls it each tick and cancels it when halted."""

    handle: Handle | None = None
    deadline: float = math.inf

    @abc.abstractmethod
    def send(self) -> Handle | None:
        """Start the request (called when the leaf starts)."""

    def label(self) -> str:
        """What the feedback messages start with ("local: no answer within 60 s"); "" for nothing."""
        return ""

    def say(self, text: str) -> None:
        """Set the feedback message, after :meth:`label` where there is one."""
        label = self.label()
        self.feedback_message = f"{label}: {text}" if label else text

    def timeout(self) -> float | None:
        """Robot-clock seconds the request may take; None: no limit."""
        return None

    def before_poll(self) -> Status | None:
        """A status that ends this tick before the handle is read, or None to poll it."""
        return None

    def idle(self) -> Status:
        """The tick's status while no request is in flight (:meth:`send` returned None)."""
        self.feedback_message = "nothing to do"
        return Status.SUCCESS

    def on_success(self) -> Status:
        return Status.SUCCESS

    def on_failure(self, status: Request) -> Status:
        """The request ended without success (failed, blocked, cancelled)."""
        self.say(f"{status.value}: {self.handle.message}")
        return Status.FAILURE

    def on_timeout(self) -> Status:
        """The deadline passed with the request in flight (it was cancelled)."""
        self.say(f"no answer within {self.timeout():.0f} s")
        return Status.FAILURE

    def on_running(self) -> Status:
        return Status.RUNNING

    def initialise(self) -> None:
        self.handle = self.send()
        limit = self.timeout()
        self.deadline = math.inf if limit is None else self.context.now() + limit

    def update(self) -> Status:
        early = self.before_poll()
        if early is not None:
            return early
        if self.handle is None:
            return self.idle()
        status = self.handle.status()
        if status is Request.SUCCEEDED:
            return self.on_success()
        if status.done:
            return self.on_failure(status)
        if self.context.now() >= self.deadline:
            self.handle.cancel()
            return self.on_timeout()
        return self.on_running()

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.handle is not None and not self.handle.status().done:
            self.handle.cancel()
