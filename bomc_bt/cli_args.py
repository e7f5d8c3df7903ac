"""Range-checked argument types of the command line: a bad number is refused by the parser.

argparse calls these on the text the user typed; an ``ArgumentTypeError`` becomes the
one ``bomc: error: argument --seed: ...`` line and exit 2, before any file is touched.
The bounds are what the values can mean: numpy seeds are unsigned 32-bit here, ports are
TCP ports, session numbers are small positive integers (the site bounds them further:
:func:`bomc_bt.run.check_session`).
"""

from __future__ import annotations

import argparse

from bomc_bt.world.timeline import MAX_SESSION

MAX_SEED = 2**32 - 1


def _integer(text: str, low: int, high: int, what: str) -> int:
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(f"must be {low} to {high} ({what}), got {value}")
    return value


def seed(text: str) -> int:
    return _integer(text, 0, MAX_SEED, "a random seed")


def port(text: str) -> int:
    return _integer(text, 0, 65535, "a TCP port; 0: any free one")


def session(text: str) -> int:
    return _integer(text, 1, MAX_SESSION, "a session number")


def session_count(text: str) -> int:
    return _integer(text, 1, 1000, "a number of sessions")


def budget(text: str) -> float:
    """``bomc monitor --budget``: seconds of robot time, positive and finite."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds of robot time, got {text!r}") from None
    if not 0 < value <= 1e7:  # also refuses nan and inf
        raise argparse.ArgumentTypeError(f"must be more than 0 and at most 1e7 seconds, got {text}")
    return value
