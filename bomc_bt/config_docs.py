"""Parameter documentation read from the code, and the YAML that shows it.

Every field of a ``*Params`` dataclass carries its unit and meaning in a comment, on the
same line or on the comment lines directly above it::

    radius: float = 5.0  # [m] how far Look Around looks for nodes

:func:`field_docs` reads those comments from the class's source (``tokenize`` for the
comments, ``ast`` for the fields), so the documentation cannot drift from the code: it
*is* the code's. :func:`documented_yaml` writes a record as ``key: value  # [unit] meaning``
lines, with each nested record's docstring above its section; ``config/defaults.yaml`` and
``bomc config`` are made by it.
"""

from __future__ import annotations

import ast
import functools
import inspect
import io
import re
import textwrap
import tokenize
from dataclasses import dataclass, fields, is_dataclass
from typing import Any

import yaml

UNITS = ("m", "m2", "s", "deg", "deg/s", "m/s", "Hz", "count", "-", "bool", "choice", "text", "list")
"""The units a field's doc may start with: ``[-]`` is a ratio or unitless number."""

WIDTH = 110  # characters a generated line aims to stay within
_DOC = re.compile(r"\[([^\]]+)\]\s*(.*)", re.DOTALL)


@dataclass(frozen=True)
class FieldDoc:
    """One field's documentation: ``unit`` is "" when the comment does not start with one."""

    unit: str
    meaning: str

    def __str__(self) -> str:
        return f"[{self.unit}] {self.meaning}" if self.unit else self.meaning


@functools.cache
def field_docs(cls: type) -> dict[str, FieldDoc]:
    """The documented fields of dataclass ``cls``: name -> its comment (trailing, else above)."""
    source = textwrap.dedent(inspect.getsource(cls))
    comments, code_lines = _comments(source)
    body = ast.parse(source).body[0]
    assert isinstance(body, ast.ClassDef)
    docs = {}
    for stmt in body.body:
        if not (isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name)):
            continue
        text = next((comments[n] for n in range(stmt.lineno, stmt.end_lineno + 1) if n in comments), None)
        if text is None:  # the block of comment-only lines directly above
            above, line = [], stmt.lineno - 1
            while line in comments and line not in code_lines:
                above.insert(0, comments[line])
                line -= 1
            text = " ".join(above) or None
        if text is not None:
            docs[stmt.target.id] = _parse(text)
    return docs


def _comments(source: str) -> tuple[dict[int, str], set[int]]:
    """Comment text by line (without ``#``), and the lines that hold code."""
    comments: dict[int, str] = {}
    code: set[int] = set()
    skip = (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENDMARKER)
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            comments[tok.start[0]] = tok.string.lstrip("#").strip()
        elif tok.type not in skip:
            code.update(range(tok.start[0], tok.end[0] + 1))
    return comments, code


def _parse(text: str) -> FieldDoc:
    match = _DOC.fullmatch(text)
    return FieldDoc(match.group(1), match.group(2)) if match else FieldDoc("", text)


def summary(cls: type) -> str:
    """The first paragraph of a class's docstring on one line ("" if it has none of its own)."""
    doc = inspect.cleandoc(cls.__dict__.get("__doc__") or "")
    return " ".join(doc.split("\n\n")[0].split())


def documented_yaml(record: Any, indent: int = 0) -> str:
    """``record`` (a dataclass instance) as YAML with every field's doc as a comment."""
    pad = " " * indent
    docs = field_docs(type(record))
    lines = []
    for f in fields(record):
        if not f.init:
            continue
        value = getattr(record, f.name)
        if is_dataclass(value):
            if summary(type(value)):
                lines.append(f"{pad}# {summary(type(value))}")
            lines.append(f"{pad}{f.name}:")
            lines.append(documented_yaml(value, indent + 2).rstrip("\n"))
            continue
        lines.extend(_commented(f"{pad}{_scalar(f.name, value)}", docs.get(f.name)))
    return "\n".join(lines) + "\n"


def _commented(line: str, doc: FieldDoc | None) -> list[str]:
    """``line  # doc``; a long doc goes on as comment lines aligned under its start."""
    if doc is None:
        return [line]
    chunks = textwrap.wrap(str(doc), max(40, WIDTH - len(line) - 4))
    return [f"{line}  # {chunks[0]}", *(f"{' ' * len(line)}  # {c}" for c in chunks[1:])]


def _scalar(name: str, value: Any) -> str:
    """``name: value`` on one line (lists and mappings in flow style)."""
    text = yaml.safe_dump({name: plain(value)}, default_flow_style=True, sort_keys=False, width=1 << 20)
    return text.strip()[1:-1]  # drop the braces of the one-key flow mapping


def plain(value: Any) -> Any:
    """YAML-able data: tuples become lists, in mappings and lists at any depth."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value
