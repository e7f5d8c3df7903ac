"""JSON text written as is: progress values a pass encodes itself, cheaper than re-encoding.

A monitor pass commits a resume point with every frame (:mod:`bomc_bt.pass_resume`); it
carries every view polygon since the last waypoint, so encoding the whole point anew each
frame grew with the frames since the waypoint (on a 50 x 45 m office the two polygon lists
were 64 KB a frame and their encoding the largest single cost of the pass). The lists only
grow, so each polygon is encoded once (:class:`AppendOnlyJSON`), the graph's maps keep the
text of each entry that did not change (:class:`JSONMemo`), and the values are joined from
their parts (:class:`EncodedJSON`), byte for byte the text ``json.dumps`` would write. The
store writes only the parts of the point that changed (:mod:`bomc_bt.resume_rows`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
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
    if isinstance(value, EncodedJSON):
        raise TypeError("encoded JSON text is written by dumps_raw, as a dict's value")
    return str(value)


def dumps(value: Any) -> str:
    """The store's encoding of one value (``json.dumps`` with :func:`to_jsonable`)."""
    return json.dumps(value, default=to_jsonable)


@dataclass(frozen=True)
class EncodedJSON:
    """A value already encoded: the store writes ``text`` unchanged."""

    text: str


@dataclass(frozen=True)
class Dropped:
    """A progress value that deletes its row instead of writing one (a resume point's part
    no longer in it, :mod:`bomc_bt.resume_rows`)."""


DROP = Dropped()


@dataclass
class AppendOnlyJSON:
    """The JSON text of a list that is only appended to, each item encoded once.

    A different list object (the pass starts a new one at each waypoint, a resume puts
    back a saved one) or a shorter one starts the encoding afresh; items already encoded
    must not change in place (the pass appends fresh lists of floats only)."""

    _items: list | None = field(default=None, repr=False)
    _parts: list[str] = field(default_factory=list, repr=False)

    def text(self, items: list, value: Callable[[Any], Any] | None = None) -> str:
        """``dumps([value(v) for v in items])`` (``value`` None: the items as they are)."""
        return "[" + ", ".join(self.parts(items, value)) + "]"

    def parts(self, items: list, value: Callable[[Any], Any] | None = None) -> list[str]:
        """Each item's text, ``dumps(value(v))``, in order (kept by the encoder: read, never change it)."""
        if items is not self._items or len(items) < len(self._parts):
            self._items, self._parts = items, []
        self._parts.extend(dumps(item if value is None else value(item)) for item in items[len(self._parts):])
        return self._parts


def dumps_raw(value: Any) -> str:
    """:func:`dumps` of ``value`` whose dicts may hold :class:`EncodedJSON` values (written as
    they are); the same text ``dumps`` gives for the plain value they encode."""
    if isinstance(value, EncodedJSON):
        return value.text
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {dumps_raw(v)}" for k, v in value.items()) + "}"
    return dumps(value)


def _same(old: Any, new: Any) -> bool:
    """``new`` writes as ``old`` did: the same object, or an equal float (not a zero: -0.0)."""
    return old is new or (type(old) is float and type(new) is float and old == new and new != 0.0)


class JSONMemo:
    """The JSON text of named maps and lists that change a few entries at a time, each
    entry encoded again only when its value is no longer the same object (module docstring).

    The owner must replace a value that changes and never change it in place; a value
    changed in place keeps its old text (tests/test_json_text.py runs a pass and compares
    every frame's text with ``json.dumps`` of the plain state)."""

    def __init__(self) -> None:
        self._maps: dict[str, dict[Any, tuple[Any, str]]] = {}
        self._lists: dict[str, dict[int, tuple[Any, str]]] = {}
        self._appended: dict[str, AppendOnlyJSON] = {}
        self._texts: dict[str, tuple[tuple, str]] = {}  # a map's keys in order and its whole text

    def map(self, name: str, pairs: Iterable[tuple[Any, Any]],
            value: Callable[[Any], Any] | None = None) -> EncodedJSON:
        """The object ``{str(key): value(v)}`` of ``pairs`` (key, v), in their order."""
        old, new, encoded = self._maps.get(name, {}), {}, 0
        for key, v in pairs:
            hit = old.get(key)
            if hit is None or (hit[0] is not v and not _same(hit[0], v)):
                hit, encoded = (v, f"{json.dumps(str(key))}: {dumps(v if value is None else value(v))}"), encoded + 1
            new[key] = hit
        keys, last = tuple(new), self._texts.get(name)
        if encoded == 0 and last is not None and last[0] == keys:  # every entry as it was, in order
            text = last[1]
        else:
            text = "{" + ", ".join(part for _, part in new.values()) + "}"
        self._maps[name], self._texts[name] = new, (keys, text)
        return EncodedJSON(text)

    def list(self, name: str, items: Iterable[Any], value: Callable[[Any], Any] | None = None) -> EncodedJSON:
        """The list ``[value(v) for v in items]``."""
        old, new, parts = self._lists.get(name, {}), {}, []
        for v in items:
            hit = old.get(id(v))
            if hit is None or hit[0] is not v:
                hit = (v, dumps(v if value is None else value(v)))
            new[id(v)] = hit  # the value is held, so its id is not another's while kept
            parts.append(hit[1])
        self._lists[name] = new
        return EncodedJSON("[" + ", ".join(parts) + "]")

    def appended(self, name: str, items: list, value: Callable[[Any], Any] | None = None) -> EncodedJSON:
        """:meth:`list` of a list that is only appended to (:class:`AppendOnlyJSON`): no
        entry is looked at twice."""
        return EncodedJSON(self._appended.setdefault(name, AppendOnlyJSON()).text(items, value))


def keyed(memo: JSONMemo | None, name: str, pairs: Iterable[tuple[Any, Any]],
          value: Callable[[Any], Any] | None = None) -> dict[str, Any] | EncodedJSON:
    """A state's map of ``pairs`` (key, v): ``{str(key): value(v)}``, or with ``memo`` its text."""
    if memo is not None:
        return memo.map(name, pairs, value)
    return {str(k): v if value is None else value(v) for k, v in pairs}


def listed(memo: JSONMemo | None, name: str, items: Iterable[Any],
           value: Callable[[Any], Any] | None = None) -> list[Any] | EncodedJSON:
    """A state's list ``[value(v) for v in items]``, or with ``memo`` its text."""
    if memo is not None:
        return memo.list(name, items, value)
    return [v if value is None else value(v) for v in items]
