"""JSON text written as is: progress values a pass encodes itself, cheaper than re-encoding.

A monitor pass commits a resume point with every frame (:mod:`bomc_bt.pass_resume`); it
carries every view polygon since the last waypoint, so encoding the whole point anew each
frame grew with the frames since the waypoint (on a 50 x 45 m office the two polygon lists
were 64 KB a frame and their encoding the largest single cost of the pass). The lists only
grow, so each polygon is encoded once (:class:`AppendOnlyJSON`) and the point is joined
from its parts (:class:`EncodedJSON`), byte for byte the text ``json.dumps`` would write.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def to_jsonable(value: Any) -> Any:
    """``json.dumps``'s ``default`` for what the store saves: arrays as lists, numpy scalars
    as numbers, anything else as its text."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def dumps(value: Any) -> str:
    """The store's encoding of one value (``json.dumps`` with :func:`to_jsonable`)."""
    return json.dumps(value, default=to_jsonable)


@dataclass(frozen=True)
class EncodedJSON:
    """A value already encoded: the store writes ``text`` unchanged."""

    text: str


def encoded_object(parts: dict[str, str]) -> EncodedJSON:
    """The JSON object of already encoded member values, in order, as ``json.dumps`` writes it."""
    return EncodedJSON("{" + ", ".join(f"{json.dumps(k)}: {v}" for k, v in parts.items()) + "}")


@dataclass
class AppendOnlyJSON:
    """The JSON text of a list that is only appended to, each item encoded once.

    A different list object (the pass starts a new one at each waypoint, a resume puts
    back a saved one) or a shorter one starts the encoding afresh; items already encoded
    must not change in place (the pass appends fresh lists of floats only)."""

    _items: list | None = field(default=None, repr=False)
    _parts: list[str] = field(default_factory=list, repr=False)

    def text(self, items: list) -> str:
        if items is not self._items or len(items) < len(self._parts):
            self._items, self._parts = items, []
        self._parts.extend(dumps(item) for item in items[len(self._parts):])
        return "[" + ", ".join(self._parts) + "]"
