"""Typed parameter records built from YAML, with errors that name the file and field.

Every module keeps its parameters in a dataclass with defaults. :func:`from_mapping`
fills one from a YAML mapping, checking unknown keys, types and nested records, so a
typo in ``config/*.yaml`` or a tree file is a one-line error instead of a silent default.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from pathlib import Path
from typing import Any, TypeVar

from bomc_bt.errors import BomcError

T = TypeVar("T")


def from_mapping(cls: type[T], data: Any, file: str | Path | None = None, where: str = "") -> T:
    """Build dataclass ``cls`` from ``data`` (a mapping), validating keys and types."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise BomcError(f"expected a mapping, got {type(data).__name__}", file, where or None)
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(map(str, data)) - set(fields))
    if unknown:
        if f"{unknown[0]}_deg" in fields:  # an angle that used to be given in radians
            raise BomcError(f"renamed: give it in degrees as {unknown[0]}_deg", file, _join(where, unknown[0]))
        known = ", ".join(sorted(fields))
        raise BomcError(f"unknown key (expected one of: {known})", file, _join(where, unknown[0]))
    values = {}
    for name, value in data.items():
        values[name] = coerce(hints[name], value, file, _join(where, name))
        check_range(cls, name, values[name], file, _join(where, name))
    missing = [
        n for n, f in fields.items()
        if n not in values and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise BomcError("missing", file, _join(where, missing[0]))
    try:
        return cls(**values)
    except (ValueError, TypeError) as exc:  # __post_init__ range checks
        raise BomcError(str(exc), file, where or None) from None


class Radians:
    """A read-only radians view of the degrees field named like it plus ``_deg``.

    Users give angles in degrees (``search_angle_deg: 34.0``); the code reads
    ``params.search_angle`` in radians, converted here, in one place::

        search_angle_deg: float = 34.0  # [deg] ...
        search_angle = Radians()
    """

    def __set_name__(self, owner: type, name: str) -> None:
        self.source = f"{name}_deg"

    def __get__(self, record: Any, owner: type | None = None) -> Any:
        return self if record is None else math.radians(getattr(record, self.source))


def merge(base: dict, override: dict) -> dict:
    """Deep-merge two YAML mappings (override wins)."""
    out = dict(base)
    for k, v in override.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


def coerce(hint: Any, value: Any, file, where: str) -> Any:
    """Check ``value`` against a type hint, converting ints to floats and lists to tuples."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if hint is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        errors = []
        for arg in args:
            try:
                return coerce(arg, value, file, where)
            except BomcError as exc:
                errors.append(exc.message)
        raise BomcError(f"has the wrong type ({_describe(value)}; expected {_name(hint)})", file, where)
    if hint is type(None):
        if value is None:
            return None
        raise BomcError(f"expected null, got {_describe(value)}", file, where)
    if dataclasses.is_dataclass(hint):
        return from_mapping(hint, value, file, where)
    if hint is bool:
        if isinstance(value, bool):
            return value
    elif hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            if abs(value) > LARGEST:
                raise BomcError(f"must be at most {LARGEST:.0e} in size, got {_describe(value)}", file, where)
            return value
    elif hint is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if isinstance(value, int) and abs(value) > LARGEST or not math.isfinite(float(value)):
                raise BomcError(f"must be a finite number at most {LARGEST:.0e} in size, got {_describe(value)}",
                                file, where)
            return float(value)
    elif hint is str:
        if isinstance(value, str):
            return value
    elif origin in (list, tuple) or hint in (list, tuple):
        if isinstance(value, (list, tuple)):
            if origin is tuple and args and args[-1] is not Ellipsis:
                if len(value) != len(args):
                    raise BomcError(f"expected {len(args)} values, got {len(value)}", file, where)
                pairs = enumerate(zip(args, value, strict=True))
                return tuple(coerce(a, v, file, f"{where}[{i}]") for i, (a, v) in pairs)
            item = args[0] if args else Any
            items = [coerce(item, v, file, f"{where}[{i}]") for i, v in enumerate(value)]
            return tuple(items) if origin is tuple else items
    elif origin is dict or hint is dict:
        if isinstance(value, dict):
            kt, vt = args if args else (Any, Any)
            return {coerce(kt, k, file, where): coerce(vt, v, file, _join(where, str(k))) for k, v in value.items()}
    elif typing.get_origin(hint) is typing.Literal:
        pass
    if origin is typing.Literal:
        if value in args:
            return value
        raise BomcError(f"must be one of {', '.join(map(repr, args))}, got {value!r}", file, where)
    raise BomcError(f"has the wrong type ({_describe(value)}; expected {_name(hint)})", file, where)


LARGEST = 10**9  # no parameter of a robot mission means anything beyond this (metres, seconds, counts)
NON_NEGATIVE_UNITS = {"s", "Hz", "count", "m2", "m/s", "deg/s"}  # times, periods, rates, sizes, speeds


def check_range(cls: type, name: str, value: Any, file, where: str) -> None:
    """Values with a physical meaning are range-checked by their documented unit: times,
    periods, rates, counts, areas and speeds are never negative (each record's own
    ``__post_init__`` checks what is particular to it)."""
    from bomc_bt.config_docs import field_docs

    try:
        doc = field_docs(cls).get(name)
    except (OSError, TypeError, SyntaxError):  # a record without source (built at run time): no docs
        return
    if doc is None or doc.unit not in NON_NEGATIVE_UNITS:
        return
    sentinel = value == -1 and "-1" in doc.meaning  # a documented "-1: for ever"
    if isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0 and not sentinel:
        raise BomcError(f"must not be negative ({doc.unit}), got {value}", file, where)


def _join(where: str, name: str) -> str:
    return f"{where}.{name}" if where else name


def _describe(value: Any) -> str:
    return "null" if value is None else f"{type(value).__name__} {value!r}"[:60]


def _name(hint: Any) -> str:
    return getattr(hint, "__name__", None) or str(hint).replace("typing.", "")
