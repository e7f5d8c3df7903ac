"""Typed reads of parsed YAML, each failing as one :class:`BomcError` naming file and field.

The world loader checks every value it takes from the file through these, so a user
sees ``lab.yaml: objects[3].size: sizes must be positive`` rather than a traceback.
A field path is dotted keys and ``[i]`` indices (:func:`join`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bomc_bt.errors import BomcError
from bomc_bt.world.timeline import entry_key


def join(where: str, key: Any) -> str:
    """The field path of ``key`` inside ``where`` (the top level when ``where`` is empty)."""
    return f"{where}.{entry_key(key)}" if where else entry_key(key)


def describe(value: Any) -> str:
    """A short ``type value`` of what the file holds, for "expected X, got Y" messages."""
    return "null" if value is None else f"{type(value).__name__} {value!r}"[:50]


@dataclass
class FieldReader:
    """Checks values read from ``file``, raising BomcError(file, field) on the first problem."""

    file: Path

    def fail(self, message: str, where: str) -> BomcError:
        return BomcError(message, self.file, where or None)

    # -- primitives --------------------------------------------------------------------------
    def mapping(self, value: Any, where: str, allowed: set[str], required: tuple[str, ...] = ()) -> dict:
        if not isinstance(value, dict):
            raise self.fail(f"expected a mapping, got {describe(value)}", where)
        for key in value:
            if not isinstance(key, str):
                raise self.fail(f"keys must be text, got {describe(key)}", where)
            if key not in allowed and not key.startswith("x-"):
                expected = ", ".join(sorted(allowed))
                raise self.fail(f"unknown key (expected one of: {expected}; 'x-' keys are extensions)",
                                join(where, key))
        for key in required:
            if key not in value:
                raise self.fail("missing", join(where, key))
        return value

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"expected a number, got {describe(value)}", where)
        if not math.isfinite(value):
            raise self.fail("must be a finite number", where)
        return float(value)

    def text(self, value: Any, where: str) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.fail(f"expected non-empty text, got {describe(value)}", where)
        return value

    def vector(self, value: Any, where: str, shape: str, lengths: tuple[int, ...]) -> tuple[float, ...]:
        ok = isinstance(value, list) and len(value) in lengths and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        if not ok:
            raise self.fail(f"expected {shape} numbers", where)
        if not all(math.isfinite(v) for v in value):
            raise self.fail(f"expected {shape} finite numbers (no NaN or inf)", where)
        return tuple(float(v) for v in value)

    def size(self, value: Any, where: str, shape: str, n: int) -> tuple[float, ...]:
        size = self.vector(value, where, shape, (n,))
        if min(size) <= 0.0:
            raise self.fail("sizes must be positive", where)
        return size

    def items(self, value: Any, where: str) -> list:
        if not isinstance(value, list):
            raise self.fail(f"expected a list, got {describe(value)}", where)
        return value
